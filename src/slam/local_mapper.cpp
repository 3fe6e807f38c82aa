#include "mcslam/slam/local_mapper.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <set>
#include <unordered_set>

#include "map_adjustment.hpp"
#include "mcslam/core/thread_priority.hpp"
#include "mcslam/core/worker.hpp"
#include "mcslam/features/lines.hpp"
#include "mcslam/optim/bundle_adjustment.hpp"
#include "measurement.hpp"

namespace mcslam::slam {

LocalMapper::LocalMapper(const PinholeCamera& camera, const MapperOptions& options,
                         const TrackerOptions& tracker_options, double close_depth, map::Map& map)
    : camera_(camera),
      options_(options),
      close_depth_(close_depth),
      map_(map),
      tracker_options_(tracker_options) {}

LocalMapper::~LocalMapper() { finish(); }

void LocalMapper::process(KeyFrameRequest request, StageTimes* times) {
  StageTimes local;
  Stopwatch watch;
  const map::KeyFrameId id = request.id;
  if (fail_at_keyframe_ >= 0 && static_cast<std::int64_t>(id) == fail_at_keyframe_)
    throw std::runtime_error("failure injected at keyframe " + std::to_string(id) +
                             " (--inject-failure)");
  // Undistorted here, on the mapper's thread and before the map's lock, not on the frame's.
  const cv::Mat color = undistorter_ && !request.color.empty()
                            ? undistorter_->apply_rgb(request.color)
                            : request.color;
  insert_keyframe(request);
  create_points(id, color);
  create_lines(id);
  associate_planes(id);
  {
    std::lock_guard<std::mutex> guard(queue_mutex_);
    inserted_ = id;
  }
  idle_cv_.notify_all();
  local.add("map_insert", watch.elapsed_ms());
  watch.restart();
  cull_recent_points(id);
  cull_recent_lines(id);
  fuse_neighbours(id);
  local.add("map_fuse", watch.elapsed_ms());
  watch.restart();
  {
    // A keyframe that arrives from now on stops this BA (enqueue sets the flag), one queued
    // before does not; a task (a loop correction, a full-BA merge) never waits for it. Set under
    // the queue's mutex, so that it cannot wipe the abort of a task queued meanwhile.
    std::lock_guard<std::mutex> guard(queue_mutex_);
    abort_ba_ = !tasks_.empty();
  }
  local_bundle_adjustment(id);
  merge_planes();
  local.add("local_ba", watch.elapsed_ms());
  watch.restart();
  if (options_.cull_keyframes) cull_keyframes(id);
  local.add("keyframe_culling", watch.elapsed_ms());
  {
    auto lock = map_.write_lock();
    map_.bump_version();
  }
  if (times) *times = local;
  {
    std::lock_guard<std::mutex> guard(times_mutex_);
    times_.push_back(std::move(local));
  }
  if (occupancy_sink_ && !request.depth.empty())
    if (const map::KeyFrame* kf = map_.keyframe(id)) occupancy_sink_(request, color, kf->T_w_c());
  if (listener_ && map_.keyframe(id) != nullptr) listener_(id);
}

void LocalMapper::set_occupancy_sink(OccupancySink sink) { occupancy_sink_ = std::move(sink); }

void LocalMapper::set_correction_listener(std::function<void()> listener) {
  correction_listener_ = std::move(listener);
}

void LocalMapper::set_undistorter(std::shared_ptr<const io::Undistorter> undistorter) {
  undistorter_ = std::move(undistorter);
}

void LocalMapper::set_vocabulary(std::shared_ptr<const place::Vocabulary> vocabulary,
                                 int levels_up) {
  vocabulary_ = std::move(vocabulary);
  direct_levels_up_ = levels_up;
  if (vocabulary_) {
    auto lock = map_.write_lock();
    // Keyframes of a map made earlier get their bags of words now.
    std::vector<map::KeyFrameId> ids;
    for (const auto& kv : map_.keyframes()) ids.push_back(kv.first);
    for (map::KeyFrameId id : ids) map_.set_keyframe_bow(id, bag_of_words(*map_.keyframe(id)));
    map_.enable_database(vocabulary_->words());
  }
}

std::shared_ptr<const place::BowImage> LocalMapper::bag_of_words(const map::KeyFrame& kf) const {
  return std::make_shared<const place::BowImage>(vocabulary_->transform(
      kf.features->point_descriptors(), direct_levels_up_, kf.excluded_points));
}

void LocalMapper::set_keyframe_listener(std::function<void(map::KeyFrameId)> listener) {
  listener_ = std::move(listener);
}

void LocalMapper::PendingTask::complete(std::exception_ptr e) {
  std::lock_guard<std::mutex> guard(mutex);
  error = std::move(e);
  done = true;
  cv.notify_one();
}

void LocalMapper::run_task(const std::function<void()>& task) {
  auto pending = std::make_shared<PendingTask>();
  {
    std::unique_lock<std::mutex> lock(queue_mutex_);
    if (!thread_.joinable() || std::this_thread::get_id() == thread_.get_id()) {
      lock.unlock();
      task();
      return;
    }
    failure_.throw_if_failed();
    pending->run = task;
    tasks_.push_back(pending);
  }
  abort_ba_ = true;
  queue_cv_.notify_one();
  std::unique_lock<std::mutex> wait(pending->mutex);
  pending->cv.wait(wait, [&] { return pending->done; });
  if (pending->error) std::rethrow_exception(pending->error);
}

void LocalMapper::start(int niceness) {
  std::lock_guard<std::mutex> guard(queue_mutex_);
  if (thread_.joinable()) return;
  stop_ = false;
  thread_ = std::thread([this, niceness] {
    set_current_thread_name("mcslam-mapper");
    lower_current_thread_priority(niceness);  // best effort: the mapper runs either way
    run_guarded();
  });
}

void LocalMapper::enqueue(KeyFrameRequest request) {
  {
    std::lock_guard<std::mutex> guard(queue_mutex_);
    if (failure_.failed()) return;  // the thread has stopped: System reports its failure
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
  return queue_.empty() && tasks_.empty() && !busy_;
}

std::size_t LocalMapper::queue_size() const {
  std::lock_guard<std::mutex> guard(queue_mutex_);
  return queue_.size();
}

std::vector<StageTimes> LocalMapper::keyframe_times() const {
  std::lock_guard<std::mutex> guard(times_mutex_);
  return times_;
}

void LocalMapper::run_guarded() {
  try {
    run();
  } catch (...) {
    failure_.set(std::current_exception());
    std::deque<std::shared_ptr<PendingTask>> waiting;
    {
      std::lock_guard<std::mutex> lock(queue_mutex_);
      queue_.clear();
      waiting.swap(tasks_);
      busy_ = false;
    }
    idle_cv_.notify_all();
    for (const auto& task : waiting) task->complete(failure_.exception());
  }
}

void LocalMapper::run() {
  for (;;) {
    KeyFrameRequest request;
    {
      std::unique_lock<std::mutex> lock(queue_mutex_);
      queue_cv_.wait(lock, [this] { return stop_ || !queue_.empty() || !tasks_.empty(); });
      if (!tasks_.empty()) {
        std::shared_ptr<PendingTask> task = std::move(tasks_.front());
        tasks_.pop_front();
        busy_ = true;
        lock.unlock();
        // A task's exception is its waiter's: the mapper's thread and state carry on.
        try {
          task->run();
          task->complete(nullptr);
        } catch (...) {
          task->complete(std::current_exception());
        }
        lock.lock();
        busy_ = false;
        idle_cv_.notify_all();
        continue;
      }
      if (queue_.empty()) return;  // stop requested and everything processed
      request = std::move(queue_.front());
      queue_.pop_front();
      busy_ = true;
    }
    process(std::move(request));
    std::lock_guard<std::mutex> lock(queue_mutex_);
    busy_ = false;
    idle_cv_.notify_all();
  }
}

void LocalMapper::wait_idle() {
  std::unique_lock<std::mutex> lock(queue_mutex_);
  if (!thread_.joinable()) return;
  idle_cv_.wait(lock, [this] { return queue_.empty() && tasks_.empty() && !busy_; });
}

void LocalMapper::wait_inserted(map::KeyFrameId id) {
  std::unique_lock<std::mutex> lock(queue_mutex_);
  if (!thread_.joinable()) return;
  idle_cv_.wait(lock, [this, id] {
    return (inserted_ && *inserted_ >= id) || failure_.failed() ||
           (queue_.empty() && !busy_);  // stopped, or the request was dropped
  });
}

void LocalMapper::insert_keyframe(const KeyFrameRequest& request) {
  auto lock = map_.write_lock();
  for (const auto& s : request.statistics)
    map_.add_tracking_statistics(s.landmark, s.visible, s.found);
  for (const auto& s : request.line_statistics)
    map_.add_line_statistics(s.landmark, s.visible, s.found);
  // Points tracking saw move (a person the detector missed) leave the map.
  for (map::PointId p : request.moved_points)
    if (map_.point(p) != nullptr) map_.erase_point(p);
  map::KeyFrame kf;
  kf.id = request.id;
  kf.frame_id = request.frame.id;
  kf.timestamp = request.frame.timestamp;
  kf.T_c_w = request.T_c_w;
  // Tracked before a loop correction: the keyframe moves with the keyframe it was tracked on,
  // through the chain of culled keyframes when that one was culled meanwhile.
  if (request.map_version < corrected_version_ && request.reference != map::kNoId)
    if (const std::optional<SE3> T_ref_w = map_.keyframe_pose_T_c_w(request.reference))
      kf.T_c_w = request.T_c_ref * (*T_ref_w);
  // The keyframe keeps the features, not the grey image they came from (~300 KB at VGA, which
  // only carries boxes from one frame to the next): the map's memory grows by what it uses.
  if (request.frame.features && !request.frame.features->image.empty()) {
    auto features = std::make_shared<features::FrameFeatures>(*request.frame.features);
    features->image = cv::Mat();
    kf.features = std::move(features);
  } else {
    kf.features = request.frame.features;
  }
  kf.excluded_points = request.excluded_points;
  kf.excluded_lines = request.excluded_lines;
  if (vocabulary_) kf.bow = bag_of_words(kf);
  const map::KeyFrameId id = map_.add_keyframe(std::move(kf));
  for (std::size_t i = 0; i < request.landmarks.size(); ++i) {
    // A landmark fused into another since the request was made: the association goes to the
    // point that replaced it (else the feature would make a duplicate point).
    const map::PointId p = map_.resolve_point(request.landmarks[i]);
    if (p == map::kNoId || map_.point(p)->observations.count(id) != 0) continue;
    map_.add_observation(p, id, static_cast<int>(i));
    map_.update_point_appearance(p);
  }
  const SE3 T_w_c = map_.keyframe(id)->T_c_w.inverse();
  const auto& lines = request.frame.features->lines;
  for (std::size_t i = 0; i < request.line_landmarks.size(); ++i) {
    const map::LineId l = map_.resolve_line(request.line_landmarks[i]);
    const map::MapLine* ml = l != map::kNoId ? map_.line(l) : nullptr;
    if (ml == nullptr || ml->observations.count(id) != 0) continue;
    map_.add_line_observation(l, id, static_cast<int>(i));
    map_.update_line_appearance(l);
    // A longer view of the same line extends it, when its 3D fit agrees with the map line.
    if (!lines[i].has_depth) continue;
    const Eigen::Vector3d s_w = T_w_c * lines[i].start_c;
    const Eigen::Vector3d e_w = T_w_c * lines[i].end_c;
    const Eigen::Vector3d dir = ml->direction();
    const auto off_line = [&](const Eigen::Vector3d& p) {
      const Eigen::Vector3d v = p - ml->start_w;
      return (v - v.dot(dir) * dir).norm();
    };
    const double tolerance = 0.03 + 0.01 * std::max(lines[i].start_c.z(), lines[i].end_c.z());
    if (off_line(s_w) < tolerance && off_line(e_w) < tolerance) map_.extend_line(l, s_w, e_w);
  }
  const auto& planes = request.frame.features->planes;
  for (std::size_t i = 0; i < request.plane_landmarks.size(); ++i) {
    const map::PlaneId p = request.plane_landmarks[i];
    if (p == map::kNoId || map_.plane(p) == nullptr) continue;
    map_.add_plane_observation(p, id, static_cast<int>(i));
    std::vector<Eigen::Vector3d> hull_w;
    for (const auto& h : planes[i].hull) hull_w.push_back(T_w_c * h);
    map_.extend_plane(p, hull_w);
  }
  map_.update_covisibility(id);
}

void LocalMapper::create_points(map::KeyFrameId id, const cv::Mat& color) {
  auto lock = map_.write_lock();
  const map::KeyFrame* kf = map_.keyframe(id);
  if (kf == nullptr) return;
  std::vector<std::pair<float, int>> by_depth;
  for (std::size_t i = 0; i < kf->features->points.size(); ++i) {
    const auto& f = kf->features->points[i];
    if (f.has_depth() && kf->landmarks[i] == map::kNoId && !kf->point_excluded(i))
      by_depth.emplace_back(f.depth, static_cast<int>(i));
  }
  std::sort(by_depth.begin(), by_depth.end());
  const SE3 T_w_c = kf->T_w_c();
  int created = 0;
  for (const auto& [depth, index] : by_depth) {
    if (depth > close_depth_ && created >= options_.min_new_points) break;
    const auto& f = kf->features->points[static_cast<std::size_t>(index)];
    const Eigen::Vector3d p_w = T_w_c * camera_.unproject(f.keypoint.uv.cast<double>(), depth);
    const map::PointId pid = map_.add_point(p_w, id, index);
    recent_points_.push_back(pid);
    if (color.type() == CV_8UC3) {
      const int x = std::clamp(static_cast<int>(std::lround(f.keypoint.uv.x())), 0, color.cols - 1);
      const int y = std::clamp(static_cast<int>(std::lround(f.keypoint.uv.y())), 0, color.rows - 1);
      const cv::Vec3b bgr = color.at<cv::Vec3b>(y, x);
      map_.set_point_color(pid, {bgr[2], bgr[1], bgr[0]});
    }
    ++created;
  }
}

void LocalMapper::create_lines(map::KeyFrameId id) {
  auto lock = map_.write_lock();
  const map::KeyFrame* kf = map_.keyframe(id);
  if (kf == nullptr) return;
  const SE3 T_w_c = kf->T_w_c();
  const auto& lines = kf->features->lines;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (!lines[i].has_depth || kf->line_landmarks[i] != map::kNoId || kf->line_excluded(i))
      continue;
    recent_lines_.push_back(
        map_.add_line(T_w_c * lines[i].start_c, T_w_c * lines[i].end_c, id, static_cast<int>(i)));
    kf = map_.keyframe(id);
  }
}

void LocalMapper::associate_planes(map::KeyFrameId id) {
  auto lock = map_.write_lock();
  const map::KeyFrame* kf = map_.keyframe(id);
  if (kf == nullptr) return;
  const SE3 T_c_w = kf->T_c_w;
  const SE3 T_w_c = T_c_w.inverse();
  const Eigen::Matrix3d R_w_c = T_w_c.rotation();
  const Eigen::Vector3d t_c_w = T_c_w.translation();
  const auto planes = kf->features->planes;
  const auto landmarks = kf->plane_landmarks;
  for (std::size_t i = 0; i < planes.size(); ++i) {
    if (landmarks[i] != map::kNoId) continue;
    // The frame plane in the world: n_w = R_w_c n_c, d_w = d_c + n_c . t_c_w.
    const Eigen::Vector3d n_w = R_w_c * planes[i].normal;
    const double d_w = planes[i].d + planes[i].normal.dot(t_c_w);
    const optim::PlaneMeasurement measured = plane_measurement_of(
        planes[i], tracker_options_.plane_angle_sigma_deg, tracker_options_.plane_distance_sigma);
    map::PlaneId best = map::kNoId;
    double best_score = 2.0;
    for (const auto& [pid, mp] : map_.planes()) {
      if (mp.observations.count(id) != 0) continue;
      const auto score = plane_match_score(tracker_options_, mp.normal, mp.d, n_w, d_w);
      if (!score || *score >= best_score) continue;
      // The match window is wider than the measurement's noise (it absorbs the prediction's
      // error in the tracker); the keyframe's pose is solved, so the association must also pass
      // the chi-square test the tracker's and bundle adjustment's outlier tests apply.
      if (!(optim::plane_chi2(measured, T_c_w, mp.coefficients()) <=
            tracker_options_.pose.chi2_plane))
        continue;
      best_score = *score;
      best = pid;
    }
    std::vector<Eigen::Vector3d> hull_w;
    for (const auto& h : planes[i].hull) hull_w.push_back(T_w_c * h);
    if (best != map::kNoId) {
      map_.add_plane_observation(best, id, static_cast<int>(i));
      map_.extend_plane(best, hull_w);
    } else {
      map_.add_plane(Eigen::Vector4d(n_w.x(), n_w.y(), n_w.z(), d_w), hull_w, id,
                     static_cast<int>(i));
    }
  }
}

void LocalMapper::cull_recent_lines(map::KeyFrameId current) {
  auto lock = map_.write_lock();
  std::vector<map::LineId> keep;
  for (map::LineId id : recent_lines_) {
    const map::MapLine* ml = map_.line(id);
    if (ml == nullptr) continue;
    const map::KeyFrameId age = current - std::min(current, ml->first_keyframe);
    if (ml->found_ratio() < 0.25 || (age >= 2 && ml->observations.size() < 2))
      map_.erase_line(id);
    else if (age < 3)
      keep.push_back(id);
  }
  recent_lines_ = std::move(keep);
}

int LocalMapper::fuse_lines_into(map::KeyFrameId target_id, const std::vector<map::LineId>& lines) {
  const map::KeyFrame* target = map_.keyframe(target_id);
  if (target == nullptr || target->features->lines.empty()) return 0;
  std::vector<features::PredictedLine> predicted;
  std::vector<map::LineId> source;
  for (map::LineId lid : lines) {
    const map::MapLine* ml = map_.line(lid);
    if (ml == nullptr || ml->observations.count(target_id) != 0) continue;
    auto p = project_segment(camera_, target->T_c_w, ml->start_w, ml->end_w);
    if (!p) continue;
    p->descriptor = ml->descriptor;
    predicted.push_back(*p);
    source.push_back(lid);
  }
  const auto found = features::match_lines(predicted, target->features->lines,
                                           line_match_criteria(tracker_options_));
  int fused = 0;
  for (const auto& m : found) {
    target = map_.keyframe(target_id);
    const map::LineId lid = source[static_cast<std::size_t>(m.predicted)];
    const map::MapLine* ml = map_.line(lid);
    if (ml == nullptr || ml->observations.count(target_id) != 0) continue;
    if (target->line_excluded(static_cast<std::size_t>(m.observed))) continue;
    const map::LineId existing = target->line_landmarks[static_cast<std::size_t>(m.observed)];
    if (existing == lid) continue;
    if (existing != map::kNoId) {
      const map::MapLine* other = map_.line(existing);
      if (other == nullptr) continue;
      if (other->observations.size() > ml->observations.size())
        map_.replace_line(lid, existing);
      else
        map_.replace_line(existing, lid);
    } else {
      map_.add_line_observation(lid, target_id, m.observed);
      map_.update_line_appearance(lid);
    }
    ++fused;
  }
  return fused;
}

void LocalMapper::merge_planes() {
  auto lock = map_.write_lock();
  const double max_angle = options_.plane_merge_angle_deg * M_PI / 180.0;
  std::vector<map::PlaneId> ids;
  for (const auto& kv : map_.planes()) ids.push_back(kv.first);
  std::sort(ids.begin(), ids.end());
  for (std::size_t a = 0; a < ids.size(); ++a) {
    for (std::size_t b = a + 1; b < ids.size(); ++b) {
      const map::MapPlane* pa = map_.plane(ids[a]);
      const map::MapPlane* pb = map_.plane(ids[b]);
      if (pa == nullptr || pb == nullptr) continue;
      const double angle = std::acos(std::clamp(pa->normal.dot(pb->normal), -1.0, 1.0));
      if (angle > max_angle || std::abs(pa->d - pb->d) > options_.plane_merge_distance) continue;
      // A keyframe that sees both as separate planes says they are not one.
      bool seen_apart = false;
      for (const auto& obs : pa->observations) seen_apart |= pb->observations.count(obs.first) != 0;
      if (seen_apart) continue;
      if (pb->observations.size() > pa->observations.size())
        map_.replace_plane(ids[a], ids[b]);
      else
        map_.replace_plane(ids[b], ids[a]);
    }
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
      if (target->point_excluded(static_cast<std::size_t>(j))) continue;
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
  // The same for lines.
  std::vector<map::LineId> my_lines;
  for (map::LineId l : map_.keyframe(id)->line_landmarks)
    if (l != map::kNoId) my_lines.push_back(l);
  for (map::KeyFrameId t : targets) fuse_lines_into(t, my_lines);
  std::vector<map::LineId> their_lines;
  std::unordered_set<map::LineId> seen_lines;
  for (map::KeyFrameId t : targets)
    if (const map::KeyFrame* kf = map_.keyframe(t))
      for (map::LineId l : kf->line_landmarks)
        if (l != map::kNoId && seen_lines.insert(l).second) their_lines.push_back(l);
  fuse_lines_into(id, their_lines);
  for (map::KeyFrameId t : targets) map_.update_covisibility(t);
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
  if (correction_listener_) correction_listener_();
}

void LocalMapper::bundle_adjust_keyframes(const std::vector<map::KeyFrameId>& local,
                                          const optim::BundleAdjustmentOptions& ba_options,
                                          const std::atomic<bool>* abort) {
  // The mapper is the only writer: building without the lock is safe on this thread.
  MapAdjustment adjustment = build_adjustment(map_, local, options_, tracker_options_);
  if (adjustment.empty()) return;
  const auto result = optim::bundle_adjust(camera_, adjustment.problem, ba_options, abort);
  if (result.failed) {
    ++ba_failures_;  // nothing to apply: the map keeps its estimate
    return;
  }
  auto lock = map_.write_lock();
  apply_adjustment(map_, adjustment, result);
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
    if (kf == nullptr || !kf->loop_edges.empty()) continue;  // loop ends stay
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

void LocalMapper::correct(const map::MapCorrection& correction) {
  {
    auto lock = map_.write_lock();
    map::apply_correction(map_, correction);
    corrected_version_ = map_.version();
  }
  if (correction_listener_) correction_listener_();
}

namespace {

/// Every keyframe's pose and covisible keyframes, as they were before a loop correction.
struct KeyFrameSnapshot {
  std::unordered_map<map::KeyFrameId, SE3> pose;
  std::unordered_map<map::KeyFrameId, std::unordered_set<map::KeyFrameId>> linked;
};

KeyFrameSnapshot snapshot_keyframes(const map::Map& map) {
  KeyFrameSnapshot before;
  for (const auto& [id, kf] : map.keyframes()) {
    before.pose.emplace(id, kf.T_c_w);
    auto& linked = before.linked[id];
    for (const auto& kv : kf.covisibility) linked.insert(kv.first);
  }
  return before;
}

/// The loop's new keyframe and its covisible keyframes (the matched one excepted), with the
/// poses that move them rigidly to where the loop puts the new one.
struct LoopGroup {
  std::vector<map::KeyFrameId> members;  // the new keyframe first
  std::unordered_map<map::KeyFrameId, SE3> corrected;
};

LoopGroup loop_group(const map::Map& map, const LoopClosure& loop) {
  const map::KeyFrame* current = map.keyframe(loop.keyframe);
  LoopGroup group;
  group.members = {loop.keyframe};
  for (map::KeyFrameId n : map.best_covisible(loop.keyframe, current->covisibility.size()))
    if (n != loop.matched) group.members.push_back(n);
  const SE3 T_cur_w = current->T_c_w;
  for (map::KeyFrameId g : group.members)
    group.corrected.emplace(g, map.keyframe(g)->T_c_w * T_cur_w.inverse() * loop.T_c_w);
  return group;
}

/// The landmarks of the old place (the matched keyframe and its best covisible keyframes outside
/// the group), each once, in the order they are first seen.
struct PlaceLandmarks {
  std::vector<map::PointId> points;
  std::vector<map::LineId> lines;
};

PlaceLandmarks old_place_landmarks(const map::Map& map, const LoopClosure& loop,
                                   const LoopGroup& group) {
  std::vector<map::KeyFrameId> old_place = {loop.matched};
  for (map::KeyFrameId n : map.best_covisible(loop.matched, 10))
    if (group.corrected.count(n) == 0) old_place.push_back(n);
  PlaceLandmarks old;
  std::unordered_set<map::PointId> seen_points;
  std::unordered_set<map::LineId> seen_lines;
  for (map::KeyFrameId k : old_place) {
    const map::KeyFrame* kf = map.keyframe(k);
    for (map::PointId p : kf->landmarks)
      if (p != map::kNoId && map.point(p) != nullptr && seen_points.insert(p).second)
        old.points.push_back(p);
    for (map::LineId l : kf->line_landmarks)
      if (l != map::kNoId && map.line(l) != nullptr && seen_lines.insert(l).second)
        old.lines.push_back(l);
  }
  return old;
}

/// The loop's verified matches: the new keyframe's feature takes the old place's point (its own
/// point, if any, merged into it). Returns the number of points fused.
int fuse_verified_matches(map::Map& map, const LoopClosure& loop) {
  int fused = 0;
  for (const auto& [feature, point] : loop.matches) {
    const map::KeyFrame* kf = map.keyframe(loop.keyframe);
    if (map.point(point) == nullptr || feature < 0 ||
        static_cast<std::size_t>(feature) >= kf->landmarks.size())
      continue;
    if (map.point(point)->observations.count(loop.keyframe) != 0) continue;
    const map::PointId mine = kf->landmarks[static_cast<std::size_t>(feature)];
    if (mine == point) continue;
    if (mine != map::kNoId && map.point(mine) != nullptr)
      map.replace_point(mine, point);
    else
      map.add_observation(point, loop.keyframe, feature);
    map.update_point_appearance(point);
    ++fused;
  }
  return fused;
}

/// The essential graph of a loop correction over every keyframe (sorted by id; the first fixed),
/// starting from the loop's keyframes corrected and the others where they were.
struct EssentialGraph {
  std::vector<map::KeyFrameId> ids;
  std::unordered_map<map::KeyFrameId, int> index;  // keyframe -> pose index
  optim::PoseGraphProblem graph;
};

/// Edges: keyframes in order, strong covisibility (weight >= essential_edge_weight), loops;
/// measured on the poses before the correction, except the connections the loop made (measured
/// after it).
EssentialGraph essential_graph(const map::Map& map, const LoopClosure& loop,
                               const KeyFrameSnapshot& before, const LoopGroup& group,
                               int essential_edge_weight) {
  EssentialGraph g;
  for (const auto& kv : map.keyframes()) g.ids.push_back(kv.first);
  std::sort(g.ids.begin(), g.ids.end());
  const auto& corrected = group.corrected;
  for (map::KeyFrameId id : g.ids) {
    g.index.emplace(id, static_cast<int>(g.graph.poses.size()));
    const auto it = corrected.find(id);
    g.graph.poses.push_back(it != corrected.end() ? it->second : before.pose.at(id));
    g.graph.fixed.push_back(id == g.ids.front());
  }
  const auto pose_before = [&](map::KeyFrameId id) { return before.pose.at(id); };
  const auto pose_after = [&](map::KeyFrameId id) {
    const auto it = corrected.find(id);
    return it != corrected.end() ? it->second : before.pose.at(id);
  };
  std::set<std::pair<map::KeyFrameId, map::KeyFrameId>> added;
  const auto add_edge = [&](map::KeyFrameId a, map::KeyFrameId b, bool loop_connection) {
    if (a == b || before.pose.count(a) == 0 || before.pose.count(b) == 0) return;
    const auto key = std::minmax(a, b);
    if (!added.insert(key).second) return;
    const SE3 T_a_b = loop_connection ? pose_after(a) * pose_after(b).inverse()
                                      : pose_before(a) * pose_before(b).inverse();
    g.graph.edges.push_back({g.index.at(a), g.index.at(b), T_a_b, 1.0});
  };
  for (std::size_t k = 1; k < g.ids.size(); ++k) add_edge(g.ids[k - 1], g.ids[k], false);
  for (map::KeyFrameId id : g.ids) {
    const map::KeyFrame* kf = map.keyframe(id);
    for (map::KeyFrameId other : kf->loop_edges) {
      const bool this_loop = std::minmax(id, other) == std::minmax(loop.keyframe, loop.matched);
      add_edge(id, other, this_loop);
    }
    for (const auto& [other, weight] : kf->covisibility) {
      const bool was_linked =
          before.linked.count(id) != 0 && before.linked.at(id).count(other) != 0;
      const bool across = (corrected.count(id) != 0) != (corrected.count(other) != 0);
      if (across && !was_linked)
        add_edge(id, other, true);  // a connection the loop made
      else if (weight >= essential_edge_weight)
        add_edge(id, other, false);
    }
  }
  return g;
}

/// The poses of the graph, by keyframe.
std::unordered_map<map::KeyFrameId, SE3> graph_poses(const EssentialGraph& g) {
  std::unordered_map<map::KeyFrameId, SE3> poses;
  for (map::KeyFrameId id : g.ids)
    poses.emplace(id, g.graph.poses[static_cast<std::size_t>(g.index.at(id))]);
  return poses;
}

}  // namespace

bool LocalMapper::close_loop(const LoopClosure& loop, const LoopOptions& options,
                             LoopEvent& event) {
  Stopwatch watch;
  // The mapper is the only writer: reading without the lock is safe on this thread.
  const map::KeyFrame* current = map_.keyframe(loop.keyframe);
  if (current == nullptr || map_.keyframe(loop.matched) == nullptr) {
    event.reason = "a keyframe of the loop was culled before the correction";
    return false;
  }
  // Every keyframe's pose and covisible set before anything moves.
  const KeyFrameSnapshot before = snapshot_keyframes(map_);
  // The new keyframe and its neighbours, moved rigidly to where the loop puts the new one.
  const LoopGroup group = loop_group(map_, loop);
  const SE3 T_cur_w = current->T_c_w;
  event.correction_m =
      (T_cur_w.inverse().translation() - loop.T_c_w.inverse().translation()).norm();
  event.correction_deg =
      rotation_angle(T_cur_w.quaternion() * loop.T_c_w.quaternion().conjugate()) * 180.0 / M_PI;

  // The old place's landmarks, fused into the group seen from the corrected poses.
  const PlaceLandmarks old = old_place_landmarks(map_, loop, group);
  {
    // The loop's own keyframes move with their landmarks in one step, then take the old
    // place's landmarks: tracking, which works around them, sees a consistent local map now,
    // and the whole map once the pose graph is solved (one write lock each).
    auto lock = map_.write_lock();
    map::MapCorrection local;
    local.listed_only = true;
    for (const auto& [g, T] : group.corrected) {
      local.before.emplace(g, before.pose.at(g));
      local.after.emplace(g, T);
    }
    map::apply_correction(map_, local);
    corrected_version_ = map_.version();
    // The verified matches first.
    event.fused_points += fuse_verified_matches(map_, loop);
    for (map::KeyFrameId g : group.members) {
      event.fused_points += fuse_into(g, old.points);
      fuse_lines_into(g, old.lines);
    }
    for (map::KeyFrameId g : group.members) map_.update_covisibility(g);
    map_.add_loop_edge(loop.keyframe, loop.matched);
  }

  EssentialGraph graph = essential_graph(map_, loop, before, group, options.essential_edge_weight);
  // The graph starts from the map as it now stands.
  std::unordered_map<map::KeyFrameId, SE3> now = graph_poses(graph);
  if (optim::optimize_pose_graph(graph.graph, options.pose_graph).failed) {
    event.pose_graph_failed = true;
    event.correct_ms = watch.elapsed_ms();
    if (correction_listener_) correction_listener_();  // the loop's own keyframes moved
    return true;  // the loop's keyframes were corrected and fused: the loop stands
  }
  map::MapCorrection correction;
  correction.before = std::move(now);
  correction.after = graph_poses(graph);
  correct(correction);
  event.correct_ms = watch.elapsed_ms();
  return true;
}

}  // namespace mcslam::slam
