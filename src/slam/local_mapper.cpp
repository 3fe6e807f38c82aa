#include "mcslam/slam/local_mapper.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_set>

#include "mcslam/optim/bundle_adjustment.hpp"
#include "measurement.hpp"

namespace mcslam::slam {

LocalMapper::LocalMapper(const PinholeCamera& camera, const MapperOptions& options,
                         double close_depth, map::Map& map)
    : camera_(camera), options_(options), close_depth_(close_depth), map_(map) {}

LocalMapper::~LocalMapper() { finish(); }

void LocalMapper::process(KeyFrameRequest request, StageTimes* times) {
  StageTimes local;
  Stopwatch watch;
  const map::KeyFrameId id = request.id;
  insert_keyframe(request);
  create_points(id);
  local.add("map_insert", watch.elapsed_ms());
  watch.restart();
  cull_recent_points(id);
  fuse_neighbours(id);
  local.add("map_fuse", watch.elapsed_ms());
  watch.restart();
  abort_ba_ = false;
  local_bundle_adjustment(id);
  local.add("local_ba", watch.elapsed_ms());
  watch.restart();
  if (options_.cull_keyframes) cull_keyframes(id);
  local.add("keyframe_culling", watch.elapsed_ms());
  {
    auto lock = map_.write_lock();
    map_.bump_version();
  }
  if (times) *times = local;
  std::lock_guard<std::mutex> guard(times_mutex_);
  times_.push_back(std::move(local));
}

void LocalMapper::start() {
  std::lock_guard<std::mutex> guard(queue_mutex_);
  if (thread_.joinable()) return;
  stop_ = false;
  thread_ = std::thread([this] { run(); });
}

void LocalMapper::enqueue(KeyFrameRequest request) {
  {
    std::lock_guard<std::mutex> guard(queue_mutex_);
    queue_.push_back(std::move(request));
  }
  abort_ba_ = true;  // a running BA yields to the new keyframe
  queue_cv_.notify_one();
}

void LocalMapper::finish() {
  {
    std::lock_guard<std::mutex> guard(queue_mutex_);
    if (!thread_.joinable()) return;
    stop_ = true;
  }
  queue_cv_.notify_one();
  thread_.join();
}

bool LocalMapper::idle() const {
  std::lock_guard<std::mutex> guard(queue_mutex_);
  return queue_.empty() && !busy_;
}

std::size_t LocalMapper::queue_size() const {
  std::lock_guard<std::mutex> guard(queue_mutex_);
  return queue_.size();
}

std::vector<StageTimes> LocalMapper::keyframe_times() const {
  std::lock_guard<std::mutex> guard(times_mutex_);
  return times_;
}

void LocalMapper::run() {
  for (;;) {
    KeyFrameRequest request;
    {
      std::unique_lock<std::mutex> lock(queue_mutex_);
      queue_cv_.wait(lock, [this] { return stop_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stop requested and everything processed
      request = std::move(queue_.front());
      queue_.pop_front();
      busy_ = true;
    }
    process(std::move(request));
    std::lock_guard<std::mutex> lock(queue_mutex_);
    busy_ = false;
  }
}

void LocalMapper::insert_keyframe(const KeyFrameRequest& request) {
  auto lock = map_.write_lock();
  for (const auto& s : request.statistics)
    map_.add_tracking_statistics(s.point, s.visible, s.found);
  map::KeyFrame kf;
  kf.id = request.id;
  kf.frame_id = request.frame.id;
  kf.timestamp = request.frame.timestamp;
  kf.T_c_w = request.T_c_w;
  kf.features = request.frame.features;
  const map::KeyFrameId id = map_.add_keyframe(std::move(kf));
  for (std::size_t i = 0; i < request.landmarks.size(); ++i) {
    const map::PointId p = request.landmarks[i];
    if (p == map::kNoId || map_.point(p) == nullptr) continue;
    map_.add_observation(p, id, static_cast<int>(i));
    map_.update_point_appearance(p);
  }
  map_.update_covisibility(id);
}

void LocalMapper::create_points(map::KeyFrameId id) {
  auto lock = map_.write_lock();
  const map::KeyFrame* kf = map_.keyframe(id);
  if (kf == nullptr) return;
  std::vector<std::pair<float, int>> by_depth;
  for (std::size_t i = 0; i < kf->features->points.size(); ++i) {
    const auto& f = kf->features->points[i];
    if (f.has_depth() && kf->landmarks[i] == map::kNoId)
      by_depth.emplace_back(f.depth, static_cast<int>(i));
  }
  std::sort(by_depth.begin(), by_depth.end());
  const SE3 T_w_c = kf->T_w_c();
  int created = 0;
  for (const auto& [depth, index] : by_depth) {
    if (depth > close_depth_ && created >= options_.min_new_points) break;
    const auto& f = kf->features->points[static_cast<std::size_t>(index)];
    const Eigen::Vector3d p_w = T_w_c * camera_.unproject(f.keypoint.uv.cast<double>(), depth);
    recent_points_.push_back(map_.add_point(p_w, id, index));
    ++created;
  }
}

void LocalMapper::cull_recent_points(map::KeyFrameId current) {
  auto lock = map_.write_lock();
  std::vector<map::PointId> keep;
  for (map::PointId id : recent_points_) {
    const map::MapPoint* mp = map_.point(id);
    if (mp == nullptr) continue;
    const map::KeyFrameId age = current - std::min(current, mp->first_keyframe);
    if (mp->found_ratio() < 0.25) {
      map_.erase_point(id);
    } else if (age >= 2 && mp->observations.size() < 2) {
      map_.erase_point(id);
    } else if (age < 3) {
      keep.push_back(id);
    }
  }
  recent_points_ = std::move(keep);
}

int LocalMapper::fuse_into(map::KeyFrameId target_id, const std::vector<map::PointId>& points) {
  const map::KeyFrame* target = map_.keyframe(target_id);
  if (target == nullptr) return 0;
  const auto& pyramid = *target->features->pyramid;
  const Eigen::Vector3d center = target->camera_center();
  std::vector<int> candidates;
  int fused = 0;
  for (map::PointId pid : points) {
    const map::MapPoint* mp = map_.point(pid);
    if (mp == nullptr || mp->observations.count(target_id) != 0) continue;
    const Eigen::Vector3d p_c = target->T_c_w * mp->p_w;
    if (p_c.z() <= 0.0) continue;
    const Eigen::Vector2d uv = camera_.project(p_c);
    if (!camera_.in_image(uv)) continue;
    const Eigen::Vector3d ray = mp->p_w - center;
    const double distance = ray.norm();
    if (distance < 0.8 * mp->min_distance || distance > 1.2 * mp->max_distance) continue;
    if (ray.dot(mp->normal) < 0.5 * distance) continue;
    const int level = pyramid.predict_level(distance, mp->max_distance);
    const double radius = options_.fuse_radius * pyramid.scale[static_cast<std::size_t>(level)];
    target->features->grid.query(static_cast<float>(uv.x()), static_cast<float>(uv.y()),
                                 static_cast<float>(radius), std::max(0, level - 1), level,
                                 candidates);
    const double ur = camera_.right_u(uv.x(), p_c.z());
    int best = 256;
    int best_idx = -1;
    for (int j : candidates) {
      const auto& f = target->features->points[static_cast<std::size_t>(j)];
      double e2 = (f.keypoint.uv.cast<double>() - uv).squaredNorm();
      if (f.has_depth()) e2 += (f.u_right - ur) * (f.u_right - ur);
      const double chi2 = e2 * pyramid.inv_sigma2[static_cast<std::size_t>(f.keypoint.level)];
      if (chi2 > (f.has_depth() ? 7.8 : 5.99)) continue;
      const int d = features::hamming_distance(mp->descriptor, f.descriptor);
      if (d < best) {
        best = d;
        best_idx = j;
      }
    }
    if (best_idx < 0 || best > options_.fuse_descriptor_distance) continue;
    const map::PointId existing = target->landmarks[static_cast<std::size_t>(best_idx)];
    if (existing != map::kNoId) {
      const map::MapPoint* other = map_.point(existing);
      if (other == nullptr) continue;
      // Keep the landmark with more observations.
      if (other->observations.size() > mp->observations.size())
        map_.replace_point(pid, existing);
      else
        map_.replace_point(existing, pid);
    } else {
      map_.add_observation(pid, target_id, best_idx);
      map_.update_point_appearance(pid);
    }
    ++fused;
    target = map_.keyframe(target_id);
  }
  return fused;
}

void LocalMapper::fuse_neighbours(map::KeyFrameId id) {
  auto lock = map_.write_lock();
  if (map_.keyframe(id) == nullptr) return;
  std::vector<map::KeyFrameId> targets;
  std::unordered_set<map::KeyFrameId> chosen{id};
  for (map::KeyFrameId n :
       map_.best_covisible(id, static_cast<std::size_t>(options_.fuse_neighbours))) {
    if (chosen.insert(n).second) targets.push_back(n);
    for (map::KeyFrameId n2 : map_.best_covisible(n, 5))
      if (chosen.insert(n2).second) targets.push_back(n2);
  }
  // The new keyframe's points into the neighbours.
  const auto own_points = [&] {
    std::vector<map::PointId> pts;
    for (map::PointId p : map_.keyframe(id)->landmarks)
      if (p != map::kNoId) pts.push_back(p);
    return pts;
  };
  std::vector<map::PointId> mine = own_points();
  for (map::KeyFrameId t : targets) fuse_into(t, mine);
  // The neighbours' points into the new keyframe.
  std::vector<map::PointId> theirs;
  std::unordered_set<map::PointId> seen;
  for (map::KeyFrameId t : targets)
    if (const map::KeyFrame* kf = map_.keyframe(t))
      for (map::PointId p : kf->landmarks)
        if (p != map::kNoId && seen.insert(p).second) theirs.push_back(p);
  fuse_into(id, theirs);
  for (map::PointId p : own_points()) map_.update_point_appearance(p);
  map_.update_covisibility(id);
}

void LocalMapper::local_bundle_adjustment(map::KeyFrameId id) {
  // The mapper is the only writer: reading without the lock is safe on this thread.
  if (map_.keyframe(id) == nullptr) return;
  std::vector<map::KeyFrameId> local = {id};
  auto neighbours = map_.best_covisible(id, static_cast<std::size_t>(options_.ba_keyframes),
                                        options_.min_covisibility_weight);
  if (neighbours.empty()) neighbours = map_.best_covisible(id, 1);
  local.insert(local.end(), neighbours.begin(), neighbours.end());
  bundle_adjust_keyframes(local, options_.ba, &abort_ba_);
}

void LocalMapper::global_bundle_adjustment() {
  finish();
  std::vector<map::KeyFrameId> all;
  for (const auto& kv : map_.keyframes()) all.push_back(kv.first);
  std::sort(all.begin(), all.end());
  if (all.size() < 2) return;
  optim::BundleAdjustmentOptions options = options_.ba;
  options.robust_iterations = options_.global_ba_iterations;
  options.refine_iterations = options_.global_ba_iterations;
  bundle_adjust_keyframes(all, options, nullptr);
}

void LocalMapper::bundle_adjust_keyframes(const std::vector<map::KeyFrameId>& local,
                                          const optim::BundleAdjustmentOptions& ba_options,
                                          const std::atomic<bool>* abort) {
  std::unordered_set<map::KeyFrameId> local_set(local.begin(), local.end());

  optim::BundleAdjustmentProblem problem;
  std::unordered_map<map::KeyFrameId, int> pose_index;
  std::unordered_map<map::PointId, int> point_index;
  std::vector<map::PointId> point_ids;
  std::vector<std::pair<map::KeyFrameId, map::PointId>> observation_ids;
  const map::KeyFrameId first_keyframe = [&] {
    map::KeyFrameId first = map::kNoId;
    for (const auto& kv : map_.keyframes()) first = std::min(first, kv.first);
    return first;
  }();
  const auto add_pose = [&](map::KeyFrameId kf_id, bool fixed) {
    const auto [it, inserted] = pose_index.emplace(kf_id, static_cast<int>(problem.poses.size()));
    if (inserted) {
      problem.poses.push_back(map_.keyframe(kf_id)->T_c_w);
      problem.pose_fixed.push_back(fixed || kf_id == first_keyframe);
    }
    return it->second;
  };
  for (map::KeyFrameId kf_id : local) add_pose(kf_id, false);
  for (map::KeyFrameId kf_id : local) {
    for (map::PointId pid : map_.keyframe(kf_id)->landmarks) {
      if (pid == map::kNoId || point_index.count(pid) != 0) continue;
      const map::MapPoint* mp = map_.point(pid);
      if (mp == nullptr) continue;
      point_index.emplace(pid, static_cast<int>(problem.points.size()));
      problem.points.push_back(mp->p_w);
      point_ids.push_back(pid);
    }
  }
  for (std::size_t k = 0; k < point_ids.size(); ++k) {
    const map::MapPoint* mp = map_.point(point_ids[k]);
    for (const auto& [kf_id, index] : mp->observations) {
      const map::KeyFrame* kf = map_.keyframe(kf_id);
      if (kf == nullptr) continue;
      optim::BundleAdjustmentProblem::Observation obs;
      obs.pose = add_pose(kf_id, local_set.count(kf_id) == 0);
      obs.point = static_cast<int>(k);
      obs.measurement = measurement_of(kf->features->points[static_cast<std::size_t>(index)],
                                       *kf->features->pyramid, options_.depth_weight);
      problem.observations.push_back(obs);
      observation_ids.emplace_back(kf_id, point_ids[k]);
    }
  }
  if (problem.observations.empty()) return;
  const auto result = optim::bundle_adjust(camera_, problem, ba_options, abort);

  auto lock = map_.write_lock();
  for (std::size_t k = 0; k < observation_ids.size(); ++k)
    if (!result.inlier[k])
      map_.erase_observation(observation_ids[k].second, observation_ids[k].first);
  for (const auto& [kf_id, index] : pose_index)
    if (!problem.pose_fixed[static_cast<std::size_t>(index)])
      map_.set_keyframe_pose(kf_id, problem.poses[static_cast<std::size_t>(index)]);
  for (std::size_t k = 0; k < point_ids.size(); ++k) {
    if (map_.point(point_ids[k]) == nullptr) continue;
    map_.set_point_position(point_ids[k], problem.points[k]);
    map_.update_point_appearance(point_ids[k]);
  }
  for (map::KeyFrameId kf_id : local) map_.update_covisibility(kf_id);
}

void LocalMapper::cull_keyframes(map::KeyFrameId id) {
  auto lock = map_.write_lock();
  const map::KeyFrameId first_keyframe = [&] {
    map::KeyFrameId first = map::kNoId;
    for (const auto& kv : map_.keyframes()) first = std::min(first, kv.first);
    return first;
  }();
  for (map::KeyFrameId candidate : map_.best_covisible(id, 1000)) {
    if (candidate == first_keyframe || candidate == id) continue;
    const map::KeyFrame* kf = map_.keyframe(candidate);
    if (kf == nullptr) continue;
    int close_points = 0;
    int redundant = 0;
    for (std::size_t i = 0; i < kf->landmarks.size(); ++i) {
      const map::PointId pid = kf->landmarks[i];
      if (pid == map::kNoId) continue;
      const auto& f = kf->features->points[i];
      if (!f.has_depth() || f.depth > close_depth_) continue;
      const map::MapPoint* mp = map_.point(pid);
      if (mp == nullptr) continue;
      ++close_points;
      if (mp->observations.size() <= 3) continue;
      int others = 0;
      for (const auto& [other_id, other_index] : mp->observations) {
        if (other_id == candidate) continue;
        const map::KeyFrame* other = map_.keyframe(other_id);
        if (other == nullptr) continue;
        if (other->features->points[static_cast<std::size_t>(other_index)].keypoint.level <=
            f.keypoint.level + 1)
          ++others;
        if (others >= 3) break;
      }
      if (others >= 3) ++redundant;
    }
    if (close_points > 0 && redundant > options_.redundant_ratio * close_points)
      map_.erase_keyframe(candidate);
  }
}

}  // namespace mcslam::slam
