#include "mcslam/slam/tracker.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <unordered_map>
#include <unordered_set>

#include "mcslam/features/lines.hpp"
#include "mcslam/features/matching.hpp"
#include "mcslam/optim/pose_optimizer.hpp"
#include "mcslam/optim/rolling_shutter.hpp"
#include "mcslam/place/matching.hpp"
#include "measurement.hpp"

namespace mcslam::slam {
namespace {

/// The descriptors of a keyframe's features that observe a map point, and those features'
/// indices. Call under the map's read lock.
void landmark_descriptors(const map::Map& map, const map::KeyFrame& kf,
                          std::vector<features::OrbDescriptor>& descriptors,
                          std::vector<int>& indices) {
  for (std::size_t i = 0; i < kf.landmarks.size(); ++i)
    if (kf.landmarks[i] != map::kNoId && map.point(kf.landmarks[i]) != nullptr) {
      descriptors.push_back(kf.features->points[i].descriptor);
      indices.push_back(static_cast<int>(i));
    }
}

constexpr int kRotationBins = 30;

/// Keeps the matches whose keypoint-angle change falls into the three most common bins of a
/// histogram (ORB-SLAM2's rotation consistency); the others are dropped.
class RotationHistogram {
 public:
  void add(int feature, float angle_from, float angle_to) {
    float rot = angle_from - angle_to;
    if (rot < 0.0f) rot += 360.0f;
    int bin = static_cast<int>(std::lround(rot * kRotationBins / 360.0f));
    if (bin == kRotationBins) bin = 0;
    bins_[static_cast<std::size_t>(bin)].push_back(feature);
  }
  /// Features outside the dominant bins.
  std::vector<int> inconsistent() const {
    std::array<std::size_t, 3> top{0, 0, 0};
    std::array<int, 3> idx{-1, -1, -1};
    for (int i = 0; i < kRotationBins; ++i) {
      const std::size_t n = bins_[static_cast<std::size_t>(i)].size();
      if (n > top[0]) {
        top = {n, top[0], top[1]};
        idx = {i, idx[0], idx[1]};
      } else if (n > top[1]) {
        top = {top[0], n, top[1]};
        idx = {idx[0], i, idx[1]};
      } else if (n > top[2]) {
        top[2] = n;
        idx[2] = i;
      }
    }
    // Secondary bins count only when they hold at least a tenth of the main one.
    if (top[1] < top[0] / 10) idx[1] = -1;
    if (top[2] < top[0] / 10) idx[2] = -1;
    std::vector<int> out;
    for (int i = 0; i < kRotationBins; ++i) {
      if (i == idx[0] || i == idx[1] || i == idx[2]) continue;
      const auto& b = bins_[static_cast<std::size_t>(i)];
      out.insert(out.end(), b.begin(), b.end());
    }
    return out;
  }

 private:
  std::array<std::vector<int>, kRotationBins> bins_;
};

// The pose from the established landmarks alone, and which of the other observations it
// explains (TrackerOptions::established_age).
struct EstablishedGate {
  SE3 T_c_w;
  std::vector<bool> keep_point;  // per problem.points
  std::vector<bool> keep_line;   // per problem.lines
};

// Nullopt when the established landmarks are not enough to stand alone (or all are established).
std::optional<EstablishedGate> gate_by_established(const PinholeCamera& camera,
                                                   const optim::PoseProblem& problem,
                                                   const std::vector<bool>& established_point,
                                                   const std::vector<bool>& established_line,
                                                   const SE3& T_c_w,
                                                   const TrackerOptions& options) {
  optim::PoseProblem anchor;
  for (std::size_t i = 0; i < problem.points.size(); ++i)
    if (established_point[i]) anchor.points.push_back(problem.points[i]);
  for (std::size_t i = 0; i < problem.lines.size(); ++i)
    if (established_line[i]) anchor.lines.push_back(problem.lines[i]);
  anchor.planes = problem.planes;
  const std::size_t young =
      problem.points.size() + problem.lines.size() - anchor.points.size() - anchor.lines.size();
  // Enough when the established landmarks alone would pass the frame's own success test.
  const auto enough = [&](std::size_t points_and_lines, std::size_t planes) {
    const auto n = static_cast<int>(points_and_lines);
    return n >= options.min_pose_inliers &&
           n + options.plane_inlier_weight * static_cast<int>(planes) >=
               options.min_local_map_inliers;
  };
  if (young == 0 || !enough(anchor.points.size() + anchor.lines.size(), anchor.planes.size()))
    return std::nullopt;
  // Two robust rounds: the pose only has to classify the rest, and the final solve refines it.
  optim::PoseOptimizerOptions anchor_options = options.pose;
  anchor_options.rounds = std::min(anchor_options.rounds, 2);
  anchor_options.robust_rounds = std::min(anchor_options.robust_rounds, 2);
  const auto result = optim::optimize_pose(camera, T_c_w, anchor, anchor_options);
  if (result.failed ||
      !enough(static_cast<std::size_t>(result.num_inliers + result.num_line_inliers),
              static_cast<std::size_t>(result.num_plane_inliers)))
    return std::nullopt;
  EstablishedGate gate{result.T_c_w, {}, {}};
  const double g = options.established_gate;
  gate.keep_point.resize(problem.points.size());
  for (std::size_t i = 0; i < problem.points.size(); ++i) {
    const auto& obs = problem.points[i];
    const double limit =
        g * (obs.measurement.has_depth() ? options.pose.chi2_rgbd : options.pose.chi2_mono);
    gate.keep_point[i] =
        established_point[i] ||
        optim::reprojection_chi2(camera, obs.measurement, gate.T_c_w * obs.p_w) <= limit;
  }
  gate.keep_line.resize(problem.lines.size());
  for (std::size_t i = 0; i < problem.lines.size(); ++i) {
    const auto& obs = problem.lines[i];
    const double chi2 = optim::line_chi2(camera, obs.measurement, gate.T_c_w * obs.start_w,
                                         gate.T_c_w * obs.end_w) *
                        obs.measurement.information;
    gate.keep_line[i] = established_line[i] || chi2 <= g * options.pose.chi2_line;
  }
  return gate;
}

// Keeps the entries of `items` whose flag is set.
template <typename T>
void keep_flagged(std::vector<T>& items, const std::vector<bool>& keep) {
  std::size_t out = 0;
  for (std::size_t i = 0; i < items.size(); ++i)
    if (keep[i]) items[out++] = std::move(items[i]);
  items.resize(out);
}

}  // namespace

Tracker::Associations::Associations(const Frame& frame)
    : points(frame.features->points.size()),
      lines(frame.features->lines.size()),
      planes(frame.features->planes.size()),
      from_last(frame.features->points.size(), -1) {}

void Tracker::Associations::clear() {
  std::fill(points.begin(), points.end(), Match{});
  std::fill(from_last.begin(), from_last.end(), -1);
  std::fill(lines.begin(), lines.end(), LineMatch{});
  std::fill(planes.begin(), planes.end(), PlaneMatch{});
}

int Tracker::Associations::active_points() const {
  return static_cast<int>(
      std::count_if(points.begin(), points.end(), [](const Match& m) { return m.active; }));
}

int Tracker::Associations::active_lines() const {
  return static_cast<int>(
      std::count_if(lines.begin(), lines.end(), [](const LineMatch& m) { return m.active; }));
}

int Tracker::Associations::inlier_points(bool landmarks_only) const {
  return static_cast<int>(std::count_if(points.begin(), points.end(), [&](const Match& m) {
    return m.active && !m.outlier && (!landmarks_only || m.landmark != map::kNoId);
  }));
}

int Tracker::Associations::inlier_lines(bool landmarks_only) const {
  return static_cast<int>(std::count_if(lines.begin(), lines.end(), [&](const LineMatch& m) {
    return m.active && !m.outlier && (!landmarks_only || m.landmark != map::kNoId);
  }));
}

int Tracker::Associations::inlier_planes() const {
  return static_cast<int>(std::count_if(
      planes.begin(), planes.end(), [](const PlaneMatch& m) { return m.active && !m.outlier; }));
}

const char* to_string(TrackingState state) {
  switch (state) {
    case TrackingState::kNotInitialized:
      return "not_initialized";
    case TrackingState::kOk:
      return "ok";
    case TrackingState::kLost:
      return "lost";
  }
  return "unknown";
}

Tracker::Tracker(const PinholeCamera& camera, const TrackerOptions& options, const map::Map& map,
                 std::shared_ptr<const place::Vocabulary> vocabulary, int direct_levels_up)
    : camera_(camera),
      options_(options),
      map_(map),
      vocabulary_(std::move(vocabulary)),
      direct_levels_up_(direct_levels_up),
      pose_filter_(options.pose_filter),
      objects_(camera, options.dynamics) {
  if (options.pose_filter.lag > 0) pose_smoother_.emplace(options.pose_filter.lag);
}

std::vector<optim::LaggedPose> Tracker::flush_lagged_poses() {
  return pose_smoother_ ? pose_smoother_->flush() : std::vector<optim::LaggedPose>{};
}

TrackingOutcome Tracker::track(const Frame& frame, bool mapper_idle, std::size_t mapper_queue,
                               StageTimes* times) {
  // One shared lock for the whole frame: every read sees one state of the map, never a
  // correction half applied (the mapper writes between frames, or waits for this one).
  Stopwatch watch;
  const auto map_lock = map_.read_lock();
  if (times) times->add("map_wait", watch.elapsed_ms());  // while the mapper writes
  watch.restart();
  follow_map();
  if (state_ == TrackingState::kNotInitialized) {
    TrackingOutcome out = initialize(frame);
    if (times) times->add("initialize", watch.elapsed_ms());
    return out;
  }

  Associations assoc(frame);
  SE3 T_c_w;
  // The first estimate leaves out the features of objects known to move; when that leaves too
  // little (a moving object filling the view), all features go in and the robust loss copes.
  {
    std::optional<SE3> predicted;
    if (state_ == TrackingState::kOk)
      if (const auto T_last = last_frame_pose()) predicted = predict(frame, *T_last);
    objects_.prepare(frame, predicted);
  }
  if (times) times->add("object_prepare", watch.elapsed_ms());
  watch.restart();
  FirstEstimate first = first_estimate(frame, assoc, T_c_w);
  if (!first.ok && objects_.any()) {
    objects_.include_all();
    assoc.clear();
    first = first_estimate(frame, assoc, T_c_w);
  }
  relocalisation_work_.reset();  // kept only for the frame's second try
  // After a place search's pose the next frames are held to its stricter test (ORB-SLAM2's
  // rule); a pose found from the last one was tracked, not guessed, and only its own frame is.
  if (first.relocalised && !relocalisation_.from_last_pose) last_relocalisation_frame_ = frame.id;
  if (times) times->add("track_frame", watch.elapsed_ms());

  if (first.ok && objects_.any()) {
    watch.restart();
    objects_.classify(frame, T_c_w);
    if (times) times->add("dynamics", watch.elapsed_ms());
  }

  watch.restart();
  const bool ok = first.ok && refine_with_local_map(frame, assoc, T_c_w, first.relocalised);
  if (times) times->add("track_local_map", watch.elapsed_ms());

  TrackingOutcome out = outcome_of(frame, assoc, first, ok);
  if (!ok) {
    state_ = TrackingState::kLost;
    velocity_.reset();
    previous_velocity_.reset();
    pose_filter_.reset();
    objects_.forget();
    out.state = state_;
    return out;
  }
  watch.restart();
  accept(frame, assoc, T_c_w, mapper_idle, mapper_queue, out);
  if (times) times->add("keyframe_decision", watch.elapsed_ms());
  return out;
}

SE3 Tracker::predict(const Frame& frame, const SE3& T_last) const {
  // The constant-velocity prediction over this frame's own interval: after a dropped frame (live
  // cameras, --realtime) it spans two steps, and one step's motion would leave half the turn
  // to the matching window (at freiburg1_rpy's 1.5 rad/s, 3 degrees).
  const std::optional<SE3> motion =
      last_ ? predicted_motion(frame.timestamp - last_->frame.timestamp) : std::nullopt;
  return motion ? (*motion) * T_last : T_last;
}

Tracker::FirstEstimate Tracker::first_estimate(const Frame& frame, Associations& assoc,
                                               SE3& T_c_w) {
  if (state_ != TrackingState::kOk) return find_again(frame, assoc, T_c_w);
  FirstEstimate first;
  first.ok = track_from_last_frame(frame, assoc, T_c_w);
  return first;
}

bool Tracker::track_without_velocity(const Frame& frame, Associations& assoc, SE3& T_c_w) {
  Associations by_descriptor(frame);
  SE3 T_by_descriptor = T_c_w;
  const bool descriptor_ok = track_reference_keyframe(frame, by_descriptor, T_by_descriptor);
  bool ok = false;
  if (const std::optional<SE3> T_last = last_frame_pose())
    ok = track_last_frame(frame, *T_last, assoc, T_c_w);
  const auto support = [](const Associations& a) {
    return a.inlier_points(false) + a.inlier_lines(false);
  };
  if (descriptor_ok && (!ok || support(by_descriptor) > support(assoc))) {
    assoc = std::move(by_descriptor);
    T_c_w = T_by_descriptor;
    return true;
  }
  if (!ok) assoc.clear();
  return ok;
}

bool Tracker::track_from_last_frame(const Frame& frame, Associations& assoc, SE3& T_c_w) {
  if (!velocity_) return track_without_velocity(frame, assoc, T_c_w);
  bool ok = false;
  if (const std::optional<SE3> T_last = last_frame_pose()) {
    ok = track_last_frame(frame, predict(frame, *T_last), assoc, T_c_w);
    // A sudden motion breaks the constant-velocity model: retry from the last pose.
    if (!ok && velocity_) {
      assoc.clear();
      ok = track_last_frame(frame, *T_last, assoc, T_c_w);
    }
  }
  if (!ok) {
    assoc.clear();
    ok = track_reference_keyframe(frame, assoc, T_c_w);
  }
  return ok;
}

bool Tracker::refine_with_local_map(const Frame& frame, Associations& assoc, SE3& T_c_w,
                                    bool relocalised) {
  const bool recent_reloc = frame.id < last_relocalisation_frame_ + 2;
  int inliers =
      track_local_map(frame, assoc, T_c_w, recent_reloc ? 5.0 : options_.local_map_search_radius);
  inliers = remove_movers(frame, assoc, T_c_w, inliers);
  const bool after_place_search =
      last_relocalisation_frame_ > 0 &&
      frame.id < last_relocalisation_frame_ + options_.max_frames_between_keyframes;
  const bool ok =
      inliers >= (relocalised || after_place_search ? options_.min_relocalisation_inliers
                                                    : options_.min_local_map_inliers);
  // Planes help but never carry tracking alone: with a blank colour image the frame is lost.
  return ok && assoc.inlier_points(false) + assoc.inlier_lines(false) >= options_.min_pose_inliers;
}

TrackingOutcome Tracker::outcome_of(const Frame& frame, const Associations& assoc,
                                    const FirstEstimate& first, bool ok) const {
  TrackingOutcome out;
  out.objects = objects_.outputs(frame);
  out.relocalised = first.relocalised && ok;
  if (first.tried_relocalisation) out.relocalisation = relocalisation_;
  out.matches = assoc.active_points();
  out.inliers = assoc.inlier_points(false);
  out.line_matches = assoc.active_lines();
  out.line_inliers = assoc.inlier_lines(false);
  out.plane_inliers = assoc.inlier_planes();
  return out;
}

void Tracker::accept(const Frame& frame, const Associations& assoc, const SE3& T_c_w,
                     bool mapper_idle, std::size_t mapper_queue, TrackingOutcome& out) {
  // The pose a robot steers by: the frame's pose fused with the motion model. Tracking itself
  // (the next frame's prediction, keyframes, the final trajectory) goes on from the frame's own
  // pose; of the filter it takes only the angular velocity the next frame's rolling shutter is
  // corrected with (filtered_angular_velocity), a prediction from the frames before it. A
  // relocalised pose is a jump the motion model must not smooth away.
  if (out.relocalised) pose_filter_.reset();
  const optim::PoseFilterUpdate filtered =
      pose_filter_.update(frame.timestamp, T_c_w, pose_information_);
  out.T_c_w_online = filtered.T_c_w;
  out.online_pose = filtered.outcome;
  if (pose_smoother_ && filtered.step) out.lagged = pose_smoother_->add(*filtered.step);
  if (const auto T_last = last_frame_pose(); T_last && state_ == TrackingState::kOk) {
    previous_velocity_ = velocity_;
    previous_velocity_dt_ = velocity_dt_;
    velocity_ = T_c_w * T_last->inverse();
    velocity_dt_ = frame.timestamp - last_->frame.timestamp;
  } else {
    velocity_.reset();
    previous_velocity_.reset();
  }
  state_ = TrackingState::kOk;
  out.state = state_;
  out.T_c_w = T_c_w;
  out.reference = reference_;
  for (std::size_t i = 0; i < assoc.points.size(); ++i)
    if (assoc.points[i].active && !assoc.points[i].outlier &&
        assoc.points[i].landmark != map::kNoId)
      out.point_inliers.emplace_back(i, assoc.points[i].landmark);
  if (!localize_ && need_keyframe(frame, assoc, mapper_idle, mapper_queue)) {
    out.keyframe = make_keyframe(frame, assoc, T_c_w);
    out.reference = out.keyframe->id;
  }
  remember_last_frame(frame, assoc, T_c_w, out.reference);
  out.T_c_ref = last_->T_c_ref;
  objects_.remember(frame, T_c_w);
}

TrackingOutcome Tracker::initialize(const Frame& frame) {
  TrackingOutcome out;
  int with_depth = 0;
  for (const auto& p : frame.features->points) with_depth += p.has_depth() ? 1 : 0;
  int lines_with_depth = 0;
  for (const auto& l : frame.features->lines) lines_with_depth += l.has_depth ? 1 : 0;
  // Points alone, or enough 3D segments. Planes alone do not start a map: they come from the
  // depth image only, and a map without image landmarks could never relocalise.
  const bool enough_points = with_depth >= options_.min_initial_points;
  const bool enough_structure = lines_with_depth >= options_.min_initial_lines;
  if (!enough_points && !enough_structure) {
    out.state = TrackingState::kNotInitialized;
    return out;
  }
  state_ = TrackingState::kOk;
  const Associations none(frame);
  out.state = state_;
  out.T_c_w = SE3();
  out.T_c_w_online = SE3();
  if (pose_smoother_) out.lagged = pose_smoother_->add_unfiltered(frame.timestamp, SE3());
  // Nothing tells yet which object moves: the map starts from the features outside the boxes
  // when they are enough, else from all.
  objects_.prepare(frame, std::nullopt);
  if (objects_.any() && objects_.static_points_with_depth(frame) < options_.min_initial_points / 2)
    objects_.include_all();
  out.objects = objects_.outputs(frame);
  out.keyframe = make_keyframe(frame, none, SE3());
  out.reference = out.keyframe->id;
  out.inliers = with_depth;
  out.line_inliers = lines_with_depth;
  remember_last_frame(frame, none, SE3(), out.reference);
  out.T_c_ref = SE3();
  objects_.forget();
  objects_.remember(frame, SE3());
  return out;
}

void Tracker::start_in_map(map::KeyFrameId next_keyframe_id, bool localize) {
  state_ = TrackingState::kLost;
  next_keyframe_id_ = next_keyframe_id;
  localize_ = localize;
}

std::optional<SE3> Tracker::predicted_motion(double dt) const {
  if (!velocity_ || !(velocity_dt_ > 1e-4) || state_ != TrackingState::kOk) return std::nullopt;
  return SE3::exp(velocity_->log() * (dt / velocity_dt_));
}

Eigen::Vector3d Tracker::angular_velocity() const {
  // The filter's rate while the camera moves within the motion model (its densities the
  // settings'); a camera livelier than that outruns it, and the last two steps follow faster.
  if (options_.filtered_angular_velocity && pose_filter_.liveliness() <= 1.0)
    if (const auto w = pose_filter_.angular_velocity()) return *w;
  if (!velocity_ || !(velocity_dt_ > 1e-4) || state_ != TrackingState::kOk)
    return Eigen::Vector3d::Zero();
  if (previous_velocity_ && previous_velocity_dt_ > 1e-4)
    return so3_log((*velocity_ * *previous_velocity_).quaternion()) /
           (velocity_dt_ + previous_velocity_dt_);
  return so3_log(velocity_->quaternion()) / velocity_dt_;
}

std::optional<SE3> Tracker::keyframe_pose(map::KeyFrameId id) const {
  {
    if (auto T = map_.keyframe_pose_T_c_w(id)) return T;
  }
  if (const auto it = pending_keyframes_.find(id); it != pending_keyframes_.end())
    return it->second;
  return std::nullopt;
}

void Tracker::follow_map() {
  if (!last_) return;
  const std::optional<SE3> T_last = last_frame_pose();
  if (!T_last) return;
  // The last frame hangs on its reference keyframe; when bundle adjustment or a correction (loop,
  // merged full BA) moved that keyframe, the world the tracker's own history was recorded in
  // moved with it: W maps positions of the old world to the map's current one.
  const SE3 W = T_last->inverse() * last_->T_c_w;
  if (W.translation().norm() < 1e-9 && rotation_angle(W.quaternion()) < 1e-9) return;
  last_->T_c_w = *T_last;
  for (auto& track : last_->tracks)
    for (Eigen::Vector3d& p : track) p = W * p;
  objects_.move_world(W);
  pose_filter_.move_world(W);
  if (pose_smoother_ && options_.pose_filter.follow_map) pose_smoother_->move_world(W);
}

std::optional<SE3> Tracker::last_frame_pose() const {
  if (!last_) return std::nullopt;
  // Follow bundle adjustment: the last frame is stored relative to its reference keyframe.
  if (const auto T_ref_w = keyframe_pose(last_->reference)) return last_->T_c_ref * (*T_ref_w);
  return last_->T_c_w;
}

int Tracker::search_last_frame(const Frame& frame, const SE3& T_c_w, double radius,
                               std::vector<Match>& matches, std::vector<int>& from_last) const {
  const auto& last_points = last_->frame.features->points;
  const auto& points = frame.features->points;
  const auto& pyramid = *frame.features->pyramid;
  std::vector<int> best_distance(points.size(), 256);
  RotationHistogram histogram;
  std::vector<int> candidates;
  std::vector<int> source(points.size(), -1);
  int count = 0;

  // World positions of the last frame's points, landmarks read from the map; the others from the
  // last frame's depth, placed where its reference keyframe now is (after bundle adjustment or a
  // loop correction, the pose tracking gave it is stale and would mix two frames of reference).
  const SE3 T_w_last = last_frame_pose()->inverse();
  std::vector<std::optional<Eigen::Vector3d>> world(last_points.size());
  {
    for (std::size_t i = 0; i < last_points.size(); ++i) {
      if (last_->landmarks[i] != map::kNoId) {
        if (moved_set_.count(last_->landmarks[i]) != 0) continue;
        if (const map::MapPoint* mp = map_.point(last_->landmarks[i])) {
          world[i] = mp->p_w;
          continue;
        }
      }
      if (last_->depth_points[i]) world[i] = T_w_last * (*last_->depth_points[i]);
    }
  }

  for (std::size_t i = 0; i < last_points.size(); ++i) {
    if (!world[i]) continue;
    const Eigen::Vector3d p_c = T_c_w * (*world[i]);
    if (p_c.z() <= 0.0) continue;
    const Eigen::Vector2d uv = camera_.project(p_c);
    if (!camera_.in_image(uv)) continue;
    const int level = last_points[i].keypoint.level;
    const double r = radius * pyramid.scale[static_cast<std::size_t>(level)];
    frame.features->grid.query(static_cast<float>(uv.x()), static_cast<float>(uv.y()),
                               static_cast<float>(r), std::max(0, level - 1), level + 1,
                               candidates);
    const double ur = camera_.right_u(uv.x(), p_c.z());
    int best = 256;
    int best_idx = -1;
    for (int j : candidates) {
      const auto& f = points[static_cast<std::size_t>(j)];
      if (f.has_depth() && std::abs(ur - f.u_right) > r) continue;
      const int d = features::hamming_distance(last_points[i].descriptor, f.descriptor);
      if (d < best) {
        best = d;
        best_idx = j;
      }
    }
    if (best_idx < 0 || best > options_.max_descriptor_distance) continue;
    const auto j = static_cast<std::size_t>(best_idx);
    if (best >= best_distance[j]) continue;  // keep the closest descriptor per feature
    if (source[j] < 0) ++count;
    best_distance[j] = best;
    source[j] = static_cast<int>(i);
    // A landmark the mapper culled since the last frame is dropped by track_local_map.
    matches[j].landmark = last_->landmarks[i];
    matches[j].p_w = *world[i];
    matches[j].active = true;
    matches[j].outlier = false;
  }
  for (std::size_t j = 0; j < points.size(); ++j)
    if (source[j] >= 0)
      histogram.add(static_cast<int>(j),
                    last_points[static_cast<std::size_t>(source[j])].keypoint.angle_deg,
                    points[j].keypoint.angle_deg);
  for (int j : histogram.inconsistent()) {
    matches[static_cast<std::size_t>(j)] = Match{};
    source[static_cast<std::size_t>(j)] = -1;
    --count;
  }
  from_last = source;
  return count;
}

int Tracker::search_last_lines(const Frame& frame, const SE3& T_c_w, double distance_factor,
                               std::vector<LineMatch>& matches) const {
  const auto& last_lines = last_->frame.features->lines;
  if (last_lines.empty() || frame.features->lines.empty()) return 0;
  // World endpoints of the last frame's segments: their map line, or their own 3D fit (placed as
  // the last frame's points are, through its reference keyframe).
  const SE3 T_w_last = last_frame_pose()->inverse();
  std::vector<features::PredictedLine> predicted;
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> world;
  std::vector<map::LineId> landmark;
  {
    for (std::size_t i = 0; i < last_lines.size(); ++i) {
      std::pair<Eigen::Vector3d, Eigen::Vector3d> w;
      map::LineId id = last_->line_landmarks[i];
      if (const map::MapLine* ml = id != map::kNoId ? map_.line(id) : nullptr) {
        w = {ml->start_w, ml->end_w};
      } else if (last_->line_has_depth[i]) {
        id = map::kNoId;
        w = {T_w_last * last_lines[i].start_c, T_w_last * last_lines[i].end_c};
      } else {
        continue;
      }
      auto line = project_segment(camera_, T_c_w, w.first, w.second);
      if (!line) continue;
      line->descriptor = last_lines[i].descriptor;
      predicted.push_back(*line);
      world.push_back(w);
      landmark.push_back(id);
    }
  }
  const auto found = features::match_lines(predicted, frame.features->lines,
                                           line_match_criteria(options_, distance_factor));
  for (const auto& m : found) {
    LineMatch& match = matches[static_cast<std::size_t>(m.observed)];
    const auto k = static_cast<std::size_t>(m.predicted);
    match.landmark = landmark[k];
    match.start_w = world[k].first;
    match.end_w = world[k].second;
    match.active = true;
    match.outlier = false;
  }
  return static_cast<int>(found.size());
}

int Tracker::search_planes(const Frame& frame, const SE3& T_c_w,
                           std::vector<PlaneMatch>& matches) const {
  const auto& planes = frame.features->planes;
  if (planes.empty() || map_.num_planes() == 0) return 0;
  const Eigen::Matrix3d R = T_c_w.rotation();
  const Eigen::Vector3d t = T_c_w.translation();
  // Every (frame plane, map plane) pair within the thresholds, best first; each used once.
  struct Candidate {
    double score;
    std::size_t frame_plane;
    map::PlaneId landmark;
  };
  std::vector<Candidate> candidates;
  for (const auto& [id, mp] : map_.planes()) {
    const Eigen::Vector3d n_c = R * mp.normal;
    const double d_c = mp.d - n_c.dot(t);
    for (std::size_t k = 0; k < planes.size(); ++k)
      if (const auto score = plane_match_score(options_, n_c, d_c, planes[k].normal, planes[k].d))
        candidates.push_back({*score, k, id});
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    return a.score != b.score ? a.score < b.score : a.landmark < b.landmark;
  });
  std::unordered_set<map::PlaneId> used;
  for (auto& m : matches) m = PlaneMatch{};
  int count = 0;
  for (const Candidate& c : candidates) {
    if (matches[c.frame_plane].active || used.count(c.landmark) != 0) continue;
    const map::MapPlane* mp = map_.plane(c.landmark);
    matches[c.frame_plane] = PlaneMatch{c.landmark, mp->coefficients(), true, false};
    used.insert(c.landmark);
    ++count;
  }
  return count;
}

bool Tracker::track_last_frame(const Frame& frame, const SE3& prediction, Associations& assoc,
                               SE3& T_c_w) {
  int n = search_last_frame(frame, prediction, options_.motion_search_radius, assoc.points,
                            assoc.from_last);
  int n_lines = search_last_lines(frame, prediction, 1.0, assoc.lines);
  if (n + n_lines < options_.min_motion_matches) {
    assoc.clear();
    n = search_last_frame(frame, prediction, 2.0 * options_.motion_search_radius, assoc.points,
                          assoc.from_last);
    n_lines = search_last_lines(frame, prediction, 2.0, assoc.lines);
  }
  int n_planes = 0;
  { n_planes = search_planes(frame, prediction, assoc.planes); }
  if (n + n_lines + options_.plane_inlier_weight * n_planes < options_.min_motion_matches)
    return false;
  T_c_w = prediction;
  return optimize(frame, assoc, T_c_w) >= options_.min_pose_inliers;
}

bool Tracker::track_reference_keyframe(const Frame& frame, Associations& assoc, SE3& T_c_w) {
  const std::optional<SE3> T_last = last_frame_pose();
  if (!T_last) return false;
  const map::KeyFrame* ref =
      map_.keyframe(reference_ != map::kNoId ? reference_ : map_.last_keyframe_id());
  if (ref == nullptr) return false;
  std::vector<features::OrbDescriptor> train;
  std::vector<int> train_index;
  landmark_descriptors(map_, *ref, train, train_index);
  const std::vector<features::OrbDescriptor> query = frame.features->point_descriptors();
  const auto found =
      features::match_descriptors(query, train, options_.max_descriptor_distance, 0.7f, true);
  for (const auto& m : found) {
    const map::PointId id =
        ref->landmarks[static_cast<std::size_t>(train_index[static_cast<std::size_t>(m.train)])];
    Match& match = assoc.points[static_cast<std::size_t>(m.query)];
    match.landmark = id;
    match.p_w = map_.point(id)->p_w;
    match.active = true;
  }
  // The reference keyframe's map lines, predicted at the last pose with a wide window.
  std::vector<features::PredictedLine> predicted;
  std::vector<const map::MapLine*> predicted_lines;
  for (map::LineId id : ref->line_landmarks) {
    const map::MapLine* ml = id != map::kNoId ? map_.line(id) : nullptr;
    if (ml == nullptr) continue;
    auto line = project_segment(camera_, *T_last, ml->start_w, ml->end_w);
    if (!line) continue;
    line->descriptor = ml->descriptor;
    predicted.push_back(*line);
    predicted_lines.push_back(ml);
  }
  const auto line_found =
      features::match_lines(predicted, frame.features->lines, line_match_criteria(options_, 4.0));
  for (const auto& m : line_found) {
    const map::MapLine* ml = predicted_lines[static_cast<std::size_t>(m.predicted)];
    assoc.lines[static_cast<std::size_t>(m.observed)] =
        LineMatch{ml->id, ml->start_w, ml->end_w, true, false};
  }
  const int n_planes = search_planes(frame, *T_last, assoc.planes);
  const int n = static_cast<int>(found.size() + line_found.size());
  if (n + options_.plane_inlier_weight * n_planes < options_.min_motion_matches) return false;
  T_c_w = *T_last;
  return optimize(frame, assoc, T_c_w) >= options_.min_pose_inliers;
}

void Tracker::refine_rolling_shutter(const Frame& frame, optim::PoseProblem& problem,
                                     optim::PoseOptimizationResult& result) const {
  if (!options_.refine_rolling_shutter || frame.readout_time == 0.0) return;
  // The turn rate the keypoints were corrected with (no velocity: none, and all is to find).
  if (velocity_ && angular_velocity().norm() < options_.refine_min_angular_velocity) return;
  // A correction the frame's shear does not show (chi-square, 3 dof, 95 %) is noise: the
  // prediction stays. Each pass re-selects the inliers under the corrected keypoints, so a large
  // error (a frame tracked without a velocity: none was corrected) is taken in steps.
  constexpr int kMaxPasses = 4;
  constexpr double kChi2 = 7.815;
  optim::PoseOptimizerOptions again_options = options_.pose;
  // From the pose just solved: one robust round to re-select the inliers, one plain.
  again_options.rounds = std::min(again_options.rounds, 2);
  again_options.robust_rounds = std::min(again_options.robust_rounds, 1);
  for (int pass = 0; pass < kMaxPasses; ++pass) {
    const optim::AngularVelocityCorrection correction = optim::estimate_angular_velocity_correction(
        camera_, problem, result.inlier, result.T_c_w, frame.readout_time,
        options_.angular_velocity_sigma);
    if (correction.points < options_.min_pose_inliers || !(correction.chi2 > kChi2)) return;
    optim::apply_angular_velocity_correction(camera_, frame.readout_time, correction.d, problem);
    auto again = optim::optimize_pose(camera_, result.T_c_w, problem, again_options);
    if (again.failed) return;
    result = std::move(again);
  }
}

int Tracker::weighted_inliers(const Associations& assoc) const {
  return assoc.inlier_points(false) + assoc.inlier_lines(false) +
         options_.plane_inlier_weight * assoc.inlier_planes();
}

int Tracker::optimize(const Frame& frame, Associations& assoc, SE3& T_c_w, bool rolling_shutter) {
  optim::PoseProblem problem;
  std::vector<std::size_t> point_index, line_index, plane_index;
  const auto& features = *frame.features;
  for (std::size_t i = 0; i < assoc.points.size(); ++i) {
    if (!assoc.points[i].active || objects_.point_excluded(i)) continue;
    optim::PoseObservation obs;
    obs.p_w = assoc.points[i].p_w;
    obs.measurement = measurement_of(features.points[i], *features.pyramid, options_.depth_weight);
    problem.points.push_back(obs);
    point_index.push_back(i);
  }
  for (std::size_t i = 0; i < assoc.lines.size(); ++i) {
    if (!assoc.lines[i].active || objects_.line_excluded(i)) continue;
    optim::PoseLineObservation obs;
    obs.start_w = assoc.lines[i].start_w;
    obs.end_w = assoc.lines[i].end_w;
    obs.measurement = line_measurement_of(features.lines[i], options_.line_sigma);
    problem.lines.push_back(obs);
    line_index.push_back(i);
  }
  for (std::size_t i = 0; i < assoc.planes.size(); ++i) {
    if (!assoc.planes[i].active) continue;
    optim::PosePlaneObservation obs;
    obs.plane_w = assoc.planes[i].plane_w;
    obs.measurement = plane_measurement_of(features.planes[i], options_.plane_angle_sigma_deg,
                                           options_.plane_distance_sigma);
    problem.planes.push_back(obs);
    plane_index.push_back(i);
  }
  if (problem.points.size() + problem.lines.size() + 3 * problem.planes.size() < 3) return 0;
  // Established landmarks first: what their pose does not explain stays out (an outlier below).
  std::vector<std::size_t> gated_points, gated_lines;
  SE3 start = T_c_w;
  if (options_.established_age > 0.0) {
    const auto established = established_flags(frame.timestamp, assoc, point_index, line_index);
    const auto gate = gate_by_established(camera_, problem, established.first, established.second,
                                          T_c_w, options_);
    if (gate) {
      start = gate->T_c_w;
      for (std::size_t k = 0; k < point_index.size(); ++k)
        if (!gate->keep_point[k]) gated_points.push_back(point_index[k]);
      for (std::size_t k = 0; k < line_index.size(); ++k)
        if (!gate->keep_line[k]) gated_lines.push_back(line_index[k]);
      keep_flagged(problem.points, gate->keep_point);
      keep_flagged(point_index, gate->keep_point);
      keep_flagged(problem.lines, gate->keep_line);
      keep_flagged(line_index, gate->keep_line);
    }
  }
  problem.constrained_points = objects_.constrained_points();
  problem.constrained_lines = objects_.constrained_lines();
  auto result = optim::optimize_pose(camera_, start, problem, options_.pose);
  if (rolling_shutter && !result.failed) refine_rolling_shutter(frame, problem, result);
  if (result.failed) {
    // No usable solution: the pose is not an estimate, and nothing is an inlier of it.
    ++solver_failures_;
    for (auto& m : assoc.points) m.outlier = m.outlier || m.active;
    for (auto& m : assoc.lines) m.outlier = m.outlier || m.active;
    for (auto& m : assoc.planes) m.outlier = m.outlier || m.active;
    return 0;
  }
  T_c_w = result.T_c_w;
  pose_information_ = result.information;
  // Features left out (on moving objects) count as outliers everywhere downstream: no landmark,
  // no statistics, no depth point for the next frame.
  for (std::size_t i = 0; i < assoc.points.size(); ++i)
    if (assoc.points[i].active && objects_.point_excluded(i)) assoc.points[i].outlier = true;
  for (std::size_t i = 0; i < assoc.lines.size(); ++i)
    if (assoc.lines[i].active && objects_.line_excluded(i)) assoc.lines[i].outlier = true;
  for (std::size_t k = 0; k < point_index.size(); ++k)
    assoc.points[point_index[k]].outlier = !result.inlier[k];
  for (std::size_t k = 0; k < line_index.size(); ++k)
    assoc.lines[line_index[k]].outlier = !result.line_inlier[k];
  for (std::size_t k = 0; k < plane_index.size(); ++k)
    assoc.planes[plane_index[k]].outlier = !result.plane_inlier[k];
  for (std::size_t i : gated_points) assoc.points[i].outlier = true;
  for (std::size_t i : gated_lines) assoc.lines[i].outlier = true;
  return weighted_inliers(assoc);
}

std::pair<std::vector<bool>, std::vector<bool>> Tracker::established_flags(
    double timestamp, const Associations& assoc, const std::vector<std::size_t>& point_index,
    const std::vector<std::size_t>& line_index) const {
  // A landmark whose first keyframe is gone (culled as redundant, which takes its points being
  // seen by three other keyframes) counts as established.
  const auto old_enough = [&](map::KeyFrameId first) {
    const map::KeyFrame* kf = map_.keyframe(first);
    return kf == nullptr || timestamp - kf->timestamp >= options_.established_age;
  };
  std::pair<std::vector<bool>, std::vector<bool>> flags;
  for (std::size_t i : point_index) {
    const map::PointId id = assoc.points[i].landmark;
    const map::MapPoint* mp = id == map::kNoId ? nullptr : map_.point(id);
    flags.first.push_back(mp != nullptr && old_enough(mp->first_keyframe));
  }
  for (std::size_t i : line_index) {
    const map::LineId id = assoc.lines[i].landmark;
    const map::MapLine* ml = id == map::kNoId ? nullptr : map_.line(id);
    flags.second.push_back(ml != nullptr && old_enough(ml->first_keyframe));
  }
  return flags;
}

void Tracker::update_local_map(const Associations& assoc, const SE3& T_c_w) {
  // Keyframes that observe the frame's landmarks, weighted by how many they share.
  for (const Match& m : assoc.points) {
    if (!m.active || m.outlier || m.landmark == map::kNoId) continue;
    const map::MapPoint* mp = map_.point(m.landmark);
    if (mp == nullptr) continue;
    for (const auto& obs : mp->observations) keyframe_counts_.add(obs.first);
  }
  for (const LineMatch& m : assoc.lines) {
    if (!m.active || m.outlier || m.landmark == map::kNoId) continue;
    const map::MapLine* ml = map_.line(m.landmark);
    if (ml == nullptr) continue;
    for (const auto& obs : ml->observations) keyframe_counts_.add(obs.first);
  }
  std::vector<map::KeyFrameId>& local_keyframes = local_.keyframes;
  std::vector<std::pair<int, map::KeyFrameId>> ranked = keyframe_counts_.take();
  std::sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second > b.second;
  });
  local_keyframes.clear();
  std::unordered_set<map::KeyFrameId> chosen;
  const auto max_kf = static_cast<std::size_t>(options_.max_local_keyframes);
  for (const auto& [n, id] : ranked) {
    if (local_keyframes.size() >= max_kf) break;
    local_keyframes.push_back(id);
    chosen.insert(id);
  }
  if (!ranked.empty()) reference_ = ranked.front().second;
  // Neighbours of the best ones, so that the local map reaches ahead of the camera.
  const std::size_t first_level = local_keyframes.size();
  for (std::size_t k = 0; k < first_level && local_keyframes.size() < max_kf; ++k)
    for (map::KeyFrameId n : map_.best_covisible(local_keyframes[k], 10))
      if (chosen.insert(n).second) {
        local_keyframes.push_back(n);
        if (local_keyframes.size() >= max_kf) break;
      }
  // Keyframes near the camera that look the same way, linked by covisibility or not: when the
  // camera comes back to a place, the old landmarks are matched again instead of being mapped a
  // second time, which closes small loops without a separate loop detector.
  if (options_.spatial_keyframes > 0) add_nearby_keyframes(T_c_w, chosen);
  if (local_keyframes.empty() && map_.last_keyframe_id() != map::kNoId &&
      map_.keyframe(map_.last_keyframe_id()) != nullptr) {
    local_keyframes.push_back(map_.last_keyframe_id());
    reference_ = map_.last_keyframe_id();
  }
  collect_local_landmarks();
}

void Tracker::add_nearby_keyframes(const SE3& T_c_w, std::unordered_set<map::KeyFrameId>& chosen) {
  const SE3 T_w_c = T_c_w.inverse();
  const Eigen::Vector3d center = T_w_c.translation();
  const Eigen::Vector3d axis = T_w_c.rotation().col(2);
  const double min_cos = std::cos(options_.spatial_max_angle_deg * M_PI / 180.0);
  std::vector<std::pair<double, map::KeyFrameId>> nearby;
  for (const auto& [id, kf] : map_.keyframes()) {
    if (chosen.count(id) != 0) continue;
    const SE3 kf_T_w_c = kf.T_w_c();
    const double distance = (kf_T_w_c.translation() - center).norm();
    if (distance > options_.spatial_radius) continue;
    if (kf_T_w_c.rotation().col(2).dot(axis) < min_cos) continue;
    nearby.emplace_back(distance, id);
  }
  std::sort(nearby.begin(), nearby.end());
  const auto n = std::min(nearby.size(), static_cast<std::size_t>(options_.spatial_keyframes));
  for (std::size_t k = 0; k < n; ++k) {
    local_.keyframes.push_back(nearby[k].second);
    chosen.insert(nearby[k].second);
  }
}

void Tracker::collect_local_landmarks() {
  local_.points.clear();
  local_.lines.clear();
  point_marks_.clear();
  line_marks_.clear();
  for (map::KeyFrameId id : local_.keyframes) {
    const map::KeyFrame* kf = map_.keyframe(id);
    if (kf == nullptr) continue;
    for (map::PointId p : kf->landmarks)
      if (p != map::kNoId && point_marks_.insert(p)) local_.points.push_back(p);
    for (map::LineId l : kf->line_landmarks)
      if (l != map::kNoId && line_marks_.insert(l)) local_.lines.push_back(l);
  }
}

int Tracker::search_local_points(const Frame& frame, const SE3& T_c_w, double radius_factor,
                                 std::vector<Match>& matches) {
  const auto& points = frame.features->points;
  const auto& pyramid = *frame.features->pyramid;
  IdMarks& already = point_marks_;
  already.clear();
  for (const Match& m : matches)
    if (m.active && m.landmark != map::kNoId) already.insert(m.landmark);
  const Eigen::Vector3d center = T_c_w.inverse().translation();
  std::vector<int> candidates;
  int added = 0;
  for (map::PointId id : local_.points) {
    if (already.contains(id) || moved_set_.count(id) != 0) continue;
    const map::MapPoint* mp = map_.point(id);
    if (mp == nullptr) continue;
    const Eigen::Vector3d p_c = T_c_w * mp->p_w;
    if (p_c.z() <= 0.0) continue;
    const Eigen::Vector2d uv = camera_.project(p_c);
    if (!camera_.in_image(uv)) continue;
    const Eigen::Vector3d ray = mp->p_w - center;
    const double distance = ray.norm();
    if (distance < 0.8 * mp->min_distance || distance > 1.2 * mp->max_distance) continue;
    const double view_cos = ray.dot(mp->normal) / distance;
    if (view_cos < 0.5) continue;
    auto& stat = statistics_[id];
    stat.landmark = id;
    ++stat.visible;
    const int level = pyramid.predict_level(distance, mp->max_distance);
    const double r = (view_cos > 0.998 ? 2.5 : 4.0) * radius_factor *
                     pyramid.scale[static_cast<std::size_t>(level)];
    frame.features->grid.query(static_cast<float>(uv.x()), static_cast<float>(uv.y()),
                               static_cast<float>(r), std::max(0, level - 1), level, candidates);
    const double ur = camera_.right_u(uv.x(), p_c.z());
    int best = 256, second = 256, best_level = -1, second_level = -1, best_idx = -1;
    for (int j : candidates) {
      const auto& m = matches[static_cast<std::size_t>(j)];
      if (m.active && m.landmark != map::kNoId) continue;
      const auto& f = points[static_cast<std::size_t>(j)];
      if (f.has_depth() && std::abs(ur - f.u_right) > r) continue;
      const int d = features::hamming_distance(mp->descriptor, f.descriptor);
      if (d < best) {
        second = best;
        second_level = best_level;
        best = d;
        best_level = f.keypoint.level;
        best_idx = j;
      } else if (d < second) {
        second = d;
        second_level = f.keypoint.level;
      }
    }
    if (best_idx < 0 || best > options_.max_descriptor_distance) continue;
    if (best_level == second_level && best > options_.local_map_ratio * second) continue;
    Match& m = matches[static_cast<std::size_t>(best_idx)];
    m.landmark = id;
    m.p_w = mp->p_w;
    m.active = true;
    m.outlier = false;
    ++added;
  }
  return added;
}

int Tracker::search_local_lines(const Frame& frame, const SE3& T_c_w,
                                std::vector<LineMatch>& matches) {
  if (frame.features->lines.empty()) return 0;
  IdMarks& already = line_marks_;
  already.clear();
  for (const LineMatch& m : matches)
    if (m.active && m.landmark != map::kNoId) already.insert(m.landmark);
  std::vector<features::PredictedLine> predicted;
  std::vector<const map::MapLine*> source;
  for (map::LineId id : local_.lines) {
    if (already.contains(id)) continue;
    const map::MapLine* ml = map_.line(id);
    if (ml == nullptr) continue;
    auto line = project_segment(camera_, T_c_w, ml->start_w, ml->end_w);
    if (!line) continue;
    auto& stat = line_statistics_[id];
    stat.landmark = id;
    ++stat.visible;
    line->descriptor = ml->descriptor;
    predicted.push_back(*line);
    source.push_back(ml);
  }
  // Segments already matched to a map line keep it; the others may take a local-map line.
  std::vector<features::LineFeature> free_lines;
  std::vector<std::size_t> free_index;
  for (std::size_t i = 0; i < matches.size(); ++i) {
    if (matches[i].active && matches[i].landmark != map::kNoId) continue;
    free_lines.push_back(frame.features->lines[i]);
    free_index.push_back(i);
  }
  const auto found =
      features::match_lines(predicted, free_lines, line_match_criteria(options_, 1.0));
  for (const auto& m : found) {
    const map::MapLine* ml = source[static_cast<std::size_t>(m.predicted)];
    matches[free_index[static_cast<std::size_t>(m.observed)]] =
        LineMatch{ml->id, ml->start_w, ml->end_w, true, false};
  }
  return static_cast<int>(found.size());
}

int Tracker::track_local_map(const Frame& frame, Associations& assoc, SE3& T_c_w,
                             double radius_factor) {
  {
    // Drop outliers of the frame-to-frame step and landmarks the mapper has culled since.
    for (Match& m : assoc.points) {
      if (m.active && m.outlier) m = Match{};
      if (m.active && m.landmark != map::kNoId) {
        if (const map::MapPoint* mp = map_.point(m.landmark))
          m.p_w = mp->p_w;
        else
          m.landmark = map::kNoId;
      }
    }
    for (LineMatch& m : assoc.lines) {
      if (m.active && m.outlier) m = LineMatch{};
      if (m.active && m.landmark != map::kNoId) {
        if (const map::MapLine* ml = map_.line(m.landmark)) {
          m.start_w = ml->start_w;
          m.end_w = ml->end_w;
        } else {
          m = LineMatch{};  // its geometry came from the map: nothing is left to use
        }
      }
    }
    // Points seen to move stay out until the mapper has removed them.
    for (auto it = moved_set_.begin(); it != moved_set_.end();)
      it = map_.point(*it) == nullptr ? moved_set_.erase(it) : std::next(it);
    update_local_map(assoc, T_c_w);
    search_local_points(frame, T_c_w, radius_factor, assoc.points);
    search_local_lines(frame, T_c_w, assoc.lines);
    search_planes(frame, T_c_w, assoc.planes);
  }
  const int inliers = optimize(frame, assoc, T_c_w, true);
  for (const Match& m : assoc.points)
    if (m.active && !m.outlier && m.landmark != map::kNoId) {
      auto& stat = statistics_[m.landmark];
      stat.landmark = m.landmark;
      ++stat.found;
    }
  for (const LineMatch& m : assoc.lines)
    if (m.active && !m.outlier && m.landmark != map::kNoId) {
      auto& stat = line_statistics_[m.landmark];
      stat.landmark = m.landmark;
      ++stat.found;
    }
  return inliers;
}

int Tracker::remove_movers(const Frame& frame, Associations& assoc, SE3& T_c_w, int inliers) {
  if (!options_.dynamics.find_movers || !frame.objects) return inliers;
  // Every matched feature that took part: where its map point (or last-frame point) should be;
  // and every feature with a track: where it was seen up to dynamics.frame_gap frames ago.
  std::vector<MotionEvidence> evidence;
  for (std::size_t i = 0; i < assoc.points.size(); ++i) {
    if (objects_.point_excluded(i)) continue;
    const Match& m = assoc.points[i];
    if (m.active) evidence.push_back({static_cast<int>(i), T_c_w * m.p_w, m.landmark});
    const int from = assoc.from_last[i];
    if (!last_ || from < 0) continue;
    const auto& track = last_->tracks[static_cast<std::size_t>(from)];
    if (track.size() >= 2)  // the last frame alone is the match above
      evidence.push_back(
          {static_cast<int>(i), T_c_w * track.front(), m.active ? m.landmark : map::kNoId});
  }
  const MoverResult movers = objects_.find_movers(frame, T_c_w, evidence);
  if (!movers.any) return inliers;
  for (map::PointId id : movers.moved_landmarks)
    if (moved_set_.insert(id).second) moved_points_.push_back(id);
  // The movers' features leave the optimisation (optimize() marks them as outliers).
  return optimize(frame, assoc, T_c_w, true);
}

Tracker::FirstEstimate Tracker::find_again(const Frame& frame, Associations& assoc, SE3& T_c_w) {
  FirstEstimate first;
  first.tried_relocalisation = true;
  relocalisation_ = RelocalisationInfo{};
  // From the pose before the loss, as a tracked frame would be (without the velocity, which the
  // loss reset), while the camera cannot have left that view.
  if (last_ && options_.recovery_window > 0.0 &&
      frame.timestamp - last_->frame.timestamp <= options_.recovery_window) {
    // The planes alone (a blank colour image) do not find the camera again.
    first.ok = track_from_last_frame(frame, assoc, T_c_w) &&
               assoc.inlier_points(false) + assoc.inlier_lines(false) >= options_.min_pose_inliers;
    if (first.ok) {
      relocalisation_.from_last_pose = true;
      relocalisation_.keyframe = reference_;
      first.relocalised = true;  // the same test as a relocalisation's
      return first;
    }
    assoc.clear();
  }
  first.ok = relocalise(frame, assoc, T_c_w);
  first.relocalised = first.ok;
  return first;
}

bool Tracker::relocalise(const Frame& frame, Associations& assoc, SE3& T_c_w) {
  if (!relocalisation_work_) {
    relocalisation_work_.emplace();
    find_relocalisation_candidates(frame, *relocalisation_work_);
  }
  RelocalisationWork& work = *relocalisation_work_;
  relocalisation_ = work.info;
  for (std::size_t k = 0; k < work.candidates.size(); ++k) {
    const RelocalisationCandidate& c = work.candidates[k];
    if (k == work.poses.size()) work.poses.push_back(solve_pnp(frame, c));
    if (!work.poses[k]) continue;
    SE3 pose = work.poses[k]->T_c_w;
    assoc.clear();
    for (int i : work.poses[k]->inliers) {
      Match& m = assoc.points[static_cast<std::size_t>(
          c.correspondences[static_cast<std::size_t>(i)].first)];
      m.landmark = c.correspondences[static_cast<std::size_t>(i)].second;
      m.p_w = c.p_w[static_cast<std::size_t>(i)];
      m.active = true;
    }
    if (optimize(frame, assoc, pose) < options_.min_pose_inliers) continue;
    T_c_w = pose;
    relocalisation_.keyframe = c.keyframe;
    relocalisation_.score = c.score;
    return true;
  }
  assoc.clear();
  return false;
}

void Tracker::find_relocalisation_candidates(const Frame& frame, RelocalisationWork& work) const {
  std::vector<RelocalisationCandidate>& candidates = work.candidates;
  RelocalisationInfo& info = work.info;
  const auto add_candidate = [&](const map::KeyFrame& kf,
                                 const std::vector<features::DescriptorMatch>& found) {
    if (found.size() < 15) return;
    RelocalisationCandidate c;
    c.keyframe = kf.id;
    for (const auto& m : found) {
      const map::PointId pid = kf.landmarks[static_cast<std::size_t>(m.train)];
      c.correspondences.emplace_back(m.query, pid);
      c.p_w.push_back(map_.point(pid)->p_w);
    }
    candidates.push_back(std::move(c));
  };
  const std::vector<features::OrbDescriptor> query = frame.features->point_descriptors();
  const auto n = static_cast<std::size_t>(options_.relocalisation_candidates);
  Stopwatch watch;
  if (map_.num_keyframes() == 0) return;
  const place::Database* database = map_.database();
  if (vocabulary_ && database != nullptr && database->size() > 0) {
    // The keyframe database's best places; features compared only under the same node.
    const place::BowImage bow = vocabulary_->transform(query, direct_levels_up_);
    const auto results = database->query(bow.bow, n);
    info.query_ms = watch.elapsed_ms();
    watch.restart();
    place::WordMatchOptions match;
    match.max_distance = 64;
    for (const auto& result : results) {
      const map::KeyFrame* kf = map_.keyframe(result.id);
      if (kf == nullptr || !kf->bow) continue;
      const std::vector<features::OrbDescriptor> train = kf->features->point_descriptors();
      const auto has_landmark = [&](int j) {
        const map::PointId p = kf->landmarks[static_cast<std::size_t>(j)];
        return p != map::kNoId && map_.point(p) != nullptr;
      };
      add_candidate(*kf, place::match_by_words(bow.direct, query, kf->bow->direct, train, match, {},
                                               has_landmark));
      if (!candidates.empty() && candidates.back().keyframe == kf->id)
        candidates.back().score = result.score;
    }
    info.by_database = true;
  } else {
    // Without a vocabulary: the newest keyframes, then a spread over the whole map.
    std::vector<map::KeyFrameId> ids;
    for (const auto& kv : map_.keyframes()) ids.push_back(kv.first);
    std::sort(ids.begin(), ids.end(), std::greater<>());
    std::vector<map::KeyFrameId> chosen(ids.begin(), ids.begin() + std::min(ids.size(), n / 2));
    if (ids.size() > chosen.size()) {
      const std::size_t rest = ids.size() - chosen.size();
      const std::size_t want = std::min(rest, n - chosen.size());
      for (std::size_t k = 0; k < want; ++k) chosen.push_back(ids[chosen.size() + k * rest / want]);
    }
    for (map::KeyFrameId id : chosen) {
      const map::KeyFrame* kf = map_.keyframe(id);
      if (kf == nullptr) continue;
      std::vector<features::OrbDescriptor> train;
      std::vector<int> feature;
      landmark_descriptors(map_, *kf, train, feature);
      auto found = features::match_descriptors(query, train, 64, 0.75f, true);
      for (auto& m : found) m.train = feature[static_cast<std::size_t>(m.train)];
      add_candidate(*kf, found);
    }
    info.by_database = false;
  }
  info.match_ms = watch.elapsed_ms();
  info.candidates = static_cast<int>(candidates.size());
  std::sort(candidates.begin(), candidates.end(),
            [](const RelocalisationCandidate& a, const RelocalisationCandidate& b) {
              return a.correspondences.size() > b.correspondences.size();
            });
}

std::optional<Tracker::PnpPose> Tracker::solve_pnp(const Frame& frame,
                                                   const RelocalisationCandidate& c) const {
  const cv::Matx33d K(camera_.fx, 0, camera_.cx, 0, camera_.fy, camera_.cy, 0, 0, 1);
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> image;
  for (std::size_t k = 0; k < c.correspondences.size(); ++k) {
    const auto& kp = frame.features->points[static_cast<std::size_t>(c.correspondences[k].first)];
    object.emplace_back(static_cast<float>(c.p_w[k].x()), static_cast<float>(c.p_w[k].y()),
                        static_cast<float>(c.p_w[k].z()));
    image.emplace_back(kp.keypoint.uv.x(), kp.keypoint.uv.y());
  }
  cv::Mat rvec, tvec;
  PnpPose out;
  bool solved = false;
  // Hypotheses from 4 points by AP3P (OpenCV then fits the inliers by EPnP): EPnP's 5-point
  // hypotheses cost a 12x12 SVD each, and a frame lost among people, whose candidates
  // rarely fit, spent 150 ms on them per attempt (70 ms by AP3P, relocalised on the same frame).
  try {
    solved = cv::solvePnPRansac(object, image, K, cv::noArray(), rvec, tvec, false, 200, 4.0f, 0.99,
                                out.inliers, cv::SOLVEPNP_AP3P);
  } catch (const cv::Exception&) {
    solved = false;  // degenerate configuration: try the next candidate
  }
  if (!solved || out.inliers.size() < 10) return std::nullopt;
  cv::Matx33d R;
  cv::Rodrigues(rvec, R);
  Eigen::Matrix3d Re;
  for (int r = 0; r < 3; ++r)
    for (int col = 0; col < 3; ++col) Re(r, col) = R(r, col);
  out.T_c_w = SE3(Re, Eigen::Vector3d(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)));
  return out;
}

bool Tracker::need_keyframe(const Frame& frame, const Associations& assoc, bool mapper_idle,
                            std::size_t mapper_queue) const {
  std::uint64_t n_keyframes = 0;
  { n_keyframes = static_cast<std::uint64_t>(map_.num_keyframes()); }
  if (frame.id < last_relocalisation_frame_ +
                     static_cast<std::uint64_t>(options_.max_frames_between_keyframes) &&
      last_relocalisation_frame_ > 0 &&
      n_keyframes > static_cast<std::uint64_t>(options_.max_frames_between_keyframes))
    return false;
  // The decision counts map landmarks only (matches to the last frame's depth points and
  // segments say nothing about how well the map covers the view): points and lines.
  const int inliers = assoc.inlier_points(true) + assoc.inlier_lines(true);
  // Landmarks of the reference keyframe that are well established.
  int reference_matches = 0;
  {
    // Observed by at least two keyframes (one while the map is that young).
    const std::size_t min_obs = n_keyframes <= 2 ? 1 : 2;
    if (const map::KeyFrame* ref = map_.keyframe(reference_)) {
      for (map::PointId p : ref->landmarks)
        if (p != map::kNoId)
          if (const map::MapPoint* mp = map_.point(p))
            reference_matches += mp->observations.size() >= min_obs ? 1 : 0;
      for (map::LineId l : ref->line_landmarks)
        if (l != map::kNoId)
          if (const map::MapLine* ml = map_.line(l))
            reference_matches += ml->observations.size() >= min_obs ? 1 : 0;
    }
  }
  // Close points tracked / not tracked.
  int tracked_close = 0, untracked_close = 0;
  const double close = keyframe_close_depth();
  for (std::size_t i = 0; i < assoc.points.size(); ++i) {
    const auto& f = frame.features->points[i];
    if (!f.has_depth() || f.depth >= close) continue;
    const Match& m = assoc.points[i];
    const bool tracked = m.active && !m.outlier && m.landmark != map::kNoId;
    tracked ? ++tracked_close : ++untracked_close;
  }
  const bool need_close = tracked_close < options_.close_tracked_threshold &&
                          untracked_close > options_.close_untracked_threshold;
  const bool c1a = frame.id >= last_keyframe_frame_ + static_cast<std::uint64_t>(
                                                          options_.max_frames_between_keyframes);
  const bool c1b = mapper_idle;
  const bool c1c = inliers < 0.25 * reference_matches || need_close;
  const bool due = options_.keyframe_interval > 0.0 &&
                   frame.timestamp - last_keyframe_time_ >= options_.keyframe_interval;
  const bool c2 =
      (inliers < options_.keyframe_ref_ratio * reference_matches || need_close || due) &&
      inliers > 15;
  if (!((c1a || c1b || c1c) && c2)) return false;
  return mapper_idle || mapper_queue < 3;
}

KeyFrameRequest Tracker::make_keyframe(const Frame& frame, const Associations& assoc,
                                       const SE3& T_c_w) {
  KeyFrameRequest request;
  request.id = next_keyframe_id_++;
  request.frame = frame;
  request.T_c_w = T_c_w;
  {
    request.map_version = map_.version();
    if (const map::KeyFrame* ref = map_.keyframe(reference_)) {
      request.reference = reference_;
      request.T_c_ref = T_c_w * ref->T_c_w.inverse();
    }
  }
  request.landmarks.assign(assoc.points.size(), map::kNoId);
  for (std::size_t i = 0; i < assoc.points.size(); ++i)
    if (assoc.points[i].active && !assoc.points[i].outlier)
      request.landmarks[i] = assoc.points[i].landmark;
  request.line_landmarks.assign(assoc.lines.size(), map::kNoId);
  for (std::size_t i = 0; i < assoc.lines.size(); ++i)
    if (assoc.lines[i].active && !assoc.lines[i].outlier)
      request.line_landmarks[i] = assoc.lines[i].landmark;
  request.plane_landmarks.assign(assoc.planes.size(), map::kNoId);
  for (std::size_t i = 0; i < assoc.planes.size(); ++i)
    if (assoc.planes[i].active && !assoc.planes[i].outlier)
      request.plane_landmarks[i] = assoc.planes[i].landmark;
  const auto sorted = [](const auto& table) {
    std::vector<LandmarkStatistics> out;
    for (const auto& kv : table) out.push_back(kv.second);
    std::sort(out.begin(), out.end(), [](const LandmarkStatistics& a, const LandmarkStatistics& b) {
      return a.landmark < b.landmark;
    });
    return out;
  };
  const auto any_set = [](const std::vector<std::uint8_t>& v) {
    return std::any_of(v.begin(), v.end(), [](std::uint8_t x) { return x != 0; });
  };
  if (any_set(objects_.point_exclusions()) || any_set(objects_.line_exclusions())) {
    request.excluded_points = objects_.point_exclusions();
    request.excluded_lines = objects_.line_exclusions();
  }
  request.moved_points = std::move(moved_points_);
  moved_points_.clear();
  request.statistics = sorted(statistics_);
  request.line_statistics = sorted(line_statistics_);
  statistics_.clear();
  line_statistics_.clear();
  pending_keyframes_[request.id] = T_c_w;
  last_keyframe_frame_ = frame.id;
  last_keyframe_time_ = frame.timestamp;
  reference_ = request.id;
  return request;
}

void Tracker::remember_last_frame(const Frame& frame, const Associations& assoc, const SE3& T_c_w,
                                  map::KeyFrameId reference) {
  LastFrame last;
  last.frame = frame;
  last.T_c_w = T_c_w;
  last.reference = reference;
  const auto T_ref_w = keyframe_pose(reference);
  last.T_c_ref = T_ref_w ? T_c_w * T_ref_w->inverse() : SE3();
  {
    // Keyframes the mapper has taken in no longer need their pending pose.
    for (auto it = pending_keyframes_.begin(); it != pending_keyframes_.end();)
      it = map_.keyframe(it->first) != nullptr ? pending_keyframes_.erase(it) : std::next(it);
  }
  const std::size_t n = frame.features->points.size();
  last.landmarks.assign(n, map::kNoId);
  last.depth_points.assign(n, std::nullopt);
  // Depth points for the closest features (all close ones, at least 100), as visual odometry
  // between frames when the map does not yet cover the view.
  std::vector<std::pair<float, std::size_t>> by_depth;
  for (std::size_t i = 0; i < n; ++i) {
    const auto& f = frame.features->points[i];
    const Match& m = assoc.points[i];
    if (m.active && !m.outlier && m.landmark != map::kNoId) {
      last.landmarks[i] = m.landmark;
      continue;
    }
    const bool moving = objects_.point_excluded(i);
    if (f.has_depth() && !moving) by_depth.emplace_back(f.depth, i);
  }
  // Tracks: each point with depth extends the track of the last frame's point it was matched
  // to, whether or not the match survived as a pose inlier.
  last.tracks.assign(n, {});
  const SE3 T_w_c = T_c_w.inverse();
  const auto window = static_cast<std::size_t>(options_.dynamics.frame_gap) + 1;
  for (std::size_t i = 0; i < n; ++i) {
    const auto& f = frame.features->points[i];
    if (!f.has_depth()) continue;
    auto& track = last.tracks[i];
    if (last_ && assoc.from_last[i] >= 0)
      track = std::move(last_->tracks[static_cast<std::size_t>(assoc.from_last[i])]);
    if (track.size() >= window) track.erase(track.begin(), track.end() - (window - 1));
    track.push_back(T_w_c * camera_.unproject(f.keypoint.uv.cast<double>(), f.depth));
  }
  std::sort(by_depth.begin(), by_depth.end());
  const double close = close_depth();
  for (std::size_t k = 0; k < by_depth.size(); ++k) {
    if (by_depth[k].first > close && k >= 100) break;
    const auto& f = frame.features->points[by_depth[k].second];
    last.depth_points[by_depth[k].second] =
        camera_.unproject(f.keypoint.uv.cast<double>(), f.depth);
  }
  // Segments: their map line when tracked, else their own 3D fit.
  const std::size_t n_lines = frame.features->lines.size();
  last.line_landmarks.assign(n_lines, map::kNoId);
  last.line_has_depth.assign(n_lines, false);
  for (std::size_t i = 0; i < n_lines; ++i) {
    const LineMatch& m = assoc.lines[i];
    if (m.active && !m.outlier && m.landmark != map::kNoId) last.line_landmarks[i] = m.landmark;
    const bool moving = objects_.line_excluded(i);
    last.line_has_depth[i] = frame.features->lines[i].has_depth && !moving;
  }
  last_ = std::move(last);
}

}  // namespace mcslam::slam
