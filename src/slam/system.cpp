#include "mcslam/slam/system.hpp"

#include <deque>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "mcslam/core/error.hpp"
#include "mcslam/io/undistort.hpp"
#include "mcslam/map/session.hpp"
#include "mcslam/slam/frame.hpp"
#include "mcslam/slam/local_mapper.hpp"
#include "mcslam/slam/occupancy.hpp"

namespace mcslam::slam {

System::System(const PinholeCamera& camera, const SystemOptions& options,
               std::unique_ptr<map::Map> initial_map,
               std::vector<mapping::KeyframeSamples> initial_dense)
    : camera_(camera), options_(options) {
  if (auto e = camera.check()) throw InputError("camera: " + *e);
  if (auto e = options.check()) throw InputError("options: " + *e);
  if (options_.localize && !initial_map)
    throw InputError("options: localize needs a map made earlier (--load-session)");
  const bool from_map = initial_map != nullptr;
  started_in_map_ = from_map;
  if (options_.localize) options_.place.loop.enabled = false;
  undistorter_ = std::make_shared<const io::Undistorter>(camera_);
  builder_ = std::make_unique<FrameBuilder>(camera_, options_);
  if (options_.extract_ahead == "true" && !builder_->needs_moving_mask())
    ahead_builder_ = std::make_unique<FrameBuilder>(camera_, options_);
  map_ = from_map ? std::move(initial_map) : std::make_unique<map::Map>();
  if (!options_.place.vocabulary.empty())
    vocabulary_ = std::make_shared<const place::Vocabulary>(
        place::Vocabulary::load(options_.place.vocabulary));
  tracker_ = std::make_unique<Tracker>(camera_, options_.tracker, *map_, vocabulary_,
                                       options_.place.direct_levels_up);
  const double close_depth = options_.tracker.close_depth_factor * camera_.bf / camera_.fx;
  mapper_ =
      std::make_unique<LocalMapper>(camera_, options_.mapper, options_.tracker, close_depth, *map_);
  mapper_->set_undistorter(undistorter_);
  if (vocabulary_) mapper_->set_vocabulary(vocabulary_, options_.place.direct_levels_up);
  if (from_map) tracker_->start_in_map(map_->counters().next_keyframe, options_.localize);
  if (vocabulary_ && options_.place.loop.enabled) {
    loop_closer_ = std::make_unique<LoopCloser>(camera_, options_.place.loop, options_.tracker,
                                                options_.mapper, vocabulary_, *map_, *mapper_);
    LoopCloser* closer = loop_closer_.get();
    if (options_.sequential) {
      mapper_->set_keyframe_listener([closer](map::KeyFrameId id) { closer->process(id); });
    } else {
      mapper_->set_keyframe_listener([closer](map::KeyFrameId id) { closer->enqueue(id); });
      loop_closer_->start(options_.background_niceness);
    }
  }
  if (options_.occupancy_enabled) {
    if (options_.localize)  // no keyframes: fed by views (add_localize_view)
      occupancy_ = std::make_unique<mapping::MappingWorker>(options_.occupancy);
    else
      connect_occupancy();
    occupancy_->set_floor_candidates(floor_candidates(*map_));
    if (!initial_dense.empty()) occupancy_->restore(std::move(initial_dense));
  }
  if (!options_.sequential) mapper_->start(options_.background_niceness);
  if (camera_.readout_auto)
    readout_ = std::make_unique<ReadoutEstimator>(camera_, options_.readout);
}

void System::connect_occupancy() {
  occupancy_ = std::make_unique<mapping::MappingWorker>(options_.occupancy);
  const double depth_margin = options_.tracker.dynamics.object_depth_gap;
  // On the mapper's thread (the map's writer: it reads the map without a lock).
  mapper_->set_occupancy_sink([this, depth_margin](const KeyFrameRequest& request,
                                                   const cv::Mat& colour, const SE3& T_w_c) {
    mapping::KeyframeDepth keyframe =
        dense_keyframe(camera_, request.depth, T_w_c, request.still_regions,
                       request.dynamic_regions, request.mover_regions, depth_margin);
    keyframe.id = request.id;
    if (colour.type() == CV_8UC3 && colour.size() == request.depth.size()) keyframe.colour = colour;
    occupancy_->set_floor_candidates(floor_candidates(*map_));
    occupancy_->enqueue_shared(std::move(keyframe));
  });
  mapper_->set_correction_listener([this] {
    std::unordered_map<mapping::KeyframeId, SE3> poses;
    for (const auto& [id, kf] : map_->keyframes()) poses.emplace(id, kf.T_w_c());
    occupancy_->set_floor_candidates(floor_candidates(*map_));
    occupancy_->correct(std::move(poses));
  });
}

ReadoutReport System::readout_report() const {
  if (readout_) return readout_->report();
  ReadoutReport r;
  r.readout_time = camera_.readout_time;
  return r;
}

System::~System() { stop_threads(); }

void System::set_detection_source(std::unique_ptr<DetectionSource> source, bool wait) {
  detections_ = std::move(source);
  wait_for_detections_ = wait;
  next_frame_waits_for_boxes_ = frame_waits_for_boxes();
}

bool System::frame_waits_for_boxes() const {
  const bool cold_start = !started_in_map_ && keyframes_made_ < options_.cold_start_keyframes;
  return detections_ != nullptr && (wait_for_detections_ || options_.sequential || cold_start);
}

cv::Mat System::undistort(const cv::Mat& rgb) const { return undistorter_->apply_rgb(rgb); }

namespace {

/// Boxes of the raw image in the undistorted image: the bounding box of 12 border points.
std::vector<perception::Detection> undistort_boxes(const PinholeCamera& camera,
                                                   std::vector<perception::Detection> boxes) {
  if (!camera.has_distortion() || boxes.empty()) return boxes;
  const cv::Matx33d K(camera.fx, 0, camera.cx, 0, camera.fy, camera.cy, 0, 0, 1);
  const cv::Mat D(1, 5, CV_64F, const_cast<double*>(camera.distortion.data()));
  std::vector<cv::Point2f> raw;
  for (const auto& d : boxes)
    for (int k = 0; k < 4; ++k) {
      const float f = k / 3.0f;
      raw.emplace_back(d.box.x + f * d.box.width, d.box.y);
      raw.emplace_back(d.box.x + f * d.box.width, d.box.y + d.box.height);
      raw.emplace_back(d.box.x, d.box.y + f * d.box.height);
    }
  std::vector<cv::Point2f> und;
  cv::undistortPoints(raw, und, K, D, cv::noArray(), K);
  for (std::size_t b = 0; b < boxes.size(); ++b) {
    cv::Rect2f r(und[b * 12], cv::Size2f(0.f, 0.f));
    float x0 = r.x, y0 = r.y, x1 = r.x, y1 = r.y;
    for (std::size_t k = 0; k < 12; ++k) {
      x0 = std::min(x0, und[b * 12 + k].x);
      y0 = std::min(y0, und[b * 12 + k].y);
      x1 = std::max(x1, und[b * 12 + k].x);
      y1 = std::max(y1, und[b * 12 + k].y);
    }
    boxes[b].box = cv::Rect2f(x0, y0, x1 - x0, y1 - y0);
  }
  return boxes;
}

}  // namespace

PreparedImages System::prepare(const cv::Mat& rgb, const cv::Mat& depth) const {
  Stopwatch watch;
  PreparedImages out;
  out.rgb = rgb;
  const bool valid_rgb =
      !rgb.empty() && rgb.depth() == CV_8U && (rgb.channels() == 3 || rgb.channels() == 1);
  const bool valid_depth = !depth.empty() && depth.type() == CV_32FC1;
  if (!valid_rgb || !valid_depth || rgb.cols != camera_.width || rgb.rows != camera_.height ||
      depth.size() != rgb.size()) {
    out.problem = !valid_rgb     ? "the colour image is not 8-bit grey or BGR"
                  : !valid_depth ? "the depth image is not CV_32FC1"
                                 : "the images are not of the camera's size";
    return out;
  }
  if (rgb.channels() == 3)
    cv::cvtColor(rgb, out.gray, cv::COLOR_BGR2GRAY);
  else
    out.gray = rgb;
  out.gray = undistorter_->apply_rgb(out.gray);
  out.depth = undistorter_->apply_depth(depth);
  // Without distortion the undistorter hands back its input: the frame keeps these images (the
  // grey one carries boxes to the next frame), and the caller may reuse its buffers.
  if (out.gray.data == rgb.data) out.gray = out.gray.clone();
  if (out.depth.data == depth.data) out.depth = depth.clone();
  out.prepare_ms = watch.elapsed_ms();
  return out;
}

bool System::can_extract_ahead() const { return ahead_builder_ != nullptr; }

bool System::extracts_ahead_now() const {
  return can_extract_ahead() && !next_frame_waits_for_boxes_.load();
}

void System::extract_features(PreparedImages& images) const {
  if (!extracts_ahead_now() || !images.problem.empty() || images.features) return;
  images.features =
      std::make_shared<const DetectedFeatures>(ahead_builder_->detect(images.gray, images.depth));
}

Frame System::build_frame(const PreparedImages& images, FrameResult& result,
                          const FrameMotion& motion) const {
  const DetectedFeatures* ahead = images.features.get();
  if (!ahead || !can_extract_ahead() || ahead->size != images.gray.size())
    return builder_->build(result.frame_id, result.timestamp, images.gray, images.depth, motion,
                           &result.times);
  // Found on another thread while the frame before was tracked: this frame did not wait.
  result.times.add_concurrent("orb_extract", ahead->orb_ms);
  if (options_.use.lines) result.times.add_concurrent("line_extract", ahead->line_ms);
  if (options_.use.planes) result.times.add_concurrent("plane_extract", ahead->plane_ms);
  return builder_->finish(result.frame_id, result.timestamp, *ahead, images.gray, images.depth,
                          motion, &result.times);
}

FrameResult System::process(const cv::Mat& rgb, const cv::Mat& depth, double timestamp,
                            std::optional<double> depth_timestamp) {
  PreparedImages images = prepare(rgb, depth);
  const double undistort_ms = images.prepare_ms;
  images.prepare_ms = -1.0;  // ran inline: listed as `undistort` below
  FrameResult result = process(images, timestamp, depth_timestamp);
  if (images.problem.empty())
    result.times.stages.insert(result.times.stages.begin(), {"undistort", undistort_ms});
  return result;
}

FrameResult System::process(const PreparedImages& images, double timestamp,
                            std::optional<double> depth_timestamp) {
  FrameResult result;
  result.frame_id = next_frame_id_++;
  result.timestamp = timestamp;
  FrameRecord record;
  record.timestamp = timestamp;

  throw_if_background_failed();
  const cv::Mat& rgb = images.rgb;
  if (!images.problem.empty() || finished_) {
    result.state = TrackingState::kLost;
    add_record(record);
    return result;
  }
  if (images.prepare_ms >= 0.0) result.times.add_concurrent("prepare", images.prepare_ms);

  // The detector starts on this image now and runs while the features are extracted. While the
  // first map is built (cold start), the frame waits for its own boxes.
  const bool wait_for_boxes = frame_waits_for_boxes();
  if (detections_ && rgb.channels() == 3)
    detections_->submit(result.frame_id, timestamp, rgb, wait_for_boxes);

  const FrameMotion motion = frame_motion(timestamp, depth_timestamp);
  result.readout_time = motion.readout_time;
  Frame frame = build_frame(images, result, motion);
  if (detections_) attach_boxes(frame, wait_for_boxes, result);
  result.features = static_cast<int>(frame.features->points.size());
  result.lines = static_cast<int>(frame.features->lines.size());
  result.planes = static_cast<int>(frame.features->planes.size());

  const bool sequential = options_.sequential;
  TrackingOutcome outcome = tracker_->track(frame, sequential || mapper_->idle(),
                                            sequential ? 0 : mapper_->queue_size(), &result.times);
  pose_failures_ = tracker_->solver_failures();
  report_tracking(frame, outcome, result);
  remember_moving_regions(result);
  if (readout_) observe_readout(frame, motion, outcome);
  if (outcome.state == TrackingState::kOk) {
    result.T_w_c = outcome.T_c_w_online.inverse();
    result.online_pose = outcome.online_pose;
    place_moving_objects(images.depth, *result.T_w_c, result);
    if (options_.localize && occupancy_) add_localize_view(images.depth, result);
    record.tracked = true;
    record.reference = outcome.reference;
    record.T_c_ref = outcome.T_c_ref;
    record.T_c_w = outcome.T_c_w_online;
  }
  if (outcome.lagged)
    result.lagged = StampedPose{outcome.lagged->timestamp, outcome.lagged->T_c_w.inverse()};
  if (outcome.keyframe) hand_over_keyframe(std::move(*outcome.keyframe), images, result);
  add_record(record, result.lagged);
  return result;
}

void System::report_tracking(const Frame& frame, TrackingOutcome& outcome,
                             FrameResult& result) const {
  result.state = outcome.state;
  result.relocalised = outcome.relocalised;
  result.relocalisation = outcome.relocalisation;
  result.matches = outcome.matches;
  result.inliers = outcome.inliers;
  result.line_matches = outcome.line_matches;
  result.line_inliers = outcome.line_inliers;
  result.plane_inliers = outcome.plane_inliers;
  result.frame_features = frame.features;
  result.point_labels = std::move(outcome.objects.point_labels);
  result.line_labels = std::move(outcome.objects.line_labels);
  result.objects = std::move(outcome.objects.objects);
  result.constrained_point_residuals = outcome.objects.constrained_point_residuals;
  result.constrained_line_residuals = outcome.objects.constrained_line_residuals;
  result.dynamics_threshold = outcome.objects.threshold;
  result.propagation_iou = outcome.objects.propagation_iou;
  result.stale_iou = outcome.objects.stale_iou;
  result.mover_regions = outcome.objects.mover_regions;
  result.mover_points = outcome.objects.mover_points;
}

void System::hand_over_keyframe(KeyFrameRequest keyframe, const PreparedImages& images,
                                FrameResult& result) {
  result.keyframe = true;
  ++keyframes_made_;
  next_frame_waits_for_boxes_ = frame_waits_for_boxes();
  // New points take their colour from the keyframe's image (for the saved map). The mapper
  // undistorts it on its thread; its own copy, as the caller may reuse its buffer.
  if (images.rgb.channels() == 3) keyframe.color = images.rgb.clone();
  if (occupancy_) {
    // Shared: the prepared depth is never written after it was made.
    keyframe.depth = images.depth;
    keyframe.dynamic_regions = object_regions(result.objects, ObjectState::kDynamic);
    keyframe.mover_regions = object_regions(result.objects, ObjectState::kConstrained);
    keyframe.still_regions = object_regions(result.objects, ObjectState::kStatic);
  }
  if (!options_.sequential) {
    const bool wait = options_.wait_for_keyframe_points && mapper_->idle();
    const map::KeyFrameId id = keyframe.id;
    mapper_->enqueue(std::move(keyframe));
    if (wait) {
      Stopwatch watch;
      mapper_->wait_inserted(id);
      result.times.add("keyframe_wait", watch.elapsed_ms());
    }
    return;
  }
  StageTimes mapper_times;
  try {
    mapper_->process(std::move(keyframe), &mapper_times);
  } catch (const std::exception& e) {
    // Inline, the mapper (and the loop closer it calls) fail in the caller's thread: named as a
    // background thread's failure is, so that a caller handles both alike.
    throw BackgroundThreadError(std::string("the mapper (inline, sequential) failed: ") + e.what());
  }
  for (auto& stage : mapper_times.stages) result.times.add(stage.first, stage.second);
}

void System::add_localize_view(const cv::Mat& depth, const FrameResult& result) {
  if (last_localize_view_ &&
      result.timestamp - *last_localize_view_ < options_.occupancy.localize_view_period)
    return;
  last_localize_view_ = result.timestamp;
  // Integrated, never stored: its objects seen still need not be told (nothing relabels it).
  mapping::KeyframeDepth view = dense_keyframe(
      camera_, depth, *result.T_w_c, {}, object_regions(result.objects, ObjectState::kDynamic),
      object_regions(result.objects, ObjectState::kConstrained),
      options_.tracker.dynamics.object_depth_gap);
  occupancy_->enqueue_transient(std::move(view));
}

void System::place_moving_objects(const cv::Mat& depth, const SE3& T_w_c, FrameResult& result) {
  // The depth image is undistorted: its camera has no distortion.
  PinholeCamera undistorted = camera_;
  undistorted.distortion = {0.0, 0.0, 0.0, 0.0, 0.0};
  // A box's centre jitters by centimetres from frame to frame (its depth pixels change with the
  // box): the velocity is the least-squares slope of the centre over the track's last half
  // second (at least 3 frames spanning 0.1 s), not a difference of two frames (up to 50 m/s on
  // Bonn crowd from that jitter over 33 ms).
  constexpr double kWindow = 0.5;  // s
  std::unordered_map<int, std::deque<std::pair<double, Eigen::Vector3d>>> tracks;
  for (ObjectReport& o : result.objects) {
    if (o.state == ObjectState::kStatic) continue;
    o.world_box = world_box(undistorted, depth, {o.detection.box, o.depth_near, o.depth_far}, T_w_c,
                            options_.tracker.dynamics.object_depth_gap);
    if (!o.world_box || o.track_id < 0) continue;
    // A box cut by the image border holds only the part in view: its centre moves as the
    // object enters or leaves the image, not with the object (p90 6.6 m/s on Bonn crowd part1
    // from such boxes). No velocity from it; the track goes on with the next whole box.
    const cv::Rect2f& b = o.detection.box;
    constexpr float kBorder = 2.0f;  // px
    if (b.x <= kBorder || b.y <= kBorder || b.x + b.width >= camera_.width - kBorder ||
        b.y + b.height >= camera_.height - kBorder) {
      if (const auto before = object_tracks_.find(o.track_id); before != object_tracks_.end())
        tracks[o.track_id] = before->second;
      continue;
    }
    auto& history = tracks[o.track_id];
    if (const auto before = object_tracks_.find(o.track_id); before != object_tracks_.end())
      history = before->second;
    history.emplace_back(result.timestamp, 0.5 * (o.world_box->first + o.world_box->second));
    while (history.front().first < result.timestamp - kWindow) history.pop_front();
    if (history.size() < 3 || history.back().first - history.front().first < 0.1) continue;
    double mean_t = 0.0;
    Eigen::Vector3d mean_p = Eigen::Vector3d::Zero();
    for (const auto& [t, p] : history) {
      mean_t += t;
      mean_p += p;
    }
    mean_t /= static_cast<double>(history.size());
    mean_p /= static_cast<double>(history.size());
    double var_t = 0.0;
    Eigen::Vector3d cov = Eigen::Vector3d::Zero();
    for (const auto& [t, p] : history) {
      var_t += (t - mean_t) * (t - mean_t);
      cov += (t - mean_t) * (p - mean_p);
    }
    o.velocity = cov / var_t;
  }
  object_tracks_ = std::move(tracks);
}

void System::observe_readout(const Frame& frame, const FrameMotion& motion,
                             const TrackingOutcome& outcome) {
  if (outcome.state != TrackingState::kOk) {
    readout_->reset();
    return;
  }
  ReadoutFrame observed;
  observed.timestamp = frame.timestamp;
  observed.T_c_w = outcome.T_c_w;
  observed.omega_used = motion.angular_velocity;
  observed.readout_used = motion.readout_time;
  const auto& points = frame.features->points;
  const auto& pyramid = *frame.features->pyramid;
  observed.points.reserve(outcome.point_inliers.size());
  for (const auto& [i, landmark] : outcome.point_inliers)
    if (points[i].has_depth())
      observed.points.push_back(
          {landmark, points[i].keypoint.uv.cast<double>(), points[i].depth,
           pyramid.inv_sigma2[static_cast<std::size_t>(points[i].keypoint.level)]});
  readout_->add(std::move(observed));
}

FrameMotion System::frame_motion(double timestamp, std::optional<double> depth_timestamp) const {
  FrameMotion motion;
  if (options_.tracker.compensate_depth_time && depth_timestamp &&
      std::abs(*depth_timestamp - timestamp) > 1e-4)
    motion.T_rgb_depth = tracker_->predicted_motion(timestamp - *depth_timestamp);
  // The readout in use: the fixed setting, or the estimate once it is confident (0 before).
  const double readout = readout_ ? readout_->readout_time() : camera_.readout_time;
  if (readout != 0.0) {
    motion.readout_time = readout;
    motion.angular_velocity = tracker_->angular_velocity();
  }
  motion.moving_regions = expected_moving_regions(timestamp);
  return motion;
}

void System::attach_boxes(Frame& frame, bool wait, FrameResult& result) const {
  Stopwatch watch;
  if (auto found = detections_->collect(result.frame_id, wait)) {
    auto objects = std::make_shared<FrameObjects>();
    objects->boxes = undistort_boxes(camera_, std::move(found->boxes));
    objects->fresh = found->frame_id == result.frame_id;
    objects->age = static_cast<int>(result.frame_id - found->frame_id);
    frame.objects = std::move(objects);
    result.detections_used = true;
    result.detections_fresh = frame.objects->fresh;
    result.detections_age = frame.objects->age;
    if (frame.objects->fresh && found->detect_ms > 0.0) result.detect_ms = found->detect_ms;
  }
  result.times.add("detection_wait", watch.elapsed_ms());
}

void System::remember_moving_regions(const FrameResult& result) {
  moving_regions_.clear();
  moving_regions_time_ = result.timestamp;
  // Static objects' boxes are kept out of the regions (max_depth < 0): Algorithm 1 needs their
  // features to go on telling them static.
  for (const ObjectReport& o : result.objects)
    if (o.state == ObjectState::kDynamic)
      moving_regions_.push_back({o.detection.box, o.depth_far > 0.0f ? o.depth_far : 0.0f});
  for (const ObjectReport& o : result.objects)
    if (o.state == ObjectState::kStatic && o.source != ObjectReport::Source::kMover)
      moving_regions_.push_back({o.detection.box, -1.0f});
}

std::vector<FrameMotion::MovingRegion> System::expected_moving_regions(double timestamp) const {
  // A person walks at up to ~1.4 m/s; at 1 m from the camera that moves their image by
  // fx * 1.4 * dt pixels, which bounds where the previous frame's moving objects can be now.
  constexpr double kWalkingSpeed = 1.4;  // m/s
  constexpr double kNearDepth = 1.0;     // m
  const double dt = std::clamp(timestamp - moving_regions_time_, 0.0, 1.0);
  const auto margin = static_cast<float>(camera_.fx * kWalkingSpeed * dt / kNearDepth);
  // Its far side comes no farther than the walk plus the gap that splits object from background.
  const auto deeper =
      static_cast<float>(kWalkingSpeed * dt + options_.tracker.dynamics.object_depth_gap);
  std::vector<FrameMotion::MovingRegion> out;
  for (const FrameMotion::MovingRegion& m : moving_regions_) {
    const cv::Rect2f& r = m.box;
    if (m.max_depth < 0.0f) {
      out.push_back(m);  // a static object's box
      continue;
    }
    out.push_back({{r.x - margin, r.y - margin, r.width + 2 * margin, r.height + 2 * margin},
                   m.max_depth > 0.0f ? m.max_depth + deeper : 0.0f});
  }
  return out;
}

void System::stop_threads() {
  // The mapper's queue first (its keyframes go to the loop closer), then the loop closer (its
  // corrections run on the mapper's thread), then the mapper.
  if (loop_closer_) {
    mapper_->wait_idle();
    loop_closer_->finish();
  }
  mapper_->finish();
}

std::string System::background_failure() const {
  if (mapper_->failure().failed()) return mapper_->failure().message();
  if (loop_closer_ && loop_closer_->failure().failed()) return loop_closer_->failure().message();
  if (detections_ && detections_->failure() && detections_->failure()->failed())
    return detections_->failure()->message();
  if (occupancy_ && occupancy_->failed()) return occupancy_->failure_message();
  return "";
}

void System::throw_if_background_failed() const {
  const std::string failure = background_failure();
  if (!failure.empty()) throw BackgroundThreadError(failure);
}

void System::inject_failure(const std::string& thread, std::int64_t at) {
  if (thread == "mapper") {
    mapper_->inject_failure_at(at);
  } else if (thread == "loop" && loop_closer_) {
    loop_closer_->inject_failure_at(at);
  } else if (thread == "detector") {
    auto* model = dynamic_cast<ModelDetectionSource*>(detections_.get());
    if (!model) throw InputError("--inject-failure detector: the run has no detector model");
    model->inject_failure_at(at);
  } else {
    throw InputError("--inject-failure: no " + thread +
                     " thread in this run (mapper, loop with loop closing, detector with a model)");
  }
}

void System::finish() {
  if (finished_) return;
  finished_ = true;
  stop_threads();
  {
    const std::vector<optim::LaggedPose> last = tracker_->flush_lagged_poses();
    std::lock_guard<std::mutex> guard(records_mutex_);
    for (const optim::LaggedPose& p : last) lagged_.push_back({p.timestamp, p.T_c_w.inverse()});
  }
  throw_if_background_failed();
  if (options_.mapper.global_ba_iterations > 0 && !options_.localize)
    mapper_->global_bundle_adjustment();  // the dense map is corrected after it
  if (occupancy_) {
    try {
      occupancy_->wait();
    } catch (const std::exception& e) {
      throw BackgroundThreadError(e.what());
    }
  }
}

void System::add_record(const FrameRecord& record, const std::optional<StampedPose>& lagged) {
  std::lock_guard<std::mutex> guard(records_mutex_);
  records_.push_back(record);
  if (lagged) lagged_.push_back(*lagged);
}

std::vector<System::FrameRecord> System::records() const {
  std::lock_guard<std::mutex> guard(records_mutex_);
  return records_;
}

SolverStatistics System::solver_statistics() const {
  SolverStatistics s;
  s.pose_failures = pose_failures_.load();
  s.bundle_adjustment_failures = mapper_->ba_failures();
  if (loop_closer_) {
    const LoopStatistics loops = loop_closer_->statistics();
    s.full_ba_failures = loops.full_ba_failed;
    s.pose_graph_failures = loops.pose_graph_failed;
  }
  return s;
}

Trajectory System::trajectory(optim::TrajectorySmoothingReport* report) const {
  std::vector<std::size_t> breaks;
  const Trajectory poses = corrected_trajectory(&breaks);
  return optim::smooth_trajectory(poses, options_.trajectory, report, breaks);
}

Trajectory System::unsmoothed_trajectory() const { return corrected_trajectory(nullptr); }

Trajectory System::corrected_trajectory(std::vector<std::size_t>* after_loss) const {
  Trajectory out;
  const std::vector<FrameRecord> frames = records();
  auto lock = map_->read_lock();
  bool lost = false;
  for (const FrameRecord& r : frames) {
    if (!r.tracked) {
      lost = !out.empty();
      continue;
    }
    if (lost && after_loss) after_loss->push_back(out.size());
    lost = false;
    const auto T_ref_w = map_->keyframe_pose_T_c_w(r.reference);
    const SE3 T_c_w = T_ref_w ? r.T_c_ref * (*T_ref_w) : r.T_c_w;
    out.push_back({r.timestamp, T_c_w.inverse()});
  }
  return out;
}

Trajectory System::online_trajectory() const {
  Trajectory out;
  for (const FrameRecord& r : records())
    if (r.tracked) out.push_back({r.timestamp, r.T_c_w.inverse()});
  return out;
}

Trajectory System::lagged_trajectory() const {
  std::lock_guard<std::mutex> guard(records_mutex_);
  return lagged_;
}

Trajectory System::keyframe_trajectory() const {
  Trajectory out;
  auto lock = map_->read_lock();
  for (const auto& [id, kf] : map_->keyframes()) out.push_back({kf.timestamp, kf.T_w_c()});
  std::sort(out.begin(), out.end(),
            [](const StampedPose& a, const StampedPose& b) { return a.timestamp < b.timestamp; });
  return out;
}

std::vector<StageTimes> System::mapper_times() const { return mapper_->keyframe_times(); }

void System::save_session(const std::string& path) const {
  map::SessionInfo info;
  info.camera = camera_;
  // The map's keypoints were compensated with the estimated readout (a session stores a number).
  if (readout_) info.camera.readout_time = readout_->readout_time();
  info.camera.readout_auto = false;
  info.vocabulary_id = vocabulary_ ? vocabulary_->id() : 0;
  info.orb_levels = options_.orb.num_levels;
  info.orb_scale_factor = options_.orb.scale_factor;
  std::vector<mapping::KeyframeSamples> dense;
  if (occupancy_) {
    occupancy_->wait();  // what is queued is part of the map
    occupancy_->with_map([&dense](const mapping::OccupancyMap& m) { dense = m.keyframes(); });
    std::sort(dense.begin(), dense.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  }
  auto lock = map_->read_lock();
  map::save_session(path, *map_, info, dense);
}

void System::set_localize(bool localize) { tracker_->set_localize(localize); }

LoopStatistics System::loop_statistics() const {
  return loop_closer_ ? loop_closer_->statistics() : LoopStatistics{};
}

}  // namespace mcslam::slam
