#include "mcslam/slam/objects.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <opencv2/video/tracking.hpp>

#include "mcslam/features/matching.hpp"

namespace mcslam::slam {
namespace {

/// The candidate whose ORB descriptor is closest to `descriptor`, when within `max_distance`
/// and clearly better than the second closest (ratio 0.8); -1 otherwise. `best` gets its
/// distance.
int unambiguous_match(const features::OrbDescriptor& descriptor, const std::vector<int>& candidates,
                      const std::vector<features::PointFeature>& points, int max_distance,
                      int* best = nullptr) {
  int first = 256, second = 256, index = -1;
  for (int j : candidates) {
    const int d =
        features::hamming_distance(descriptor, points[static_cast<std::size_t>(j)].descriptor);
    if (d < first) {
      second = first;
      first = d;
      index = j;
    } else if (d < second) {
      second = d;
    }
  }
  if (best) *best = first;
  if (index < 0 || first > max_distance || first > 0.8 * second) return -1;
  return index;
}

/// Background features matched per frame to measure its noise (see adaptive_threshold).
constexpr std::size_t kBackgroundSample = 150;
/// Frames kept for carrying boxes forward: a detector slower than this many frames a detection
/// gets its boxes only grown.
constexpr std::size_t kRecentFrames = 12;
/// A moving region no evidence has confirmed for this many frames is dropped.
constexpr int kMoverLife = 10;
/// Features of a box matched to carry it forward (a median needs no more).
constexpr std::size_t kPropagationSample = 40;
/// Boxes per frame (one bit each in the feature masks).
constexpr std::size_t kMaxBoxes = 64;

/// The label of a feature in the boxes of `mask` (bit b: box b): dynamic when any of them is
/// dynamic, else constrained when any is constrained, else static.
FeatureLabel label_for(std::uint64_t mask, const std::vector<ObjectState>& state) {
  FeatureLabel label = FeatureLabel::kStatic;
  for (std::size_t b = 0; b < state.size() && b < kMaxBoxes; ++b) {
    if (!(mask & (std::uint64_t{1} << b))) continue;
    if (state[b] == ObjectState::kDynamic) return FeatureLabel::kDynamic;
    if (state[b] == ObjectState::kConstrained) label = FeatureLabel::kConstrained;
  }
  return label;
}

bool contains(const cv::Rect2f& r, const Eigen::Vector2f& p) {
  return p.x() >= r.x && p.y() >= r.y && p.x() < r.x + r.width && p.y() < r.y + r.height;
}

cv::Rect2f grown(const cv::Rect2f& r, float dx, float dy) {
  return {r.x - dx, r.y - dy, r.width + 2 * dx, r.height + 2 * dy};
}

template <typename T>
T median_of(std::vector<T> v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

/// The object's depth band among the depths of a box's features: they are split into clusters
/// where sorted depths jump by more than `gap`; the object is the largest cluster.
std::optional<std::pair<float, float>> object_band(std::vector<float> depths, double gap) {
  if (depths.empty()) return std::nullopt;
  std::sort(depths.begin(), depths.end());
  std::size_t best_start = 0, best_size = 0, start = 0;
  for (std::size_t i = 1; i <= depths.size(); ++i) {
    if (i < depths.size() && depths[i] - depths[i - 1] <= gap) continue;
    if (i - start > best_size) {
      best_size = i - start;
      best_start = start;
    }
    start = i;
  }
  return std::make_pair(depths[best_start], depths[best_start + best_size - 1]);
}

/// Mean over the boxes of `truth` of the best IoU of a box of the same class in `estimate`;
/// boxes with no counterpart at all (objects that just appeared) are not counted. -1: none.
double mean_best_iou(const std::vector<perception::Detection>& truth,
                     const std::vector<perception::Detection>& estimate) {
  double sum = 0.0;
  int n = 0;
  for (const auto& t : truth) {
    double best = 0.0;
    for (const auto& e : estimate)
      if (e.class_name == t.class_name) best = std::max(best, perception::iou(t.box, e.box));
    if (best <= 0.0) continue;
    sum += best;
    ++n;
  }
  return n > 0 ? sum / n : -1.0;
}

/// The image motion of each box's sampled features (indices into from.points) from `from`'s
/// image to `to`'s, by pyramidal Lucas-Kanade started at `predict` (where the camera's motion
/// alone puts them); a feature counts when tracking it back returns within `max_error` pixels.
/// One list of shifts per box; empty lists without images.
template <typename Predict>
std::vector<std::vector<Eigen::Vector2d>> flow_shifts(
    const features::FrameFeatures& from, const features::FrameFeatures& to,
    const std::vector<std::vector<std::size_t>>& samples, const Predict& predict,
    double max_error) {
  std::vector<std::vector<Eigen::Vector2d>> out(samples.size());
  if (from.image.empty() || to.image.empty() || from.image.size() != to.image.size()) return out;
  std::vector<cv::Point2f> start, moved;
  std::vector<std::size_t> box_of;
  for (std::size_t b = 0; b < samples.size(); ++b)
    for (std::size_t i : samples[b]) {
      const features::PointFeature& f = from.points[i];
      const auto at = predict(f);
      if (!at) continue;
      start.emplace_back(f.keypoint.uv.x(), f.keypoint.uv.y());
      moved.emplace_back(static_cast<float>(at->x()), static_cast<float>(at->y()));
      box_of.push_back(b);
    }
  if (start.empty()) return out;
  // A 15 px window over 4 levels (3 halvings) follows ~60 px beyond the start: a person
  // crossing the view at 1.5 m/s, 1 m away, for 2-3 frames at 30 Hz. The pyramids are built
  // once and serve both directions.
  const cv::TermCriteria stop(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 0.03);
  const cv::Size window(15, 15);
  constexpr int kLevels = 3;
  std::vector<cv::Mat> from_pyramid, to_pyramid;
  cv::buildOpticalFlowPyramid(from.image, from_pyramid, window, kLevels);
  cv::buildOpticalFlowPyramid(to.image, to_pyramid, window, kLevels);
  std::vector<std::uint8_t> found, found_back;
  std::vector<float> error;
  cv::calcOpticalFlowPyrLK(from_pyramid, to_pyramid, start, moved, found, error, window, kLevels,
                           stop, cv::OPTFLOW_USE_INITIAL_FLOW);
  std::vector<cv::Point2f> back = start;
  cv::calcOpticalFlowPyrLK(to_pyramid, from_pyramid, moved, back, found_back, error, window,
                           kLevels, stop, cv::OPTFLOW_USE_INITIAL_FLOW);
  for (std::size_t k = 0; k < start.size(); ++k) {
    if (!found[k] || !found_back[k]) continue;
    if (cv::norm(back[k] - start[k]) > max_error) continue;
    out[box_of[k]].emplace_back(moved[k].x - start[k].x, moved[k].y - start[k].y);
  }
  return out;
}

}  // namespace

const char* to_string(ObjectReport::Source source) {
  switch (source) {
    case ObjectReport::Source::kFresh:
      return "fresh";
    case ObjectReport::Source::kPropagated:
      return "propagated";
    case ObjectReport::Source::kGrown:
      return "grown";
    case ObjectReport::Source::kMover:
      return "moving_region";
  }
  return "unknown";
}

ObjectHandler::ObjectHandler(const PinholeCamera& camera, const DynamicsOptions& options)
    : camera_(camera), options_(options) {}

const ObjectHandler::PastFrame* ObjectHandler::recent(std::uint64_t id) const {
  for (const PastFrame& f : recent_)
    if (f.id == id) return &f;
  return nullptr;
}

std::vector<ObjectState> ObjectHandler::box_states() const {
  std::vector<ObjectState> state(boxes_.size());
  for (std::size_t b = 0; b < boxes_.size(); ++b)
    state[b] = tracks_.tracks()[static_cast<std::size_t>(boxes_[b].track)].state;
  return state;
}

void ObjectHandler::prepare(const Frame& frame, const std::optional<SE3>& predicted_T_c_w) {
  const auto& features = *frame.features;
  boxes_.clear();
  fresh_ = true;
  age_ = 0;
  decisions_.clear();
  constraints_.clear();
  constrained_points_.clear();
  constrained_lines_.clear();
  threshold_ = 0.0;
  propagation_iou_ = stale_iou_ = -1.0;
  mover_regions_ = mover_points_ = 0;
  point_boxes_.assign(features.points.size(), 0);
  line_boxes_.assign(features.lines.size(), 0);
  point_excluded_.assign(features.points.size(), 0);
  line_excluded_.assign(features.lines.size(), 0);
  point_mover_.assign(features.points.size(), 0);
  line_mover_.assign(features.lines.size(), 0);
  recent_.push_front(PastFrame{frame.id, frame.features, std::nullopt});
  while (recent_.size() > kRecentFrames) recent_.pop_back();
  if (!options_.enabled || !frame.objects) {
    tracks_.clear();
    movers_.clear();
    return;
  }

  std::vector<perception::Detection> detections = frame.objects->boxes;
  std::stable_sort(detections.begin(), detections.end(),
                   [](const auto& a, const auto& b) { return a.score > b.score; });
  if (detections.size() > kMaxBoxes) detections.resize(kMaxBoxes);
  fresh_ = frame.objects->fresh;
  age_ = std::max(0, frame.objects->age);
  const std::uint64_t source = frame.id >= static_cast<std::uint64_t>(age_) ? frame.id - age_ : 0;
  const PastFrame* from = recent(source);
  std::vector<Box> boxes =
      propagate(detections, from, features, predicted_T_c_w, age_, ObjectReport::Source::kFresh);

  // A new detection: how well would the previous one have been carried to its frame?
  if (last_detection_frame_ && source > *last_detection_frame_ && from) {
    const PastFrame* previous = recent(*last_detection_frame_);
    const int gap = static_cast<int>(source - *last_detection_frame_);
    if (previous) {
      const std::optional<SE3> T_from_w = source == frame.id ? predicted_T_c_w : from->T_c_w;
      std::vector<perception::Detection> carried, stale;
      for (const Box& b : propagate(last_detection_, previous, *from->features, T_from_w, gap,
                                    ObjectReport::Source::kFresh))
        carried.push_back(b.detection);
      const float grow = std::min(0.3f, 0.05f * static_cast<float>(gap));
      for (auto d : last_detection_) {
        d.box = grown(d.box, grow * d.box.width / 2, grow * d.box.height / 2);
        stale.push_back(d);
      }
      propagation_iou_ = mean_best_iou(detections, carried);
      stale_iou_ = mean_best_iou(detections, stale);
    }
  }
  if (!last_detection_frame_ || source != *last_detection_frame_) {
    last_detection_frame_ = source;
    last_detection_ = detections;
  }

  // Moving regions found without a box in earlier frames, carried forward like boxes.
  for (Mover& m : movers_) {
    if (boxes.size() >= kMaxBoxes) break;
    const PastFrame* seen = recent(m.frame);
    const int age = static_cast<int>(frame.id - m.frame);
    auto carried = propagate({m.detection}, seen, features, predicted_T_c_w, age,
                             ObjectReport::Source::kMover);
    carried.front().source = ObjectReport::Source::kMover;
    carried.front().unconfirmed = m.unconfirmed;
    carried.front().age = age;
    carried.front().flat = m.flat;
    boxes.push_back(carried.front());
  }

  boxes_ = std::move(boxes);
  std::vector<perception::Detection> dets;
  for (const Box& b : boxes_) dets.push_back(b.detection);
  const auto tracks = tracks_.associate(dets, [this](const perception::Detection& d) {
    return options_.self_moving(d.class_name) || d.class_name == kMovingRegionClass;
  });
  for (std::size_t b = 0; b < boxes_.size(); ++b) boxes_[b].track = tracks[b];
  assign_features(frame);
  update_exclusions();
}

std::vector<ObjectHandler::Box> ObjectHandler::propagate(
    const std::vector<perception::Detection>& detections, const PastFrame* from,
    const features::FrameFeatures& to, const std::optional<SE3>& T_to_w, int age,
    ObjectReport::Source source) const {
  std::vector<Box> out;
  for (const auto& d : detections) {
    Box box;
    box.detection = d;
    box.source = source;
    out.push_back(box);
  }
  if (age <= 0) return out;
  const bool carry = options_.propagate_boxes && from != nullptr;
  if (!carry) {
    // Grown a little per frame of age: objects move meanwhile.
    const float grow = std::min(0.3f, 0.05f * static_cast<float>(age));
    for (Box& b : out) {
      auto& r = b.detection.box;
      r = grown(r, grow * r.width / 2, grow * r.height / 2);
      if (b.source == ObjectReport::Source::kFresh) b.source = ObjectReport::Source::kGrown;
    }
    return out;
  }
  const auto& old = *from->features;
  std::optional<SE3> T_to_from;
  if (from->T_c_w && T_to_w) T_to_from = (*T_to_w) * from->T_c_w->inverse();
  const auto predict = [&](const features::PointFeature& f) -> std::optional<Eigen::Vector2d> {
    const Eigen::Vector2d uv = f.keypoint.uv.cast<double>();
    if (!T_to_from) return uv;
    const Eigen::Vector3d p = f.has_depth() ? (*T_to_from) * camera_.unproject(uv, f.depth)
                                            : T_to_from->rotation() * camera_.unproject(uv, 1.0);
    if (p.z() <= 1e-6) return std::nullopt;
    return camera_.project(p);
  };
  std::vector<int> candidates;
  // Each box's sample of its object's features in the detector's frame (at most
  // kPropagationSample: a median needs no more), followed by optical flow all at once.
  std::vector<std::vector<std::size_t>> samples(out.size());
  std::vector<std::optional<std::pair<float, float>>> bands(out.size());
  for (std::size_t bi = 0; bi < out.size(); ++bi) {
    Box& b = out[bi];
    const cv::Rect2f& r = b.detection.box;
    // The object's features in the detector's frame: inside the box, and not behind the
    // object's depth band (the background moves with the camera, not with the object).
    std::vector<std::size_t> inside;
    std::vector<float> depths;
    for (std::size_t i = 0; i < old.points.size(); ++i) {
      if (!contains(r, old.points[i].keypoint.uv)) continue;
      inside.push_back(i);
      if (old.points[i].has_depth()) depths.push_back(old.points[i].depth);
    }
    const auto band = object_band(depths, options_.object_depth_gap);
    bands[bi] = band;
    std::vector<std::size_t> object;
    for (std::size_t i : inside)
      if (!band || !old.points[i].has_depth() || old.points[i].depth <= band->second)
        object.push_back(i);
    const std::size_t stride = std::max<std::size_t>(1, object.size() / kPropagationSample);
    for (std::size_t k = 0; k < object.size(); k += stride) samples[bi].push_back(object[k]);
  }
  const std::vector<std::vector<Eigen::Vector2d>> flow =
      options_.propagate_by_flow ? flow_shifts(old, to, samples, predict, options_.flow_max_error)
                                 : std::vector<std::vector<Eigen::Vector2d>>(out.size());
  for (std::size_t bi = 0; bi < out.size(); ++bi) {
    Box& b = out[bi];
    const cv::Rect2f& r = b.detection.box;
    const auto& band = bands[bi];
    std::vector<double> dx, dy;
    for (const Eigen::Vector2d& d : flow[bi]) {
      dx.push_back(d.x());
      dy.push_back(d.y());
    }
    if (static_cast<int>(dx.size()) < options_.min_propagation_matches) {
      // Too few followed by flow: matched by descriptor near the prediction instead.
      dx.clear();
      dy.clear();
      for (std::size_t i : samples[bi]) {
        const auto& f = old.points[i];
        const auto at = predict(f);
        if (!at) continue;
        // The object's own motion does not scale with the keypoint's level: one radius.
        const int level = f.keypoint.level;
        const double radius = options_.match_radius + options_.propagation_radius * age;
        to.grid.query(static_cast<float>(at->x()), static_cast<float>(at->y()),
                      static_cast<float>(radius), std::max(0, level - 1), level + 1, candidates);
        const int best_idx =
            unambiguous_match(f.descriptor, candidates, to.points, options_.descriptor_distance);
        if (best_idx < 0) continue;
        const Eigen::Vector2f shift =
            to.points[static_cast<std::size_t>(best_idx)].keypoint.uv - f.keypoint.uv;
        dx.push_back(shift.x());
        dy.push_back(shift.y());
      }
    }
    b.propagated_matches = static_cast<int>(dx.size());
    Eigen::Vector2d shift = Eigen::Vector2d::Zero();
    if (static_cast<int>(dx.size()) >= options_.min_propagation_matches) {
      shift = {median_of(dx), median_of(dy)};
      if (b.source == ObjectReport::Source::kFresh) b.source = ObjectReport::Source::kPropagated;
    } else {
      // Too few matches (a blurred or textureless object): it moves with the camera at least,
      // and is grown as an unpropagated box would be.
      if (T_to_from && band) {
        const Eigen::Vector2d c(r.x + r.width / 2.0, r.y + r.height / 2.0);
        const double z = 0.5 * (band->first + band->second);
        const Eigen::Vector3d p = (*T_to_from) * camera_.unproject(c, z);
        if (p.z() > 1e-6) shift = camera_.project(p) - c;
      }
      const float grow = std::min(0.3f, 0.05f * static_cast<float>(age));
      b.detection.box = grown(r, grow * r.width / 2, grow * r.height / 2);
      if (b.source == ObjectReport::Source::kFresh) b.source = ObjectReport::Source::kGrown;
    }
    // Moving regions are carried from one frame to the next and re-fitted: no margin.
    const float margin = b.source == ObjectReport::Source::kMover
                             ? 0.0f
                             : static_cast<float>(options_.propagation_margin * age);
    cv::Rect2f moved = b.detection.box;
    moved.x += static_cast<float>(shift.x());
    moved.y += static_cast<float>(shift.y());
    b.detection.box = grown(moved, margin, margin);
  }
  return out;
}

void ObjectHandler::grow_movers(const features::FrameFeatures& features,
                                const std::vector<cv::Rect2f>& plane_extent) {
  // A moving region found on a moving plane (find_movers) holds part of a rigid surface, which
  // moves whole: a frame plane with most of its points inside the region's box is the region's
  // (the flat face of a box carried, a door, the synthetic people), and the box grows
  // towards the plane's extent (the object coming further into view), by at most
  // propagation_radius pixels a frame on each side: how far a person's image moves in a frame.
  // A plane reaching farther (the floor, a wall) is only partly taken, and only while the box
  // still holds most of it.
  const cv::Rect2f image(0.0f, 0.0f, static_cast<float>(camera_.width),
                         static_cast<float>(camera_.height));
  const std::size_t n_planes = features.planes.size();
  const auto plane_of = [&](const features::PointFeature& f) -> std::optional<std::size_t> {
    if (f.plane < 0 || static_cast<std::size_t>(f.plane) >= n_planes) return std::nullopt;
    return static_cast<std::size_t>(f.plane);
  };
  std::vector<int> total(n_planes, 0);
  for (const auto& f : features.points)
    if (const auto k = plane_of(f)) ++total[*k];
  for (Box& box : boxes_) {
    if (box.source != ObjectReport::Source::kMover || !box.flat) continue;
    std::vector<int> inside(n_planes, 0);
    for (const auto& f : features.points)
      if (const auto k = plane_of(f)) inside[*k] += contains(box.detection.box, f.keypoint.uv);
    const auto reach = static_cast<float>(options_.propagation_radius * std::max(1, box.age));
    const cv::Rect2f bound = grown(box.detection.box, reach, reach) & image;
    cv::Rect2f region = box.detection.box & image;
    for (std::size_t k = 0; k < n_planes; ++k) {
      if (2 * inside[k] <= total[k] || plane_extent[k].area() <= 0.0f) continue;
      cv::Rect2f extent = plane_extent[k];
      extent.width += 1.0f;  // a box holds the pixels on its far edges too, as a region's does
      extent.height += 1.0f;
      region |= extent & bound;
    }
    box.detection.box = region;
  }
}

void ObjectHandler::assign_features(const Frame& frame) {
  const auto& features = *frame.features;
  const DynamicsOptions& opt = options_;
  // Image extent of each frame plane, to tell structural planes (floor, wall) from an object's.
  std::vector<cv::Rect2f> plane_extent;
  for (const auto& plane : features.planes) {
    float x0 = 1e9f, y0 = 1e9f, x1 = -1e9f, y1 = -1e9f;
    for (const auto& h : plane.hull) {
      if (h.z() <= 1e-3) continue;
      const Eigen::Vector2d uv = camera_.project(h);
      x0 = std::min(x0, static_cast<float>(uv.x()));
      y0 = std::min(y0, static_cast<float>(uv.y()));
      x1 = std::max(x1, static_cast<float>(uv.x()));
      y1 = std::max(y1, static_cast<float>(uv.y()));
    }
    const cv::Rect2f r = x1 > x0 && y1 > y0 ? cv::Rect2f(x0, y0, x1 - x0, y1 - y0) : cv::Rect2f();
    plane_extent.push_back(r & cv::Rect2f(0.f, 0.f, static_cast<float>(camera_.width),
                                          static_cast<float>(camera_.height)));
  }
  grow_movers(features, plane_extent);
  const auto structural = [&](std::size_t box, int plane) {
    if (plane < 0 || static_cast<std::size_t>(plane) >= plane_extent.size()) return false;
    const cv::Rect2f& e = plane_extent[static_cast<std::size_t>(plane)];
    const double area = e.area();
    if (area <= 0.0) return false;
    const double inside = (e & boxes_[box].detection.box).area();
    return 1.0 - inside / area >= opt.structural_outside;
  };
  const std::size_t n_boxes = boxes_.size();
  for (std::size_t i = 0; i < features.points.size(); ++i) {
    const auto& f = features.points[i];
    for (std::size_t b = 0; b < n_boxes; ++b) {
      if (!contains(boxes_[b].detection.box, f.keypoint.uv)) continue;
      if (structural(b, f.plane)) continue;  // the floor or wall seen through the box
      point_boxes_[i] |= std::uint64_t{1} << b;
    }
  }
  // Each box's object depth: from the features in it alone when it has some (the cupboard's
  // depth from the part of it a person in front does not hide), else from all of its features.
  std::vector<std::vector<float>> box_depths(n_boxes), exclusive_depths(n_boxes);
  for (std::size_t i = 0; i < features.points.size(); ++i) {
    const std::uint64_t mask = point_boxes_[i];
    if (!features.points[i].has_depth()) continue;
    for (std::size_t b = 0; b < n_boxes; ++b) {
      if (!((mask >> b) & 1U)) continue;
      box_depths[b].push_back(features.points[i].depth);
      if (mask == std::uint64_t{1} << b) exclusive_depths[b].push_back(features.points[i].depth);
    }
  }
  for (std::size_t b = 0; b < n_boxes; ++b) {
    auto& d = exclusive_depths[b].size() >= 5 ? exclusive_depths[b] : box_depths[b];
    const auto band = object_band(d, opt.object_depth_gap);
    if (!band) continue;
    std::vector<float> own;
    for (float z : d)
      if (z >= band->first && z <= band->second) own.push_back(z);
    boxes_[b].depth = median_of(own);
    boxes_[b].depth_near = band->first;
    boxes_[b].depth_far = band->second;
  }
  const auto behind = [&](std::size_t b, double depth) {
    return opt.separate_background && depth > 0.0 && boxes_[b].depth_far > 0.0f &&
           depth > boxes_[b].depth_far;
  };
  // A feature inside overlapping boxes (a person walking in front of a cupboard) belongs to the
  // object at its depth: the box whose depth is closest to the feature's.
  const auto nearest_box = [&](std::uint64_t mask, double depth) {
    if (depth <= 0.0 || (mask & (mask - 1)) == 0) return mask;  // no depth, or a single box
    std::uint64_t best = mask;
    double best_gap = std::numeric_limits<double>::infinity();
    for (std::size_t b = 0; b < n_boxes; ++b) {
      if (!((mask >> b) & 1U) || boxes_[b].depth < 0.0f) continue;
      const double gap = std::abs(boxes_[b].depth - depth);
      if (gap < best_gap) {
        best_gap = gap;
        best = std::uint64_t{1} << b;
      }
    }
    return best;
  };
  const auto drop_background = [&](std::uint64_t mask, double depth) {
    for (std::size_t b = 0; b < n_boxes; ++b)
      if (((mask >> b) & 1U) && behind(b, depth)) {
        mask &= ~(std::uint64_t{1} << b);
        ++boxes_[b].background_points;
      }
    return mask;
  };
  for (std::size_t i = 0; i < features.points.size(); ++i) {
    const double depth = features.points[i].has_depth() ? features.points[i].depth : 0.0;
    point_boxes_[i] = nearest_box(drop_background(point_boxes_[i], depth), depth);
  }
  for (std::size_t i = 0; i < features.lines.size(); ++i) {
    const auto& l = features.lines[i];
    for (std::size_t b = 0; b < n_boxes; ++b) {
      if (!contains(boxes_[b].detection.box, l.midpoint())) continue;
      bool on_structure = false;
      if (l.has_depth)
        for (std::size_t k = 0; k < features.planes.size() && !on_structure; ++k)
          on_structure = structural(b, static_cast<int>(k)) &&
                         std::abs(features.planes[k].distance(l.start_c)) < opt.plane_distance &&
                         std::abs(features.planes[k].distance(l.end_c)) < opt.plane_distance;
      if (!on_structure) line_boxes_[i] |= std::uint64_t{1} << b;
    }
    if (l.has_depth && opt.separate_background) {
      // A segment is background only when both of its ends are behind the object.
      const double near_end = std::min(l.start_c.z(), l.end_c.z());
      for (std::size_t b = 0; b < n_boxes; ++b)
        if (((line_boxes_[i] >> b) & 1U) && behind(b, near_end))
          line_boxes_[i] &= ~(std::uint64_t{1} << b);
    }
    line_boxes_[i] =
        nearest_box(line_boxes_[i], l.has_depth ? 0.5 * (l.start_c.z() + l.end_c.z()) : 0.0);
  }
}

void ObjectHandler::update_exclusions() {
  const std::vector<ObjectState> state = box_states();
  for (std::size_t i = 0; i < point_boxes_.size(); ++i)
    point_excluded_[i] =
        point_mover_[i] || label_for(point_boxes_[i], state) != FeatureLabel::kStatic ? 1 : 0;
  for (std::size_t i = 0; i < line_boxes_.size(); ++i)
    line_excluded_[i] =
        line_mover_[i] || label_for(line_boxes_[i], state) != FeatureLabel::kStatic ? 1 : 0;
}

void ObjectHandler::include_all() {
  std::fill(point_excluded_.begin(), point_excluded_.end(), 0);
  std::fill(line_excluded_.begin(), line_excluded_.end(), 0);
}

int ObjectHandler::static_points_with_depth(const Frame& frame) const {
  int n = 0;
  for (std::size_t i = 0; i < frame.features->points.size(); ++i)
    n += frame.features->points[i].has_depth() && !point_excluded(i) ? 1 : 0;
  return n;
}

std::vector<MotionMatch> ObjectHandler::match_to_reference(const Frame& frame, const PastFrame& ref,
                                                           const SE3& T_cur_ref,
                                                           std::uint64_t boxes) const {
  const DynamicsOptions& opt = options_;
  const auto& cur = *frame.features;
  const auto& old = *ref.features;
  const auto& pyramid = *cur.pyramid;
  const SE3 T_ref_cur = T_cur_ref.inverse();
  // Where a current pixel would be in the reference image if it were static.
  const auto predict = [&](const Eigen::Vector2d& uv,
                           double depth) -> std::optional<Eigen::Vector2d> {
    const Eigen::Vector3d p = depth > 0.0 ? T_ref_cur * camera_.unproject(uv, depth)
                                          : T_ref_cur.rotation() * camera_.unproject(uv, 1.0);
    if (p.z() <= 1e-6) return std::nullopt;
    return camera_.project(p);
  };
  std::vector<MotionMatch> out;
  // Points: best descriptor within the window, with a ratio test; one current feature per
  // reference feature.
  std::vector<int> candidates;
  // Per reference feature: the distance and slot in point_pairs of its current claim (slot -1:
  // none).
  std::vector<std::pair<int, std::ptrdiff_t>> taken(old.points.size(), {0, -1});
  std::vector<std::pair<std::size_t, int>> point_pairs;  // (current, reference)
  // A sample of the background (features outside every box) is matched too: it tells how far
  // static features land from the camera-motion prediction in this frame.
  std::size_t background = 0;
  for (std::size_t i = 0; i < cur.points.size(); ++i) background += point_boxes_[i] == 0;
  const std::size_t stride = std::max<std::size_t>(1, background / kBackgroundSample);
  std::size_t background_seen = 0;
  for (std::size_t i = 0; i < cur.points.size(); ++i) {
    if (point_boxes_[i] == 0 && background_seen++ % stride != 0) continue;
    if (point_boxes_[i] != 0 && (point_boxes_[i] & boxes) == 0) continue;
    const auto& f = cur.points[i];
    const auto at = predict(f.keypoint.uv.cast<double>(), f.has_depth() ? f.depth : 0.0);
    if (!at) continue;
    const int level = f.keypoint.level;
    const double r = opt.match_radius * pyramid.scale[static_cast<std::size_t>(level)];
    old.grid.query(static_cast<float>(at->x()), static_cast<float>(at->y()), static_cast<float>(r),
                   std::max(0, level - 1), level + 1, candidates);
    int best = 256;
    const int best_idx =
        unambiguous_match(f.descriptor, candidates, old.points, opt.descriptor_distance, &best);
    if (best_idx < 0) continue;
    auto& claim = taken[static_cast<std::size_t>(best_idx)];
    if (claim.second >= 0) {
      if (claim.first <= best) continue;
      point_pairs[static_cast<std::size_t>(claim.second)].second = -1;  // the earlier claim loses
    }
    claim = {best, static_cast<std::ptrdiff_t>(point_pairs.size())};
    point_pairs.emplace_back(i, best_idx);
  }
  for (const auto& [i, j] : point_pairs) {
    if (j < 0) continue;
    const auto& f = cur.points[i];
    const auto& g = old.points[static_cast<std::size_t>(j)];
    MotionMatch m;
    m.feature = static_cast<int>(i);
    m.ref_uv[0] = g.keypoint.uv.cast<double>();
    m.cur_uv[0] = f.keypoint.uv.cast<double>();
    if (g.has_depth()) m.ref_c[0] = camera_.unproject(m.ref_uv[0], g.depth);
    if (f.has_depth()) m.cur_c[0] = camera_.unproject(m.cur_uv[0], f.depth);
    m.scale = pyramid.scale[static_cast<std::size_t>(f.keypoint.level)];
    if (point_boxes_[i] == 0) out.push_back(m);  // background: box -1
    for (std::size_t b = 0; b < boxes_.size(); ++b)
      if (point_boxes_[i] & (std::uint64_t{1} << b)) {
        m.box = static_cast<int>(b);
        out.push_back(m);
      }
  }
  // Lines: midpoint within the window, similar direction, best LBD distance.
  const double max_angle = std::cos(20.0 * M_PI / 180.0);
  for (std::size_t i = 0; i < cur.lines.size(); ++i) {
    if ((line_boxes_[i] & boxes) == 0) continue;
    const auto& l = cur.lines[i];
    const Eigen::Vector3d mid_c = 0.5 * (l.start_c + l.end_c);
    const auto at = l.has_depth ? predict(camera_.project(mid_c), mid_c.z())
                                : predict(l.midpoint().cast<double>(), 0.0);
    if (!at) continue;
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
    if (best_idx < 0 || best > opt.line_descriptor_distance) continue;
    const auto& o = old.lines[static_cast<std::size_t>(best_idx)];
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
    for (std::size_t b = 0; b < boxes_.size(); ++b)
      if (line_boxes_[i] & (std::uint64_t{1} << b)) {
        m.box = static_cast<int>(b);
        out.push_back(m);
      }
  }
  return out;
}

double ObjectHandler::adaptive_threshold(const std::vector<MotionMatch>& matches,
                                         const SE3& T_cur_ref) const {
  std::vector<double> distances;
  for (const MotionMatch& m : matches)
    if (m.box < 0)
      if (const auto d = motion_distance(camera_, T_cur_ref, m, 0))
        distances.push_back(*d / m.scale);
  const double floor = options_.epipolar_threshold;
  if (distances.size() < 20) return floor;
  // For 2D Gaussian residuals 3 x the median is about the 99.5th percentile.
  return std::max(floor, options_.background_factor * median_of(distances));
}

void ObjectHandler::classify(const Frame& frame, const SE3& T_c_w) {
  const DynamicsOptions& opt = options_;
  const std::size_t n_boxes = boxes_.size();
  decisions_.assign(n_boxes, ObjectDecision{});
  constraints_.assign(n_boxes, ConstraintDecision{});
  constrained_points_.clear();
  constrained_lines_.clear();
  if (n_boxes == 0) return;
  std::vector<MotionMatch> matches;
  // The reference: dynamics.frame_gap tracked frames back, or the oldest one kept.
  const PastFrame* reference =
      history_.empty()
          ? nullptr
          : &history_[std::min(history_.size(), static_cast<std::size_t>(opt.frame_gap)) - 1];
  if (reference) {
    const PastFrame& ref = *reference;
    const SE3 T_cur_ref = T_c_w * ref.T_c_w->inverse();
    matches = match_to_reference(frame, ref, T_cur_ref);
    DynamicsOptions frame_opt = opt;
    frame_opt.epipolar_threshold = adaptive_threshold(matches, T_cur_ref);
    threshold_ = frame_opt.epipolar_threshold;
    decisions_ =
        detect_dynamic_objects(static_cast<int>(n_boxes), matches, camera_, T_cur_ref, frame_opt);
    // A box with too few matches to that frame (an object that just came into view) is tried
    // against the last frame.
    if (&ref != &history_.front()) {
      std::uint64_t undecided = 0;
      for (std::size_t b = 0; b < n_boxes; ++b)
        if (!decisions_[b].decided) undecided |= std::uint64_t{1} << b;
      if (undecided != 0) {
        const SE3 T_cur_last = T_c_w * history_.front().T_c_w->inverse();
        const auto recent_matches =
            match_to_reference(frame, history_.front(), T_cur_last, undecided);
        DynamicsOptions last_opt = opt;
        last_opt.epipolar_threshold = adaptive_threshold(recent_matches, T_cur_last);
        const auto retry = detect_dynamic_objects(static_cast<int>(n_boxes), recent_matches,
                                                  camera_, T_cur_last, last_opt);
        for (std::size_t b = 0; b < n_boxes; ++b)
          if (!decisions_[b].decided && retry[b].decided) decisions_[b] = retry[b];
      }
    }
    // An object seen through a moving one (a cupboard behind a walking person) is not judged by
    // the features it shares with it: when most of a box's matches lie inside another box found
    // dynamic, the box gets no verdict this frame.
    std::vector<bool> moving(n_boxes);
    for (std::size_t b = 0; b < n_boxes; ++b)
      moving[b] =
          decisions_[b].dynamic ||
          tracks_.tracks()[static_cast<std::size_t>(boxes_[b].track)].state != ObjectState::kStatic;
    const auto in_front = [&](std::size_t c, std::size_t b) {
      return boxes_[c].depth > 0.0f && boxes_[b].depth > 0.0f && boxes_[c].depth < boxes_[b].depth;
    };
    for (std::size_t b = 0; b < n_boxes; ++b) {
      if (!decisions_[b].dynamic) continue;
      int total = 0, shared = 0;
      for (const MotionMatch& m : matches) {
        if (m.box != static_cast<int>(b)) continue;
        ++total;
        const cv::Point2f p(static_cast<float>(m.cur_uv[0].x()),
                            static_cast<float>(m.cur_uv[0].y()));
        for (std::size_t c = 0; c < n_boxes; ++c)
          if (c != b && moving[c] && in_front(c, b) && boxes_[c].detection.box.contains(p)) {
            ++shared;
            break;
          }
      }
      if (2 * shared > total) decisions_[b].decided = decisions_[b].dynamic = false;
    }
    for (std::size_t b = 0; b < n_boxes; ++b) {
      decisions_[b].box = static_cast<int>(b);
      ObjectDecision evidence = decisions_[b];
      int needed = opt.static_frames_to_clear;
      if (opt.self_moving(boxes_[b].detection.class_name)) {
        // The class prior: only a verdict of "still" under the strict epsilon_d counts, for a
        // sustained time.
        needed = opt.moving_class_static_frames;
        if (evidence.decided && !evidence.dynamic &&
            !(evidence.median_distance <= opt.epipolar_threshold)) {
          // Most of its features are off the camera's motion: moving, even if fewer than
          // epsilon_r; between the strict and the adaptive epsilon_d: no evidence either way.
          evidence.dynamic = evidence.median_distance > threshold_;
          evidence.decided = evidence.dynamic;
        }
      }
      tracks_.update(boxes_[b].track, evidence, needed);
    }
    // Algorithm 2 for moving objects of the classes that can only slide.
    const auto& planes = frame.features->planes;
    const SE3 T_w_c = T_c_w.inverse();
    std::vector<Eigen::Vector4d> planes_w;
    for (const auto& p : planes) {
      const Eigen::Vector3d n_w = T_w_c.rotation() * p.normal;
      planes_w.emplace_back(n_w.x(), n_w.y(), n_w.z(), p.d + p.normal.dot(T_c_w.translation()));
    }
    for (std::size_t b = 0; b < n_boxes; ++b) {
      const int t = boxes_[b].track;
      if (tracks_.tracks()[static_cast<std::size_t>(t)].state == ObjectState::kStatic) continue;
      if (!opt.constraints || !opt.constrainable(boxes_[b].detection.class_name)) {
        tracks_.set_constrained(t, false, -1);
        continue;
      }
      std::vector<const MotionMatch*> object;
      for (const MotionMatch& m : matches)
        if (m.box == static_cast<int>(b)) object.push_back(&m);
      // Only planes that reach beyond the box can hold the object (the floor, not its seat).
      std::vector<Eigen::Vector4d> candidates;
      std::vector<int> index;
      for (std::size_t k = 0; k < planes.size(); ++k) {
        bool inside_only = true;
        for (const auto& h : planes[k].hull) {
          if (h.z() <= 1e-3) continue;
          const Eigen::Vector2d uv = camera_.project(h);
          if (!boxes_[b].detection.box.contains(
                  cv::Point2f(static_cast<float>(uv.x()), static_cast<float>(uv.y()))))
            inside_only = false;
        }
        if (inside_only) continue;
        candidates.push_back(planes_w[k]);
        index.push_back(static_cast<int>(k));
      }
      ConstraintDecision c =
          check_moving_constraint(object, candidates, ref.T_c_w->inverse(), T_w_c, opt);
      if (c.plane >= 0) c.plane = index[static_cast<std::size_t>(c.plane)];
      constraints_[b] = c;
      tracks_.set_constrained(t, c.constrained, c.plane);
    }
  }
  update_exclusions();
  // Moving regions: confirmed while Algorithm 1 keeps finding them moving, dropped when found
  // still (their track turned static) or unconfirmed for too long.
  std::vector<Mover> kept;
  for (std::size_t b = 0; b < n_boxes; ++b) {
    if (boxes_[b].source != ObjectReport::Source::kMover) continue;
    const auto& track = tracks_.tracks()[static_cast<std::size_t>(boxes_[b].track)];
    if (track.state == ObjectState::kStatic) continue;
    Mover m;
    m.detection = boxes_[b].detection;
    m.frame = frame.id;
    m.unconfirmed = decisions_[b].dynamic ? 0 : boxes_[b].unconfirmed + 1;
    m.flat = boxes_[b].flat;
    if (m.unconfirmed < kMoverLife) kept.push_back(m);
  }
  movers_ = std::move(kept);
  // Residuals (9) and (10) from the matched features of constrained objects.
  if (!reference) return;
  const std::vector<ObjectState> state = box_states();
  const SE3 T_w_ref = reference->T_c_w->inverse();
  const SE3 T_w_c = T_c_w.inverse();
  for (const MotionMatch& m : matches) {
    if (m.box < 0) continue;  // background
    const auto b = static_cast<std::size_t>(m.box);
    if (state[b] != ObjectState::kConstrained) continue;
    const std::uint64_t mask = m.line ? line_boxes_[static_cast<std::size_t>(m.feature)]
                                      : point_boxes_[static_cast<std::size_t>(m.feature)];
    if (label_for(mask, state) != FeatureLabel::kConstrained) continue;  // also in a dynamic box
    const int plane = constraints_[b].plane;
    if (plane < 0) continue;
    const Eigen::Vector3d n_w =
        T_w_c.rotation() * frame.features->planes[static_cast<std::size_t>(plane)].normal;
    if (!m.line) {
      if (!m.ref_c[0] || !m.cur_c[0]) continue;
      optim::ConstrainedPointMeasurement c;
      c.p_last_w = T_w_ref * (*m.ref_c[0]);
      c.p_c = *m.cur_c[0];
      c.n_w = n_w;
      c.information = 1.0 / (opt.constraint_point_sigma * opt.constraint_point_sigma);
      constrained_points_.push_back(c);
    } else {
      if (!m.ref_c[0] || !m.ref_c[1] || !m.cur_c[0] || !m.cur_c[1]) continue;
      optim::ConstrainedLineMeasurement c;
      c.s_last_w = T_w_ref.rotation() * (*m.ref_c[1] - *m.ref_c[0]);
      c.s_c = *m.cur_c[1] - *m.cur_c[0];
      c.n_w = n_w;
      c.information = 1.0 / (opt.constraint_line_sigma * opt.constraint_line_sigma);
      constrained_lines_.push_back(c);
    }
  }
}

/// Frame planes seen to move: their points with evidence pass a region's test (at least
/// dynamics.mover_min_seeds seeds, and at least dynamics.mover_seed_share of them seeds).
std::vector<std::uint8_t> ObjectHandler::moving_planes(
    const features::FrameFeatures& features, const std::vector<std::uint8_t>& seed,
    const std::vector<std::uint8_t>& measured) const {
  const std::size_t n_planes = features.planes.size();
  std::vector<int> seeds(n_planes, 0), with_evidence(n_planes, 0);
  for (std::size_t i = 0; i < features.points.size(); ++i) {
    const int k = features.points[i].plane;
    if (k < 0 || static_cast<std::size_t>(k) >= n_planes || !measured[i]) continue;
    ++with_evidence[static_cast<std::size_t>(k)];
    seeds[static_cast<std::size_t>(k)] += seed[i];
  }
  std::vector<std::uint8_t> moving(n_planes, 0);
  for (std::size_t k = 0; k < n_planes; ++k)
    moving[k] = seeds[k] >= options_.mover_min_seeds &&
                seeds[k] >= options_.mover_seed_share * with_evidence[k];
  return moving;
}

MoverResult ObjectHandler::find_movers(const Frame& frame, const SE3& T_c_w,
                                       const std::vector<MotionEvidence>& evidence) {
  MoverResult result;
  const DynamicsOptions& opt = options_;
  if (!opt.enabled || !opt.find_movers || !frame.objects) return result;
  const auto& points = frame.features->points;
  const std::size_t n = points.size();
  std::vector<std::uint8_t> seed(n, 0), measured(n, 0);
  std::vector<map::PointId> landmark(n, map::kNoId);
  int seeds = 0;
  for (const MotionEvidence& e : evidence) {
    const auto i = static_cast<std::size_t>(e.point);
    if (i >= n || !points[i].has_depth() || point_excluded(i)) continue;
    const auto& f = points[i];
    const Eigen::Vector3d seen = camera_.unproject(f.keypoint.uv.cast<double>(), f.depth);
    const double limit = opt.mover_displacement + opt.mover_relative * f.depth;
    measured[i] = 1;
    if (e.landmark != map::kNoId) landmark[i] = e.landmark;
    if (e.expected_c.z() <= 1e-6) continue;
    // Off in the image as well as in depth: a depth error alone (dark or shiny surfaces, mixed
    // pixels at an edge) moves a point along its ray, not across the image.
    const double scale = frame.features->pyramid->scale[static_cast<std::size_t>(f.keypoint.level)];
    const double pixels =
        (camera_.project(e.expected_c) - f.keypoint.uv.cast<double>()).norm() / scale;
    if (!seed[i] && (seen - e.expected_c).norm() > limit && pixels > opt.mover_pixels) {
      seed[i] = 1;
      ++seeds;
    }
  }
  std::vector<Mover> previous_candidates;
  for (Mover& c : candidates_)
    if (frame.id - c.frame <= 2) previous_candidates.push_back(c);
  candidates_.clear();
  if (seeds < opt.mover_min_seeds) return result;
  // Nodes: points with depth not yet left out; a point on a frame plane (floor, wall, desk top)
  // joins a region only as a seed, so that a region never spreads along the floor a person
  // stands on; unless the plane itself is seen to move (as many of its points with evidence
  // are seeds as a region needs): the flat side of a box carried, a door, a cart.
  const std::vector<std::uint8_t> moving_plane = moving_planes(*frame.features, seed, measured);
  const auto on_moving_plane = [&](std::size_t i) {
    const int plane = points[i].plane;
    return plane >= 0 && static_cast<std::size_t>(plane) < moving_plane.size() &&
           moving_plane[static_cast<std::size_t>(plane)] != 0;
  };
  std::vector<std::size_t> nodes;
  int with_depth = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!points[i].has_depth() || point_excluded(i)) continue;
    ++with_depth;
    if (seed[i] || points[i].plane < 0 || on_moving_plane(i)) nodes.push_back(i);
  }
  std::vector<int> component(n, -1);
  const double r2 = opt.mover_link_radius * opt.mover_link_radius;
  int next = 0;
  std::vector<std::size_t> stack;
  for (std::size_t s0 : nodes) {
    if (!seed[s0] || component[s0] >= 0) continue;
    const int c = next++;
    component[s0] = c;
    stack.assign(1, s0);
    std::vector<std::size_t> members;
    while (!stack.empty()) {
      const std::size_t a = stack.back();
      stack.pop_back();
      members.push_back(a);
      const auto& pa = points[a];
      for (std::size_t b : nodes) {
        if (component[b] >= 0) continue;
        const auto& pb = points[b];
        if ((pa.keypoint.uv - pb.keypoint.uv).cast<double>().squaredNorm() > r2) continue;
        if (std::abs(pa.depth - pb.depth) > opt.mover_link_depth) continue;
        component[b] = c;
        stack.push_back(b);
      }
    }
    int region_seeds = 0, region_measured = 0;
    for (std::size_t m : members) {
      region_seeds += seed[m];
      region_measured += measured[m];
    }
    // A region of most of the view is a bad pose, not a mover: nothing can be told then.
    if (region_seeds < opt.mover_min_seeds ||
        region_seeds < opt.mover_seed_share * region_measured ||
        members.size() * 2 > static_cast<std::size_t>(with_depth))
      continue;
    float x0 = 1e9f, y0 = 1e9f, x1 = -1e9f, y1 = -1e9f;
    for (std::size_t m : members) {
      const auto& uv = points[m].keypoint.uv;
      x0 = std::min(x0, uv.x());
      y0 = std::min(y0, uv.y());
      x1 = std::max(x1, uv.x());
      y1 = std::max(y1, uv.y());
    }
    // Seen in two frames in a row at the same place (the earlier region carried here by its
    // features' motion), or it is only a candidate: depth noise at an object's edge and a
    // mismatch or two can make one frame's region, rarely the same one twice.
    const cv::Rect2f region(x0, y0, x1 - x0 + 1.0f, y1 - y0 + 1.0f);
    bool confirmed = false;
    for (const Mover& c : previous_candidates) {
      const auto carried =
          propagate({c.detection}, recent(c.frame), *frame.features, T_c_w,
                    static_cast<int>(frame.id - c.frame), ObjectReport::Source::kMover);
      const cv::Rect2f& r = carried.front().detection.box;
      const double overlap = (r & region).area();
      confirmed = confirmed || overlap > 0.5 * std::min(r.area(), region.area());
    }
    perception::Detection d;
    d.box = region;
    d.class_name = kMovingRegionClass;
    d.class_id = -1;
    d.score = static_cast<float>(region_seeds) / static_cast<float>(std::max(1, region_measured));
    if (!confirmed) {
      candidates_.push_back(Mover{d, frame.id, 0, false});
      continue;
    }
    float z0 = 1e9f, z1 = -1e9f;
    bool flat = false;  // found on a moving plane
    for (std::size_t m : members) {
      flat = flat || on_moving_plane(m);
      point_mover_[m] = 1;
      if (seed[m] && landmark[m] != map::kNoId) result.moved_landmarks.push_back(landmark[m]);
      z0 = std::min(z0, points[m].depth);
      z1 = std::max(z1, points[m].depth);
    }
    // Segments within the region's extent and depth are the mover's too.
    for (std::size_t i = 0; i < frame.features->lines.size(); ++i) {
      const auto& l = frame.features->lines[i];
      if (!l.has_depth || !contains(region, l.midpoint())) continue;
      const double z = 0.5 * (l.start_c.z() + l.end_c.z());
      if (z >= z0 - opt.mover_link_depth && z <= z1 + opt.mover_link_depth) line_mover_[i] = 1;
    }
    ++mover_regions_;
    mover_points_ += static_cast<int>(members.size());
    result.any = true;
    // The region is carried to the next frames as a box, unless a known moving object's box
    // already covers it.
    bool covered = false;
    const auto state = box_states();
    for (std::size_t b = 0; b < boxes_.size(); ++b)
      covered = covered || (state[b] != ObjectState::kStatic &&
                            perception::iou(boxes_[b].detection.box, region) > 0.5);
    if (!covered && movers_.size() < 8) movers_.push_back(Mover{d, frame.id, 0, flat});
  }
  if (result.any) update_exclusions();
  return result;
}

void ObjectHandler::move_world(const SE3& W) {
  const SE3 W_inv = W.inverse();
  for (auto* frames : {&recent_, &history_})
    for (PastFrame& f : *frames)
      if (f.T_c_w) f.T_c_w = (*f.T_c_w) * W_inv;
}

void ObjectHandler::remember(const Frame& frame, const SE3& T_c_w) {
  if (!recent_.empty() && recent_.front().id == frame.id) recent_.front().T_c_w = T_c_w;
  history_.push_front(PastFrame{frame.id, frame.features, T_c_w});
  while (history_.size() > static_cast<std::size_t>(options_.frame_gap)) history_.pop_back();
}

void ObjectHandler::forget() {
  history_.clear();
  movers_.clear();
  candidates_.clear();
}

ObjectOutputs ObjectHandler::outputs(const Frame& frame) const {
  ObjectOutputs out;
  const auto& features = *frame.features;
  out.point_labels.assign(features.points.size(), FeatureLabel::kStatic);
  out.line_labels.assign(features.lines.size(), FeatureLabel::kStatic);
  out.fresh = fresh_;
  out.age = age_;
  out.threshold = threshold_;
  out.propagation_iou = propagation_iou_;
  out.stale_iou = stale_iou_;
  out.mover_regions = mover_regions_;
  out.mover_points = mover_points_;
  const std::vector<ObjectState> state = box_states();
  for (std::size_t b = 0; b < boxes_.size(); ++b) {
    const auto& track = tracks_.tracks()[static_cast<std::size_t>(boxes_[b].track)];
    ObjectReport r;
    r.detection = boxes_[b].detection;
    r.track_id = track.id;
    r.state = track.state;
    if (b < decisions_.size()) r.decision = decisions_[b];
    if (b < constraints_.size()) r.constraint = constraints_[b];
    r.source = boxes_[b].source;
    r.propagated_matches = boxes_[b].propagated_matches;
    r.depth_near = boxes_[b].depth_near;
    r.depth_far = boxes_[b].depth_far;
    r.background_points = boxes_[b].background_points;
    out.objects.push_back(r);
  }
  for (std::size_t i = 0; i < point_boxes_.size(); ++i)
    out.point_labels[i] =
        point_mover_[i] ? FeatureLabel::kDynamic : label_for(point_boxes_[i], state);
  for (std::size_t i = 0; i < line_boxes_.size(); ++i)
    out.line_labels[i] = line_mover_[i] ? FeatureLabel::kDynamic : label_for(line_boxes_[i], state);
  out.constrained_point_residuals = static_cast<int>(constrained_points_.size());
  out.constrained_line_residuals = static_cast<int>(constrained_lines_.size());
  return out;
}

}  // namespace mcslam::slam
