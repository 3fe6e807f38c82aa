// Object stages on motion: matching a frame's features to an earlier frame, Algorithm 1 with
// the class prior, Algorithm 2 and the inputs of residuals (9) and (10).

#include <algorithm>
#include <cmath>

#include "mcslam/features/matching.hpp"
#include "mcslam/slam/object_stages.hpp"
#include "object_geometry.hpp"

namespace mcslam::slam {
namespace {

/// Background features matched per frame to measure its noise (see background_threshold).
constexpr std::size_t kBackgroundSample = 150;

/// Where a current pixel would be in the reference image if it were static.
struct ReferencePrediction {
  const PinholeCamera& camera;
  SE3 T_ref_cur;

  std::optional<Eigen::Vector2d> operator()(const Eigen::Vector2d& uv, double depth) const {
    return object_geometry::static_prediction(camera, T_ref_cur, uv, depth);
  }
};

/// Current points (the boxes' of `selected` and a sample of the background) paired with the
/// reference point of best descriptor within the window around their prediction, with a ratio
/// test; one current point per reference point (the closer claim wins; a lost pair's
/// reference index is -1).
std::vector<std::pair<std::size_t, int>> pair_points(const features::FrameFeatures& cur,
                                                     const features::FrameFeatures& old,
                                                     const std::vector<std::uint64_t>& point_boxes,
                                                     std::uint64_t selected,
                                                     const ReferencePrediction& predict,
                                                     const DynamicsOptions& opt) {
  const auto& pyramid = *cur.pyramid;
  std::vector<int> candidates;
  // Per reference feature: the distance and slot in pairs of its current claim (slot -1: none).
  std::vector<std::pair<int, std::ptrdiff_t>> taken(old.points.size(), {0, -1});
  std::vector<std::pair<std::size_t, int>> pairs;  // (current, reference)
  // The background sample tells how far static features land from the camera-motion
  // prediction in this frame.
  std::size_t background = 0;
  for (std::size_t i = 0; i < cur.points.size(); ++i) background += point_boxes[i] == 0;
  const std::size_t stride = std::max<std::size_t>(1, background / kBackgroundSample);
  std::size_t background_seen = 0;
  for (std::size_t i = 0; i < cur.points.size(); ++i) {
    if (point_boxes[i] == 0 && background_seen++ % stride != 0) continue;
    if (point_boxes[i] != 0 && (point_boxes[i] & selected) == 0) continue;
    const auto& f = cur.points[i];
    const auto at = predict(f.keypoint.uv.cast<double>(), f.has_depth() ? f.depth : 0.0);
    if (!at) continue;
    const int level = f.keypoint.level;
    const double r = opt.match_radius * pyramid.scale[static_cast<std::size_t>(level)];
    old.grid.query(static_cast<float>(at->x()), static_cast<float>(at->y()), static_cast<float>(r),
                   std::max(0, level - 1), level + 1, candidates);
    int best = 256;
    const int best_idx = object_geometry::unambiguous_match(f.descriptor, candidates, old.points,
                                                            opt.descriptor_distance, &best);
    if (best_idx < 0) continue;
    auto& claim = taken[static_cast<std::size_t>(best_idx)];
    if (claim.second >= 0) {
      if (claim.first <= best) continue;
      pairs[static_cast<std::size_t>(claim.second)].second = -1;  // the earlier claim loses
    }
    claim = {best, static_cast<std::ptrdiff_t>(pairs.size())};
    pairs.emplace_back(i, best_idx);
  }
  return pairs;
}

/// The point pairs as matches: one per box of the current point, or one of box -1 for the
/// background.
void add_point_matches(const std::vector<std::pair<std::size_t, int>>& pairs,
                       const features::FrameFeatures& cur, const features::FrameFeatures& old,
                       const std::vector<std::uint64_t>& point_boxes, std::size_t box_count,
                       const PinholeCamera& camera, std::vector<MotionMatch>& out) {
  for (const auto& [i, j] : pairs) {
    if (j < 0) continue;
    const auto& f = cur.points[i];
    const auto& g = old.points[static_cast<std::size_t>(j)];
    MotionMatch m;
    m.feature = static_cast<int>(i);
    m.ref_uv[0] = g.keypoint.uv.cast<double>();
    m.cur_uv[0] = f.keypoint.uv.cast<double>();
    if (g.has_depth()) m.ref_c[0] = camera.unproject(m.ref_uv[0], g.depth);
    if (f.has_depth()) m.cur_c[0] = camera.unproject(m.cur_uv[0], f.depth);
    m.scale = cur.pyramid->scale[static_cast<std::size_t>(f.keypoint.level)];
    if (point_boxes[i] == 0) out.push_back(m);  // background: box -1
    for (std::size_t b = 0; b < box_count; ++b)
      if (point_boxes[i] & (std::uint64_t{1} << b)) {
        m.box = static_cast<int>(b);
        out.push_back(m);
      }
  }
}

/// The reference segment matching current segment `l`: midpoint within 1.5 match_radius of its
/// prediction, direction within 20 degrees, best LBD distance within line_descriptor_distance;
/// -1 for none.
int match_line(const features::LineFeature& l, const features::FrameFeatures& old,
               const ReferencePrediction& predict, const PinholeCamera& camera,
               const DynamicsOptions& opt) {
  const double max_angle = std::cos(20.0 * M_PI / 180.0);
  const Eigen::Vector3d mid_c = 0.5 * (l.start_c + l.end_c);
  const auto at = l.has_depth ? predict(camera.project(mid_c), mid_c.z())
                              : predict(l.midpoint().cast<double>(), 0.0);
  if (!at) return -1;
  const Eigen::Vector2f dir = (l.end - l.start).normalized();
  int best = 256, best_idx = -1;
  for (std::size_t j = 0; j < old.lines.size(); ++j) {
    const auto& o = old.lines[j];
    if ((o.midpoint().cast<double>() - *at).norm() > 1.5 * opt.match_radius) continue;
    const Eigen::Vector2f odir = (o.end - o.start).normalized();
    if (std::abs(dir.dot(odir)) < max_angle) continue;
    const int d = features::hamming_distance(l.descriptor, o.descriptor);
    if (d < best) {
      best = d;
      best_idx = static_cast<int>(j);
    }
  }
  if (best_idx < 0 || best > opt.line_descriptor_distance) return -1;
  return best_idx;
}

/// A segment pair as a match, the reference endpoints oriented like the current segment's.
MotionMatch line_match(std::size_t i, const features::LineFeature& l,
                       const features::LineFeature& o) {
  const Eigen::Vector2f dir = (l.end - l.start).normalized();
  const bool flip = dir.dot((o.end - o.start).normalized()) < 0.0f;
  MotionMatch m;
  m.line = true;
  m.feature = static_cast<int>(i);
  m.ref_uv[0] = (flip ? o.end : o.start).cast<double>();
  m.ref_uv[1] = (flip ? o.start : o.end).cast<double>();
  m.cur_uv[0] = l.start.cast<double>();
  m.cur_uv[1] = l.end.cast<double>();
  if (o.has_depth) {
    m.ref_c[0] = flip ? o.end_c : o.start_c;
    m.ref_c[1] = flip ? o.start_c : o.end_c;
  }
  if (l.has_depth) {
    m.cur_c[0] = l.start_c;
    m.cur_c[1] = l.end_c;
  }
  m.cur_line = l.coefficients();
  return m;
}

}  // namespace

FeatureLabel label_for(std::uint64_t mask, const std::vector<ObjectState>& state) {
  FeatureLabel label = FeatureLabel::kStatic;
  for (std::size_t b = 0; b < state.size() && b < kMaxBoxes; ++b) {
    if (!(mask & (std::uint64_t{1} << b))) continue;
    if (state[b] == ObjectState::kDynamic) return FeatureLabel::kDynamic;
    if (state[b] == ObjectState::kConstrained) label = FeatureLabel::kConstrained;
  }
  return label;
}

std::vector<MotionMatch> match_to_reference(const features::FrameFeatures& current,
                                            const features::FrameFeatures& reference,
                                            const SE3& T_cur_ref, const FeatureBoxes& boxes,
                                            std::size_t box_count, std::uint64_t selected,
                                            const PinholeCamera& camera,
                                            const DynamicsOptions& options) {
  const ReferencePrediction predict{camera, T_cur_ref.inverse()};
  std::vector<MotionMatch> out;
  add_point_matches(pair_points(current, reference, boxes.points, selected, predict, options),
                    current, reference, boxes.points, box_count, camera, out);
  for (std::size_t i = 0; i < current.lines.size(); ++i) {
    if ((boxes.lines[i] & selected) == 0) continue;
    const auto& l = current.lines[i];
    const int j = match_line(l, reference, predict, camera, options);
    if (j < 0) continue;
    MotionMatch m = line_match(i, l, reference.lines[static_cast<std::size_t>(j)]);
    for (std::size_t b = 0; b < box_count; ++b)
      if (boxes.lines[i] & (std::uint64_t{1} << b)) {
        m.box = static_cast<int>(b);
        out.push_back(m);
      }
  }
  return out;
}

double background_threshold(const std::vector<MotionMatch>& matches, const SE3& T_cur_ref,
                            const PinholeCamera& camera, const DynamicsOptions& options) {
  std::vector<double> distances;
  for (const MotionMatch& m : matches)
    if (m.box < 0)
      if (const auto d = motion_distance(camera, T_cur_ref, m, 0))
        distances.push_back(*d / m.scale);
  const double floor = options.epipolar_threshold;
  if (distances.size() < 20) return floor;
  // For 2D Gaussian residuals 3 x the median is about the 99.5th percentile.
  return std::max(floor, options.background_factor * object_geometry::median_of(distances));
}

BoxVerdicts judge_boxes(const features::FrameFeatures& current, const SE3& T_c_w,
                        const ObjectFrame& reference, const ObjectFrame& last,
                        const FeatureBoxes& boxes, std::size_t box_count,
                        const PinholeCamera& camera, const DynamicsOptions& options) {
  BoxVerdicts out;
  const SE3 T_cur_ref = T_c_w * reference.T_c_w->inverse();
  out.matches = match_to_reference(current, *reference.features, T_cur_ref, boxes, box_count,
                                   ~std::uint64_t{0}, camera, options);
  DynamicsOptions frame_opt = options;
  frame_opt.epipolar_threshold = background_threshold(out.matches, T_cur_ref, camera, options);
  out.threshold = frame_opt.epipolar_threshold;
  const int n_boxes = static_cast<int>(box_count);
  out.decisions = detect_dynamic_objects(n_boxes, out.matches, camera, T_cur_ref, frame_opt);
  if (&reference == &last) return out;
  std::uint64_t undecided = 0;
  for (std::size_t b = 0; b < box_count; ++b)
    if (!out.decisions[b].decided) undecided |= std::uint64_t{1} << b;
  if (undecided == 0) return out;
  const SE3 T_cur_last = T_c_w * last.T_c_w->inverse();
  const auto recent_matches = match_to_reference(current, *last.features, T_cur_last, boxes,
                                                 box_count, undecided, camera, options);
  DynamicsOptions last_opt = options;
  last_opt.epipolar_threshold = background_threshold(recent_matches, T_cur_last, camera, options);
  const auto retry = detect_dynamic_objects(n_boxes, recent_matches, camera, T_cur_last, last_opt);
  for (std::size_t b = 0; b < box_count; ++b)
    if (!out.decisions[b].decided && retry[b].decided) out.decisions[b] = retry[b];
  return out;
}

void withhold_shared_verdicts(std::vector<ObjectDecision>& decisions,
                              const std::vector<MotionMatch>& matches,
                              const std::vector<ObjectBox>& boxes,
                              const std::vector<bool>& moving) {
  const std::size_t n_boxes = boxes.size();
  const auto in_front = [&](std::size_t c, std::size_t b) {
    return boxes[c].depth > 0.0f && boxes[b].depth > 0.0f && boxes[c].depth < boxes[b].depth;
  };
  for (std::size_t b = 0; b < n_boxes; ++b) {
    if (!decisions[b].dynamic) continue;
    int total = 0, shared = 0;
    for (const MotionMatch& m : matches) {
      if (m.box != static_cast<int>(b)) continue;
      ++total;
      const cv::Point2f p(static_cast<float>(m.cur_uv[0].x()), static_cast<float>(m.cur_uv[0].y()));
      for (std::size_t c = 0; c < n_boxes; ++c)
        if (c != b && moving[c] && in_front(c, b) && boxes[c].detection.box.contains(p)) {
          ++shared;
          break;
        }
    }
    if (2 * shared > total) decisions[b].decided = decisions[b].dynamic = false;
  }
}

TrackEvidence track_evidence(const ObjectDecision& decision, const std::string& class_name,
                             double threshold, const DynamicsOptions& options) {
  TrackEvidence out{decision, options.static_frames_to_clear};
  if (!options.self_moving(class_name)) return out;
  out.frames_to_clear = options.moving_class_static_frames;
  ObjectDecision& evidence = out.evidence;
  if (evidence.decided && !evidence.dynamic &&
      !(evidence.median_distance <= options.epipolar_threshold)) {
    // Most of its features are off the camera's motion: moving, even if fewer than epsilon_r;
    // between the strict and the adaptive epsilon_d: no evidence either way.
    evidence.dynamic = evidence.median_distance > threshold;
    evidence.decided = evidence.dynamic;
  }
  return out;
}

ConstraintFrame constraint_frame(const std::vector<features::PlaneFeature>& planes,
                                 const SE3& T_c_w, const SE3& T_ref_w) {
  ConstraintFrame out{planes, {}, T_ref_w.inverse(), T_c_w.inverse()};
  for (const auto& p : planes) {
    const Eigen::Vector3d n_w = out.T_w_c.rotation() * p.normal;
    out.planes_w.emplace_back(n_w.x(), n_w.y(), n_w.z(), p.d + p.normal.dot(T_c_w.translation()));
  }
  return out;
}

ConstraintDecision check_box_constraint(std::size_t b, const ObjectBox& box,
                                        const std::vector<MotionMatch>& matches,
                                        const ConstraintFrame& frame, const PinholeCamera& camera,
                                        const DynamicsOptions& options) {
  const auto& planes = frame.planes;
  std::vector<const MotionMatch*> object;
  for (const MotionMatch& m : matches)
    if (m.box == static_cast<int>(b)) object.push_back(&m);
  std::vector<Eigen::Vector4d> candidates;
  std::vector<int> index;
  for (std::size_t k = 0; k < planes.size(); ++k) {
    bool inside_only = true;
    for (const auto& h : planes[k].hull) {
      if (h.z() <= 1e-3) continue;
      const Eigen::Vector2d uv = camera.project(h);
      if (!box.detection.box.contains(
              cv::Point2f(static_cast<float>(uv.x()), static_cast<float>(uv.y()))))
        inside_only = false;
    }
    if (inside_only) continue;
    candidates.push_back(frame.planes_w[k]);
    index.push_back(static_cast<int>(k));
  }
  ConstraintDecision c =
      check_moving_constraint(object, candidates, frame.T_w_ref, frame.T_w_c, options);
  if (c.plane >= 0) c.plane = index[static_cast<std::size_t>(c.plane)];
  return c;
}

ConstraintMeasurements constraint_measurements(const std::vector<MotionMatch>& matches,
                                               const std::vector<ObjectState>& state,
                                               const FeatureBoxes& boxes,
                                               const std::vector<ConstraintDecision>& constraints,
                                               const ConstraintFrame& frame,
                                               const DynamicsOptions& opt) {
  ConstraintMeasurements out;
  for (const MotionMatch& m : matches) {
    if (m.box < 0) continue;  // background
    const auto b = static_cast<std::size_t>(m.box);
    if (state[b] != ObjectState::kConstrained) continue;
    const std::uint64_t mask = m.line ? boxes.lines[static_cast<std::size_t>(m.feature)]
                                      : boxes.points[static_cast<std::size_t>(m.feature)];
    if (label_for(mask, state) != FeatureLabel::kConstrained) continue;  // also in a dynamic box
    const int plane = constraints[b].plane;
    if (plane < 0) continue;
    const Eigen::Vector3d n_w =
        frame.T_w_c.rotation() * frame.planes[static_cast<std::size_t>(plane)].normal;
    if (!m.line) {
      if (!m.ref_c[0] || !m.cur_c[0]) continue;
      optim::ConstrainedPointMeasurement c;
      c.p_last_w = frame.T_w_ref * (*m.ref_c[0]);
      c.p_c = *m.cur_c[0];
      c.n_w = n_w;
      c.information = 1.0 / (opt.constraint_point_sigma * opt.constraint_point_sigma);
      out.points.push_back(c);
    } else {
      if (!m.ref_c[0] || !m.ref_c[1] || !m.cur_c[0] || !m.cur_c[1]) continue;
      optim::ConstrainedLineMeasurement c;
      c.s_last_w = frame.T_w_ref.rotation() * (*m.ref_c[1] - *m.ref_c[0]);
      c.s_c = *m.cur_c[1] - *m.cur_c[0];
      c.n_w = n_w;
      c.information = 1.0 / (opt.constraint_line_sigma * opt.constraint_line_sigma);
      out.lines.push_back(c);
    }
  }
  return out;
}

}  // namespace mcslam::slam
