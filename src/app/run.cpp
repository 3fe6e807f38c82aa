#include "mcslam/app/run.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <iomanip>
#include <iostream>
#include <map>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "map_quality.hpp"
#include "mcslam/app/frame_feed.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/core/thread_failure.hpp"
#include "mcslam/eval/bonn.hpp"
#include "mcslam/eval/metrics.hpp"
#include "mcslam/io/files.hpp"
#include "mcslam/io/sequence.hpp"
#include "mcslam/io/trajectory_io.hpp"
#include "mcslam/map/export.hpp"
#include "mcslam/map/session.hpp"
#include "mcslam/perception/detection.hpp"
#include "mcslam/perception/detector.hpp"
#include "mcslam/place/vocabulary.hpp"
#include "mcslam/slam/config.hpp"
#include "mcslam/slam/readout_calibration.hpp"
#include "mcslam/slam/system.hpp"
#include "occupancy_outputs.hpp"
#include "run_observers.hpp"

namespace mcslam::app {
namespace {

/// Peak resident memory of this process in MiB (Linux), 0 when unknown.
double peak_rss_mib() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return 0.0;
}

bool is_bonn(const std::string& directory) {
  std::string name = std::filesystem::path(directory).lexically_normal().filename().string();
  std::transform(name.begin(), name.end(), name.begin(), ::tolower);
  return name.find("bonn") != std::string::npos;
}

std::string format_tum_keyframes(const Trajectory& keyframes) {
  std::ostringstream s;
  s << "# keyframe poses T_w_c: timestamp tx ty tz qx qy qz qw\n";
  s << std::fixed;
  for (const auto& p : keyframes) {
    const auto& q = p.T_w_c.quaternion();
    const auto& t = p.T_w_c.translation();
    s << std::setprecision(6) << p.timestamp << std::setprecision(9) << ' ' << t.x() << ' ' << t.y()
      << ' ' << t.z() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
  }
  return s.str();
}

/// The detection source the request asks for, or null (geometry only).
std::unique_ptr<slam::DetectionSource> make_detection_source(const RunRequest& request,
                                                             const PinholeCamera& camera,
                                                             const slam::SystemOptions& system) {
  if (request.model && request.detections)
    throw InputError("--model and --detections exclude each other: give one source of boxes");
  if (request.detections) {
    perception::DetectionsFile file = perception::read_detections(*request.detections);
    if ((file.image_width && *file.image_width != camera.width) ||
        (file.image_height && *file.image_height != camera.height))
      throw InputError(file_error(*request.detections,
                                  "boxes are for " + std::to_string(file.image_width.value_or(0)) +
                                      "x" + std::to_string(file.image_height.value_or(0)) +
                                      " images but the camera is " + std::to_string(camera.width) +
                                      "x" + std::to_string(camera.height)));
    return std::make_unique<slam::FileDetectionSource>(std::move(file), *request.detections);
  }
  if (request.model) {
    perception::DetectorOptions options;
    if (request.confidence) options.confidence = *request.confidence;
    if (auto e = options.check()) throw InputError("--confidence: " + *e);
    options.input_size =
        perception::input_size_for(cv::Size(camera.width, camera.height), system.detector_scale);
    // A frame that waits for its own boxes must be given to the detector.
    const bool waits = request.wait_for_detections || system.sequential;
    return std::make_unique<slam::ModelDetectionSource>(
        perception::Detector(*request.model, options), waits ? 1 : system.detection_interval,
        waits ? 0 : system.detector_niceness);
  }
  return nullptr;
}

}  // namespace

void draw_overlay(cv::Mat& bgr, const slam::FrameResult& r) {
  if (bgr.empty() || bgr.type() != CV_8UC3 || !r.frame_features) return;
  const cv::Scalar green(0, 200, 0), red(0, 0, 230), yellow(0, 220, 255), grey(150, 150, 150),
      white(255, 255, 255);
  const auto& f = *r.frame_features;
  for (std::size_t i = 0; i < f.lines.size(); ++i) {
    const auto label = i < r.line_labels.size() ? r.line_labels[i] : slam::FeatureLabel::kStatic;
    const cv::Scalar c = label == slam::FeatureLabel::kStatic        ? red
                         : label == slam::FeatureLabel::kConstrained ? yellow
                                                                     : grey;
    cv::line(bgr, cv::Point2f(f.lines[i].start.x(), f.lines[i].start.y()),
             cv::Point2f(f.lines[i].end.x(), f.lines[i].end.y()), c, 1, cv::LINE_AA);
  }
  for (std::size_t i = 0; i < f.points.size(); ++i) {
    const auto label = i < r.point_labels.size() ? r.point_labels[i] : slam::FeatureLabel::kStatic;
    const cv::Scalar c = label == slam::FeatureLabel::kStatic        ? green
                         : label == slam::FeatureLabel::kConstrained ? yellow
                                                                     : grey;
    cv::circle(bgr, cv::Point2f(f.points[i].keypoint.uv.x(), f.points[i].keypoint.uv.y()), 2, c, -1,
               cv::LINE_AA);
  }
  for (const slam::ObjectReport& o : r.objects) {
    const cv::Scalar c = o.state == slam::ObjectState::kDynamic       ? red
                         : o.state == slam::ObjectState::kConstrained ? yellow
                                                                      : white;
    const cv::Rect box(cv::Point(cvRound(o.detection.box.x), cvRound(o.detection.box.y)),
                       cv::Size(cvRound(o.detection.box.width), cvRound(o.detection.box.height)));
    cv::rectangle(bgr, box, c, o.state == slam::ObjectState::kStatic ? 1 : 2);
    std::ostringstream text;
    text << o.detection.class_name << ' ' << std::fixed << std::setprecision(2) << o.detection.score
         << ' ' << slam::to_string(o.state);
    int baseline = 0;
    const cv::Size size = cv::getTextSize(text.str(), cv::FONT_HERSHEY_SIMPLEX, 0.45, 1, &baseline);
    const cv::Point origin(box.x, std::max(size.height + 2, box.y - 2));
    cv::rectangle(bgr, origin + cv::Point(0, 2), origin + cv::Point(size.width, -size.height - 2),
                  c, cv::FILLED);
    cv::putText(bgr, text.str(), origin, cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1,
                cv::LINE_AA);
  }
}

void apply_feature_list(const std::string& list, bool& points, bool& lines, bool& planes) {
  points = lines = planes = false;
  std::stringstream stream(list);
  for (std::string kind; std::getline(stream, kind, ',');) {
    if (kind == "points")
      points = true;
    else if (kind == "lines")
      lines = true;
    else if (kind == "planes")
      planes = true;
    else
      throw InputError("--features: unknown feature kind '" + kind +
                       "' (use a comma-separated subset of points,lines,planes)");
  }
  if (!points && !lines && !planes)
    throw InputError("--features: name at least one of points, lines, planes");
}

namespace {

/// A session file whose map can continue in this run: same camera, ORB pyramid and vocabulary.
map::Session load_compatible_session(const std::string& path, const slam::RunConfig& config) {
  map::Session session = map::load_session(path);
  const PinholeCamera& a = session.info.camera;
  const PinholeCamera& b = config.camera;
  const auto close = [](double x, double y) {
    return std::abs(x - y) <= 1e-6 * (1.0 + std::abs(y));
  };
  if (a.width != b.width || a.height != b.height || !close(a.fx, b.fx) || !close(a.fy, b.fy) ||
      !close(a.cx, b.cx) || !close(a.cy, b.cy) || !close(a.bf, b.bf))
    throw InputError(file_error(path, "the map was made with another camera (" +
                                          std::to_string(a.width) + "x" + std::to_string(a.height) +
                                          ", fx " + std::to_string(a.fx) + ") than this run's (" +
                                          std::to_string(b.width) + "x" + std::to_string(b.height) +
                                          ", fx " + std::to_string(b.fx) + ")"));
  if (session.info.orb_levels != config.options.orb.num_levels ||
      !close(session.info.orb_scale_factor, config.options.orb.scale_factor))
    throw InputError(file_error(path, "the map was made with other ORB pyramid settings (" +
                                          std::to_string(session.info.orb_levels) + " levels)"));
  std::uint64_t vocabulary_id = 0;
  if (!config.options.place.vocabulary.empty())
    vocabulary_id = place::Vocabulary::load(config.options.place.vocabulary).id();
  if (session.info.vocabulary_id != vocabulary_id) {
    char ids[80];
    std::snprintf(ids, sizeof(ids), "%016llx, this run's is %016llx",
                  static_cast<unsigned long long>(session.info.vocabulary_id),
                  static_cast<unsigned long long>(vocabulary_id));
    throw InputError(
        file_error(path, std::string("the map was made with another vocabulary (id ") + ids + ")"));
  }
  return session;
}

/// Loops for summary.json: counts, every verified candidate with its figures, timings.
/// The rolling-shutter readout time used and, when estimated, how (summary.json "readout").
nlohmann::json readout_json(const slam::ReadoutReport& r) {
  nlohmann::json j = {{"mode", r.automatic ? "auto" : "fixed"}, {"readout_time_s", r.readout_time}};
  if (!r.automatic) return j;
  j["estimate_s"] = r.estimate;
  j["std_s"] = r.std;
  j["frames_used"] = r.frames_used;
  j["frames_rejected"] = r.frames_rejected;
  j["epochs"] = r.epochs;
  j["confident"] = r.confident;
  j["confident_at_timestamp"] = r.confident_at;
  j["frames_used_when_confident"] = r.frames_used_when_confident;
  return j;
}

/// The calibration pass before the run (summary.json "readout" / "calibration").
nlohmann::json calibration_json(const slam::ReadoutCalibration& c) {
  return {{"frames", c.frames},
          {"sequence_s", c.sequence_s},
          {"wall_ms", c.wall_ms},
          {"confident", c.report.confident},
          {"estimate_s", c.report.estimate},
          {"std_s", c.report.std},
          {"frames_used", c.report.frames_used},
          {"start_readout_time_s", c.readout_time}};
}

nlohmann::json loops_json(const slam::LoopStatistics& stats, const slam::PlaceOptions& place) {
  nlohmann::json events = nlohmann::json::array();
  int accepted = 0;
  for (const auto& e : stats.events) {
    accepted += e.accepted ? 1 : 0;
    nlohmann::json j = {{"keyframe", e.keyframe},
                        {"matched_keyframe", e.matched},
                        {"timestamp", e.timestamp},
                        {"matched_timestamp", e.matched_timestamp},
                        {"score", e.score},
                        {"matches", e.matches},
                        {"ransac_inliers", e.ransac_inliers},
                        {"inliers", e.inliers},
                        {"accepted", e.accepted},
                        {"verify_ms", e.verify_ms}};
    if (e.accepted) {
      j["correction_m"] = e.correction_m;
      j["correction_deg"] = e.correction_deg;
      j["fused_points"] = e.fused_points;
      j["correct_ms"] = e.correct_ms;
    } else {
      j["reason"] = e.reason;
    }
    events.push_back(std::move(j));
  }
  const SampleStats detection = compute_stats(stats.detection_ms);
  const SampleStats ba = compute_stats(stats.full_ba_ms);
  return {{"enabled", place.loop.enabled && !place.vocabulary.empty()},
          {"vocabulary", place.vocabulary},
          {"candidates_without_matches", stats.unmatched_candidates},
          {"detected", stats.events.size()},
          {"accepted", accepted},
          {"rejected", static_cast<int>(stats.events.size()) - accepted},
          {"detection_median_ms", detection.median},
          {"detection_p95_ms", detection.p95},
          {"keyframes_checked", detection.count},
          {"full_ba_runs", stats.full_ba_runs},
          {"full_ba_aborted", stats.full_ba_aborted},
          {"full_ba_median_ms", ba.median},
          {"events", events}};
}

/// The frames a run plays: the sequence `passes` times in a row, pass k shifted by k * period.
struct StreamPlan {
  std::vector<io::FrameEntry> frames;
  int passes = 1;
  std::size_t frames_per_pass = 0;
  std::size_t first_index = 0;     // the source's index of frames[0] (--first-frame)
  double first = 0.0, last = 0.0;  // RGB timestamps of the sequence's first and last frames
  double gap = 0.0;                // median time between frames
  double period = 0.0;             // last - first + gap: pass k starts at first + k * period
};

/// One frame's images, of the camera's size (InputError naming the file otherwise).
io::RgbdImages load_checked(const io::FrameSource& source, const StreamPlan& plan, std::size_t k,
                            const PinholeCamera& camera) {
  const io::FrameEntry& entry = plan.frames[k];
  io::RgbdImages raw =
      source.load(plan.first_index + k % plan.frames_per_pass, camera.depth_factor);
  if (raw.rgb.cols != camera.width || raw.rgb.rows != camera.height)
    throw InputError(file_error(
        entry.rgb_path, "image is " + std::to_string(raw.rgb.cols) + "x" +
                            std::to_string(raw.rgb.rows) + " but the camera is " +
                            std::to_string(camera.width) + "x" + std::to_string(camera.height)));
  return raw;
}

StreamPlan plan_stream(std::vector<io::FrameEntry> frames, int passes, std::size_t first_index) {
  StreamPlan plan;
  plan.passes = passes;
  plan.first_index = first_index;
  frames.erase(frames.begin(),
               frames.begin() + static_cast<std::ptrdiff_t>(std::min(first_index, frames.size())));
  plan.frames_per_pass = frames.size();
  if (frames.empty()) return plan;  // a live stream
  plan.first = frames.front().rgb_timestamp;
  plan.last = frames.back().rgb_timestamp;
  std::vector<double> gaps;
  for (std::size_t i = 1; i < frames.size(); ++i)
    gaps.push_back(frames[i].rgb_timestamp - frames[i - 1].rgb_timestamp);
  plan.gap = gaps.empty() ? 1.0 : compute_stats(gaps).median;
  plan.period = plan.last - plan.first + plan.gap;
  plan.frames.reserve(frames.size() * passes);
  for (int k = 0; k < passes; ++k) {
    for (io::FrameEntry entry : frames) {
      entry.rgb_timestamp += k * plan.period;
      entry.depth_timestamp += k * plan.period;
      plan.frames.push_back(std::move(entry));
    }
  }
  return plan;
}

/// The ground truth of each pass: the poses within half a frame gap of the sequence's frames,
/// shifted as the pass's frames are (the copies cannot overlap: period = span + gap).
Trajectory repeat_groundtruth(const Trajectory& groundtruth, const StreamPlan& plan) {
  Trajectory out;
  for (int k = 0; k < plan.passes; ++k)
    for (const StampedPose& pose : groundtruth)
      if (pose.timestamp >= plan.first - 0.5 * plan.gap &&
          pose.timestamp < plan.last + 0.5 * plan.gap)
        out.push_back({pose.timestamp + k * plan.period, pose.T_w_c});
  return out;
}

/// The frames of a run, one at a time: from the feed (a recorded sequence, read ahead on the
/// feed's thread) or from a live stream (prepared on the loop's thread as they arrive).
struct InputFrame {
  slam::PreparedImages images;
  double rgb_timestamp = 0.0, depth_timestamp = 0.0;
  std::size_t index = 0;  // frames taken or dropped before this one
  double wait_ms = 0.0;
  std::size_t dropped_before = 0;
  double due_s = 0.0;  // real time: when the frame was due on the feed's clock
};

class FrameInput {
 public:
  FrameInput(const RunRequest& request, const io::FrameSource* source, const StreamPlan& plan,
             std::size_t total, const slam::System& system, const PinholeCamera& camera)
      : live_(request.live.get()), plan_(plan), system_(system), camera_(camera) {
    if (live_) return;
    // Frames are read, decoded and undistorted on the feed's thread, off the frame loop.
    auto load = [&plan, &system, source, &camera](std::size_t k) {
      const io::RgbdImages raw = load_checked(*source, plan, k, camera);
      return system.prepare(raw.rgb, raw.depth);
    };
    std::vector<double> stamps;
    stamps.reserve(total);
    for (std::size_t k = 0; k < total; ++k) stamps.push_back(plan.frames[k].rgb_timestamp);
    // Threaded runs may extract each frame's features on the feed's thread once the frame is
    // due, while the loop tracks the frame before (SystemOptions::extract_ahead); not while
    // frames wait for their own boxes (the cold start), when the loop extracts them beside the
    // detector and the feed hands them over as without extraction ahead.
    FrameFeed::Finisher extract;
    FrameFeed::FinishWanted extracting;
    if (!system.options().sequential && system.can_extract_ahead()) {
      extract = [&system](slam::PreparedImages& images) { system.extract_features(images); };
      extracting = [&system] { return system.extracts_ahead_now(); };
    }
    feed_.emplace(load, std::move(stamps), FeedOptions{request.realtime, 2}, std::move(extract),
                  std::move(extracting));
  }

  /// The next frame, nullopt at the end of the stream. image_load (wait_ms) is the time the
  /// loop waited for the feed (in real time: for the camera).
  std::optional<InputFrame> next(std::size_t done) {
    InputFrame in;
    if (live_) {
      Stopwatch wait;
      std::optional<LiveFrame> frame = live_->next();
      if (!frame) return std::nullopt;
      if (frame->rgb.cols != camera_.width || frame->rgb.rows != camera_.height ||
          frame->depth.size() != frame->rgb.size())
        throw InputError(live_->describe() + ": frame at " + std::to_string(frame->rgb_timestamp) +
                         " s is " + std::to_string(frame->rgb.cols) + "x" +
                         std::to_string(frame->rgb.rows) + " (depth " +
                         std::to_string(frame->depth.cols) + "x" +
                         std::to_string(frame->depth.rows) + ") but the camera is " +
                         std::to_string(camera_.width) + "x" + std::to_string(camera_.height));
      in.index = done;
      in.wait_ms = wait.elapsed_ms();
      in.dropped_before = frame->dropped_before;
      in.images = system_.prepare(frame->rgb, frame->depth);
      in.rgb_timestamp = frame->rgb_timestamp;
      in.depth_timestamp = frame->depth_timestamp;
      return in;
    }
    std::optional<FedFrame> fed = feed_->next();
    if (!fed) return std::nullopt;
    in.index = fed->index;
    in.wait_ms = fed->wait_ms;
    in.dropped_before = fed->dropped_before;
    in.due_s = fed->due_s;
    in.images = std::move(fed->images);
    in.rgb_timestamp = plan_.frames[fed->index].rgb_timestamp;
    in.depth_timestamp = plan_.frames[fed->index].depth_timestamp;
    return in;
  }
  /// Seconds on the feed's clock (real time).
  double now_s() const { return feed_ ? feed_->now_s() : 0.0; }
  std::vector<std::size_t> dropped() const {
    return feed_ ? feed_->dropped() : std::vector<std::size_t>{};
  }

 private:
  LiveSource* live_;
  const StreamPlan& plan_;
  const slam::System& system_;
  const PinholeCamera& camera_;
  std::optional<FrameFeed> feed_;
};

/// `--inject-failure THREAD:N` (testing the failure path): see System::inject_failure.
void inject_failure(slam::System& system, const std::string& spec) {
  const std::size_t colon = spec.find(':');
  std::int64_t at = -1;
  if (colon != std::string::npos) {
    try {
      std::size_t used = 0;
      at = std::stoll(spec.substr(colon + 1), &used);
      if (used != spec.size() - colon - 1) at = -1;
    } catch (const std::exception&) {
      at = -1;
    }
  }
  if (at < 0)
    throw InputError("--inject-failure '" + spec +
                     "': expected THREAD:N (mapper:N, loop:N or detector:N, N >= 0)");
  system.inject_failure(spec.substr(0, colon), at);
}

/// How the frame loop ended.
struct Streamed {
  bool interrupted = false;
  std::size_t done = 0;     // frames processed
  std::size_t offered = 0;  // frames taken or dropped
  /// What stopped the run early: a background thread's failure (BackgroundThreadError) or an
  /// exception of the frame's own path; "" when the stream ended or was stopped.
  std::string failure;
};

/// Feeds every frame to the system and each result to the observers, until the stream ends, a
/// stop is requested or something fails (then the outputs so far are still written).
Streamed stream_frames(const RunRequest& request, FrameInput& input, slam::System& system,
                       const std::vector<FrameObserver*>& observers, RunControl* control,
                       Viewer* viewer) {
  Streamed out;
  bool viewer_failure_reported = false;
  try {
    for (;;) {
      if (request.stop_requested && request.stop_requested()) {
        out.interrupted = true;
        break;
      }
      if (control) {
        // Between two frames: wait while paused, switch localisation only on or off.
        control->wait_while_paused(request.stop_requested);
        if (request.stop_requested && request.stop_requested()) continue;
        if (const std::optional<bool> localize = control->take_localize_change(out.done))
          system.set_localize(*localize);
      }
      if (viewer && !viewer_failure_reported && !viewer->failure().empty()) {
        // The viewer only watches: SLAM goes on without it, and the run's exit code says so.
        std::cerr << "mcslam: error: " << viewer->failure() << " (the run goes on without it)\n";
        viewer_failure_reported = true;
      }
      std::optional<InputFrame> in = input.next(out.done);
      if (!in) break;
      out.offered = in->index + 1;
      const slam::FrameResult r =
          system.process(in->images, in->rgb_timestamp, in->depth_timestamp);
      ++out.done;
      FrameEvent event{r,           in->images,  system,      in->rgb_timestamp,
                       out.done,    out.offered, in->wait_ms, in->dropped_before,
                       std::nullopt};
      if (request.realtime) event.latency_ms = 1000.0 * (input.now_s() - in->due_s);
      for (FrameObserver* o : observers) o->on_frame(event);
    }
  } catch (const InputError&) {
    throw;  // bad input: reported as such, before or instead of outputs
  } catch (const std::exception& e) {
    out.failure = e.what();
  }
  for (FrameObserver* o : observers) o->on_stream_end(system);
  return out;
}

/// On a sequence of `mcslam synth` (its objects.json beside the images), the dense map scored
/// against the scene's exact geometry: occupancy["quality"] (or "quality_error").
void score_synthetic_map(nlohmann::json& occupancy, const std::string& source_path,
                         const Trajectory& trajectory, const SE3& T_gt_est,
                         const mapping::MappingWorker& worker) {
  try {
    const auto scene =
        read_synthetic_scene(std::filesystem::path(source_path) / "objects.json",
                             trajectory.front().timestamp, trajectory.back().timestamp);
    if (!scene) return;
    worker.with_map([&](const mapping::OccupancyMap& map) {
      occupancy["quality"] = evaluate_synthetic_map(map, *scene, T_gt_est.inverse());
    });
  } catch (const InputError& e) {
    occupancy["quality_error"] = e.what();
  }
}

nlohmann::json run_frames(const RunRequest& request, const std::string& source_path,
                          const io::FrameSource* source, const std::vector<std::string>& warnings,
                          const StreamPlan& plan, std::size_t total, const slam::RunConfig& config,
                          std::unique_ptr<slam::DetectionSource> detection_source,
                          map::Session initial, const std::optional<Trajectory>& groundtruth,
                          const std::optional<slam::ReadoutCalibration>& calibration,
                          RunStatus& status, Viewer* viewer, RunControl* control) {
  namespace fs = std::filesystem;
  const fs::path out(request.output_dir);
  slam::System system(config.camera, config.options, std::move(initial.map),
                      std::move(initial.dense));
  std::string detection_description;
  if (detection_source) {
    detection_description = detection_source->describe();
    system.set_detection_source(std::move(detection_source), request.wait_for_detections);
  }
  if (request.inject_failure) inject_failure(system, *request.inject_failure);

  // The viewer reads the System from its own thread: it lets go before the System goes, also
  // when the run ends with an error.
  struct DetachViewer {
    Viewer* viewer;
    ~DetachViewer() {
      if (viewer) viewer->detach();
    }
  } detach_viewer{viewer};
  // So do the callbacks' own threads (the ROS node's map publisher): RunRequest::on_detach.
  struct DetachCallbacks {
    const std::function<void()>& detach;
    ~DetachCallbacks() {
      if (detach) detach();
    }
  } detach_callbacks{request.on_detach};

  // The observers of each frame's result, in the order they see it.
  FrameRecorder recorder;
  ObjectsRecorder objects(system.detection_source()
                              ? std::optional<std::string>((out / "objects.json").string())
                              : std::nullopt);
  std::optional<OverlayWriter> overlays;
  if (request.save_overlays) overlays.emplace(out / "overlays");
  std::optional<CallbackObserver> callback;
  if (request.on_frame) callback.emplace(request.on_frame);
  std::optional<PassRecorder> passes;
  if (plan.passes > 1) passes.emplace(recorder, plan.frames_per_pass, total);
  Checkpointer checkpoints(out, status, request.live != nullptr, total);
  std::optional<ProgressObserver> progress;
  if (request.progress) progress.emplace(total, recorder);
  std::vector<FrameObserver*> observers = {&recorder, &objects};
  if (overlays) observers.push_back(&*overlays);
  if (callback) observers.push_back(&*callback);
  if (passes) observers.push_back(&*passes);
  observers.push_back(&checkpoints);
  if (progress) observers.push_back(&*progress);
  if (viewer) observers.push_back(viewer);

  Stopwatch wall;
  FrameInput input(request, source, plan, total, system, config.camera);
  const Streamed streamed = stream_frames(request, input, system, observers, control, viewer);
  const bool interrupted = streamed.interrupted;
  const std::size_t offered = streamed.offered;
  std::string failure = streamed.failure;
  if (failure.empty()) {
    try {
      system.finish();
    } catch (const std::exception& e) {
      failure = e.what();
    }
  }
  const double wall_s = wall.elapsed_ms() / 1000.0;
  // A failed thread may have left the map half-changed: no session is made of it.
  if (request.save_session && failure.empty()) system.save_session(*request.save_session);
  const std::size_t processed = streamed.done;

  // Outputs.
  optim::TrajectorySmoothingReport smoothing;
  const Trajectory trajectory = system.trajectory(&smoothing);
  const Trajectory unsmoothed = system.unsmoothed_trajectory();
  const std::string note = !failure.empty() ? "failed after frame " + std::to_string(offered) +
                                                  " of " + std::to_string(total) + ": " + failure
                           : interrupted
                               ? "interrupted after frame " + std::to_string(offered) + " of " +
                                     std::to_string(total) + " (stopped on request)"
                               : std::string();
  io::write_tum_trajectory((out / "trajectory.txt").string(), trajectory, note);
  io::write_tum_trajectory((out / "trajectory_unsmoothed.txt").string(), unsmoothed, note);
  io::write_tum_trajectory((out / "trajectory_online.txt").string(), system.online_trajectory(),
                           note);
  io::write_file_atomic((out / "keyframes.txt").string(),
                        format_tum_keyframes(system.keyframe_trajectory()));
  io::write_file_atomic((out / "timings.csv").string(), recorder.timings_csv(request.realtime));

  nlohmann::json summary;
  summary["state"] = !failure.empty() ? "failed" : interrupted ? "interrupted" : "complete";
  if (!failure.empty()) summary["failure"] = failure;
  summary["sequence"] = source_path;
  summary["camera_source"] = config.camera_source;
  if (calibration && calibration->report.confident) {
    // The run used the calibration pass's estimate as a fixed value; the setting was auto.
    summary["readout"] = readout_json(calibration->report);
    slam::RunConfig as_given = config;
    as_given.camera.readout_auto = true;
    io::write_file_atomic((out / "config.yaml").string(),
                          slam::to_yaml(as_given, calibration->report));
  } else {
    summary["readout"] = readout_json(system.readout_report());
    io::write_file_atomic((out / "config.yaml").string(),
                          slam::to_yaml(config, system.readout_report()));
  }
  if (calibration) summary["readout"]["calibration"] = calibration_json(*calibration);
  summary["sequential"] = config.options.sequential;
  summary["frames"] = processed;
  summary["tracked_frames"] = recorder.tracked;
  summary["tracked_ratio"] =
      processed == 0 ? 0.0 : static_cast<double>(recorder.tracked) / processed;
  summary["lost_frames"] = recorder.lost;
  summary["not_initialized_frames"] =
      static_cast<int>(processed) - recorder.tracked - recorder.lost;
  summary["relocalisations"] = recorder.relocalised;
  {
    const SampleStats q = compute_stats(recorder.reloc_query_ms);
    summary["relocalisation"] = {
        {"attempts", recorder.reloc_attempts},  {"succeeded", recorder.relocalised},
        {"from_last_pose", recorder.recovered}, {"by_database", recorder.reloc_by_database},
        {"query_median_ms", q.median},          {"query_p95_ms", q.p95},
        {"events", recorder.reloc_events}};
  }
  summary["loops"] = loops_json(system.loop_statistics(), config.options.place);
  const slam::SolverStatistics solver = system.solver_statistics();
  summary["solver_failures"] = {{"pose", solver.pose_failures},
                                {"bundle_adjustment", solver.bundle_adjustment_failures},
                                {"full_ba", solver.full_ba_failures},
                                {"pose_graph", solver.pose_graph_failures}};
  summary["session"] = {{"loaded", request.load_session.value_or("")},
                        {"localize", config.options.localize},
                        {"saved", request.save_session.value_or("")}};
  summary["keyframes_inserted"] = recorder.keyframes_inserted;
  {
    auto lock = system.map().read_lock();
    summary["keyframes_in_map"] = system.map().num_keyframes();
    summary["points_in_map"] = system.map().num_points();
    summary["lines_in_map"] = system.map().num_lines();
    summary["planes_in_map"] = system.map().num_planes();
    if (request.save_map) {
      io::write_file_atomic((out / "map.ply").string(), map::map_to_ply(system.map()));
      io::write_file_atomic((out / "map.json").string(),
                            map::map_to_json(system.map()).dump(1) + "\n");
    }
  }
  if (system.occupancy() && failure.empty())
    summary["occupancy"] = write_occupancy_outputs(*system.occupancy(), out);
  summary["features"] = {{"points", config.options.use.points},
                         {"lines", config.options.use.lines},
                         {"planes", config.options.use.planes}};
  nlohmann::json per_frame = nlohmann::json::object();
  for (const auto& [name, samples] : recorder.counts) {
    const SampleStats st = compute_stats(samples);
    per_frame[name] = {{"median", st.median}, {"mean", st.mean}, {"max", st.max}};
  }
  summary["per_frame_counts"] = per_frame;
  {
    nlohmann::json d;
    d["source"] = detection_description.empty() ? "none (geometry only)" : detection_description;
    d["enabled"] = config.options.tracker.dynamics.enabled && !detection_description.empty();
    d["constraints"] = config.options.tracker.dynamics.constraints;
    d["frames_with_boxes"] = objects.frames_with_boxes;
    d["fresh_frames"] = objects.fresh_frames;
    d["fresh_ratio"] = objects.frames_with_boxes == 0
                           ? 0.0
                           : static_cast<double>(objects.fresh_frames) / objects.frames_with_boxes;
    d["median_age_frames"] = compute_stats(objects.detection_age).median;
    const SampleStats det = compute_stats(objects.detect_ms);
    d["detector_ms"] = {{"median", det.median}, {"p95", det.p95}, {"count", det.count}};
    d["object_frames"] = objects.object_states;  // box-frames per state
    // Boxes carried forward against the detector's next boxes (see ObjectOutputs).
    d["propagation"] = {{"enabled", config.options.tracker.dynamics.propagate_boxes},
                        {"measured", objects.propagation_iou.size()},
                        {"iou_median", compute_stats(objects.propagation_iou).median},
                        {"stale_iou_median", compute_stats(objects.stale_iou).median}};
    d["mover_frames"] = objects.mover_frames;  // frames where motion without a box was found
    // Every forward pass of a model, whichever frame used its boxes: the detector's actual rate.
    // (none for boxes from a file)
    const std::vector<double> passes_ms = system.detection_source()
                                              ? system.detection_source()->pass_times_ms()
                                              : std::vector<double>{};
    if (!passes_ms.empty()) {
      const SampleStats pass = compute_stats(passes_ms);
      d["detector_passes"] = passes_ms.size();
      d["detector_rate_hz"] = wall_s > 0.0 ? passes_ms.size() / wall_s : 0.0;
      d["detector_pass_ms"] = {{"median", pass.median}, {"p95", pass.p95}};
    }
    summary["dynamics"] = d;
    objects.commit();
  }
  if (request.realtime) {
    const std::vector<std::size_t> dropped = input.dropped();
    const SampleStats latency = compute_stats(recorder.latency_ms);
    summary["realtime"] = {
        {"enabled", true},
        {"frames_offered", offered},
        {"frames_processed", processed},
        {"frames_dropped", dropped.size()},
        {"processed_ratio", offered == 0 ? 0.0 : static_cast<double>(processed) / offered},
        // Tracked frames over the frames the camera delivered: dropped frames count as missing.
        {"coverage", offered == 0 ? 0.0 : static_cast<double>(recorder.tracked) / offered},
        {"latency_median_ms", latency.median},
        {"latency_p95_ms", latency.p95},
        {"latency_max_ms", latency.max}};
  }
  summary["wall_time_s"] = wall_s;
  // Time spent paused from the viewer does not count against the frame rate.
  const double running_s = wall_s - (control ? control->paused_ms() / 1000.0 : 0.0);
  summary["frames_per_second"] = running_s > 0 ? processed / running_s : 0.0;
  if (control) summary["controls"] = control->summary();
  if (viewer) summary["viewer"] = viewer->summary();
  const std::string viewer_failure = viewer ? viewer->failure() : std::string();
  if (!viewer_failure.empty()) summary["viewer_failure"] = viewer_failure;
  summary["peak_rss_mib"] = peak_rss_mib();
  nlohmann::json stages = nlohmann::json::object();
  for (const auto& name : recorder.stage_table.names) {
    // Stages that did not run on a frame count as 0 there only for the per-frame total.
    const SampleStats s = compute_stats(recorder.stage_samples[name]);
    stages[name] = {
        {"median_ms", s.median}, {"p95_ms", s.p95}, {"mean_ms", s.mean}, {"frames", s.count}};
  }
  const SampleStats track_stats = compute_stats(recorder.tracking_ms);
  stages["tracking_total"] = {{"median_ms", track_stats.median},
                              {"p95_ms", track_stats.p95},
                              {"mean_ms", track_stats.mean},
                              {"frames", track_stats.count}};
  const SampleStats load_stats = compute_stats(recorder.load_ms);
  stages["image_load"] = {{"median_ms", load_stats.median},
                          {"p95_ms", load_stats.p95},
                          {"mean_ms", load_stats.mean},
                          {"frames", load_stats.count}};
  if (!config.options.sequential) {
    std::map<std::string, std::vector<double>> mapper_samples;
    for (const auto& t : system.mapper_times())
      for (const auto& [name, ms] : t.stages) mapper_samples[name].push_back(ms);
    nlohmann::json mapper = nlohmann::json::object();
    for (const auto& [name, samples] : mapper_samples) {
      const SampleStats s = compute_stats(samples);
      mapper[name] = {{"median_ms", s.median}, {"p95_ms", s.p95}, {"keyframes", s.count}};
    }
    summary["mapper_stages"] = mapper;
  }
  summary["stages"] = stages;
  summary["warnings"] = warnings;
  summary["trajectory_smoothing"] = {
      {"applied", smoothing.applied},
      {"position_noise_m", smoothing.position_noise},
      {"segments", smoothing.segments},
      {"downweighted", smoothing.downweighted},
      {"rms_change_m", smoothing.rms_change},
      {"acceleration_density", config.options.trajectory.acceleration_density}};
  if (groundtruth && !trajectory.empty()) {
    try {
      const eval::EvalReport report = eval::evaluate(*groundtruth, trajectory);
      if (summary.contains("occupancy") && plan.passes == 1)
        score_synthetic_map(summary["occupancy"], source_path, trajectory, report.ate.T_gt_est,
                            *system.occupancy());
      summary["eval"] = eval::to_json(report);
      summary["ate_rmse_m"] = report.ate.translation.rmse;
      if (smoothing.applied)
        summary["trajectory_smoothing"]["unsmoothed_ate_rmse_m"] =
            eval::evaluate(*groundtruth, unsmoothed).ate.translation.rmse;
      const Trajectory online = system.online_trajectory();
      if (!online.empty())
        summary["online_ate_rmse_m"] = eval::evaluate(*groundtruth, online).ate.translation.rmse;
    } catch (const InputError& e) {
      summary["eval_error"] = e.what();
    }
  }
  if (plan.passes > 1) {
    summary["repeat"] = plan.passes;
    nlohmann::json pass_rows = nlohmann::json::array();
    for (std::size_t k = 0; k < passes->passes().size(); ++k) {
      const PassFigures& p = passes->passes()[k];
      const SampleStats t = compute_stats(p.tracking_ms);
      nlohmann::json row = {{"pass", k + 1},
                            {"frames", p.frames},
                            {"tracked_frames", p.tracked},
                            {"lost_frames", p.lost},
                            {"relocalisations", p.relocalised},
                            {"keyframes_inserted", p.keyframes_inserted},
                            {"tracking_median_ms", t.median},
                            {"tracking_p95_ms", t.p95},
                            {"frames_per_second", p.wall_s > 0 ? p.frames / p.wall_s : 0.0},
                            {"rss_end_mib", p.rss_end_mib},
                            {"keyframes_in_map", p.keyframes_in_map},
                            {"points_in_map", p.points_in_map},
                            {"lines_in_map", p.lines_in_map}};
      // Each pass's own ATE (its own alignment), from the final trajectory.
      const double begin = plan.first + k * plan.period - 0.5 * plan.gap;
      const double end = plan.last + k * plan.period + 0.5 * plan.gap;
      Trajectory part;
      for (const StampedPose& pose : trajectory)
        if (pose.timestamp >= begin && pose.timestamp < end) part.push_back(pose);
      if (groundtruth && !part.empty()) {
        try {
          row["ate_rmse_m"] = eval::evaluate(*groundtruth, part).ate.translation.rmse;
        } catch (const InputError&) {
        }
      }
      pass_rows.push_back(row);
    }
    summary["passes"] = pass_rows;
  }
  if (request.on_end) request.on_end(system, summary);
  io::write_file_atomic((out / "summary.json").string(), summary.dump(2) + "\n");
  if (!failure.empty()) {
    status.failed(failure);
    throw BackgroundThreadError(failure + "; the outputs of the " + std::to_string(processed) +
                                " frames before it are in " + out.string());
  }
  status.finished(interrupted, offered);
  if (!viewer_failure.empty())
    throw BackgroundThreadError(viewer_failure + " (SLAM went on without it; the outputs are in " +
                                out.string() + ")");
  return summary;
}

}  // namespace

nlohmann::json run_sequence(const RunRequest& request) {
  namespace fs = std::filesystem;
  if (request.repeat < 1) throw InputError("--repeat: must be at least 1");
  if (request.realtime && request.repeat > 1)
    throw InputError("--realtime: not with --repeat (a soak run plays frames as fast as it can)");
  if (request.live &&
      (request.realtime || request.repeat > 1 || request.max_frames > 0 || request.first_frame > 0))
    throw InputError(
        "a live stream runs without --realtime, --repeat, --max-frames and --first-frame");
  if (request.first_frame < 0) throw InputError("--first-frame: must be at least 0");
  std::shared_ptr<const io::FrameSource> source = request.source;
  if (!source && !request.live) {
    io::SequenceOptions seq_options;
    if (request.associations_path) seq_options.associations_file = *request.associations_path;
    source = io::FolderSource::open(request.sequence_dir, seq_options);
  }
  const std::string source_path = request.live
                                      ? request.live->describe()
                                      : fs::path(source->path()).lexically_normal().string();
  const std::vector<std::string> warnings =
      source ? source->warnings() : std::vector<std::string>{};
  for (const auto& warning : warnings) std::cerr << "mcslam: warning: " << warning << "\n";
  slam::RunConfig config = slam::resolve_run_config(
      source_path, request.config_path,
      request.live ? request.live->camera_hints() : source->camera_hints(), request.camera_preset);
  if (request.sequential) config.options.sequential = *request.sequential;
  if (request.vocabulary) config.options.place.vocabulary = *request.vocabulary;
  if (request.no_loop_closing) config.options.place.loop.enabled = false;
  if (request.localize && !request.load_session)
    throw InputError("--localize: give the map to localise in with --load-session FILE");
  config.options.localize = request.localize;
  if (request.features)
    apply_feature_list(*request.features, config.options.use.points, config.options.use.lines,
                       config.options.use.planes);
  // lines.detector auto: the region detector, offline and in real time (it costs what FLD did
  // and finds LSD's segments). config.yaml holds the effective values of the settings read as
  // auto.
  if (config.options.lines.detector == "auto") config.options.lines.detector = "region";
  config.options.planes.pixel_step = config.options.planes.effective_pixel_step();
  // system.extract_ahead auto: on where a frame the loop cannot take is lost (real time; a live
  // stream prepares its frames on the loop's thread, so there is nothing to overlap).
  if (config.options.extract_ahead == "auto")
    config.options.extract_ahead = request.realtime ? "true" : "false";
  io::ensure_directory(request.output_dir);
  const fs::path out(request.output_dir);
  io::write_file_atomic((out / "config.yaml").string(), slam::to_yaml(config));

  const std::vector<io::FrameEntry> entries =
      source ? source->frames() : std::vector<io::FrameEntry>{};
  if (request.first_frame > 0 && static_cast<std::size_t>(request.first_frame) >= entries.size())
    throw InputError(source_path + ": --first-frame " + std::to_string(request.first_frame) +
                     " is past the sequence's last frame (it has " +
                     std::to_string(entries.size()) + ")");
  const StreamPlan plan =
      plan_stream(entries, request.repeat, static_cast<std::size_t>(request.first_frame));
  // Ground truth is read before the run so that a broken file is reported at once.
  std::optional<Trajectory> groundtruth = source ? source->groundtruth() : std::nullopt;
  if (groundtruth) {
    if (is_bonn(source_path)) groundtruth = eval::bonn_marker_to_camera(*groundtruth);
    if (request.repeat > 1) groundtruth = repeat_groundtruth(*groundtruth, plan);
  }

  // OpenCV's thread pool is process-wide: the application sets it (SystemOptions).
  if (config.options.opencv_threads > 0) cv::setNumThreads(config.options.opencv_threads);
  if (request.no_dynamics) config.options.tracker.dynamics.enabled = false;
  if (request.no_constraints) config.options.tracker.dynamics.constraints = false;
  if (request.no_occupancy) config.options.occupancy_enabled = false;
  map::Session initial;  // the loaded session's map and dense map, or none
  if (request.load_session) initial = load_compatible_session(*request.load_session, config);
  std::unique_ptr<slam::DetectionSource> detection_source =
      make_detection_source(request, config.camera, config.options);
  if (!detection_source)
    std::cerr << "mcslam: warning: no --model or --detections given: running on geometry only, "
                 "without dynamic-object handling\n";
  if (request.save_overlays) io::ensure_directory((out / "overlays").string());

  std::size_t total = plan.frames.size();
  if (request.max_frames > 0) total = std::min(total, static_cast<std::size_t>(request.max_frames));
  RunStatus status((out / "status.json").string(), total);
  try {
    // camera.readout_time: auto on a recorded sequence: its start is tracked once to estimate the
    // readout, and the run starts from that estimate (slam/readout_calibration.hpp). Not in real
    // time (a live camera is not replayed) nor in a loaded map (made with a fixed readout).
    std::optional<slam::ReadoutCalibration> calibration;
    if (source && config.camera.readout_auto && !request.realtime && !initial.map &&
        config.options.readout.calibration_seconds > 0.0) {
      const auto frame = [&](std::size_t k) {
        const io::FrameEntry& entry = plan.frames[k];
        const io::RgbdImages raw = load_checked(*source, plan, k, config.camera);
        return slam::RecordedFrame{raw.rgb, raw.depth, entry.rgb_timestamp, entry.depth_timestamp};
      };
      calibration = slam::calibrate_readout(config.camera, config.options, total, frame);
      // A confident estimate is used as a fixed value from the first frame on. Going on
      // estimating (in epochs, as without the pass) and switching to each new estimate cost
      // more than it gave on freiburg1_rpy: the later estimates settle at +-26 ms where the
      // pass's +21.6 / -20.2 ms (forwards / played backwards) gave 0.0105 / 0.0107 m and the
      // switching run 0.0109 / 0.0854 m (a map made of frames compensated differently).
      if (calibration->report.confident) {
        config.camera.readout_time = calibration->readout_time;
        config.camera.readout_auto = false;
      }
      if (request.progress)
        std::cerr << "mcslam: readout time " << std::fixed << std::setprecision(1)
                  << 1e3 * calibration->readout_time << " ms to start from ("
                  << (calibration->report.confident ? "estimated" : "no confident estimate")
                  << " over the first " << calibration->frames << " frames in "
                  << std::setprecision(1) << calibration->wall_ms / 1e3 << " s)\n";
    }
    // The viewer listens before the run starts, so that a port in use is reported at once.
    std::optional<RunControl> control;
    std::unique_ptr<Viewer> viewer;
    if (request.viewer) {
      control.emplace(config.options.localize);
      viewer = std::make_unique<Viewer>(*request.viewer, *control, source_path, total, groundtruth);
      const std::string& bind = request.viewer->server.bind;
      if (bind != "127.0.0.1" && bind != "::1")
        std::cerr << "mcslam: warning: the viewer listens on " << bind
                  << ", not only on this machine: anyone who can reach it can watch and pause "
                     "the run (see docs/viewer.md for an SSH tunnel instead)\n";
      std::cerr << "mcslam: viewer at " << viewer->url() << "\n";
    }
    return run_frames(request, source_path, source.get(), warnings, plan, total, config,
                      std::move(detection_source), std::move(initial), groundtruth, calibration,
                      status, viewer.get(), control ? &*control : nullptr);
  } catch (const InputError& e) {
    status.failed(e.what());
    throw;
  }
}

std::string summary_text(const nlohmann::json& s) {
  std::ostringstream o;
  o << std::fixed;
  o << "frames " << s["frames"].get<int>() << ", tracked " << std::setprecision(1)
    << 100.0 * s["tracked_ratio"].get<double>() << "%, lost " << s["lost_frames"].get<int>()
    << ", relocalised " << s["relocalisations"].get<int>() << ", keyframes "
    << s["keyframes_in_map"].get<int>() << "\n";
  o << "map: " << s["points_in_map"].get<int>() << " points, " << s["lines_in_map"].get<int>()
    << " lines, " << s["planes_in_map"].get<int>() << " planes\n";
  o << "speed " << std::setprecision(1) << s["frames_per_second"].get<double>()
    << " fps; tracking median " << std::setprecision(1)
    << s["stages"]["tracking_total"]["median_ms"].get<double>() << " ms, p95 "
    << s["stages"]["tracking_total"]["p95_ms"].get<double>() << " ms; peak memory "
    << std::setprecision(0) << s["peak_rss_mib"].get<double>() << " MiB\n";
  if (s.contains("dynamics") && s["dynamics"]["frames_with_boxes"].get<int>() > 0) {
    const auto& d = s["dynamics"];
    o << "objects: " << d["source"].get<std::string>() << "; boxes on "
      << d["frames_with_boxes"].get<int>() << " frames (" << std::setprecision(0)
      << 100.0 * d["fresh_ratio"].get<double>() << "% fresh)";
    for (const auto& [state, n] : d["object_frames"].items())
      o << ", " << state << " " << n.get<int>();
    o << "\n";
  }
  if (s.contains("loops") && s["loops"]["enabled"].get<bool>()) {
    const auto& l = s["loops"];
    o << "loops: " << l["accepted"].get<int>() << " closed of " << l["detected"].get<int>()
      << " verified; detection median " << std::setprecision(2)
      << l["detection_median_ms"].get<double>() << " ms per keyframe\n";
  }
  if (s.contains("session") && !s["session"]["loaded"].get<std::string>().empty())
    o << "session: " << (s["session"]["localize"].get<bool>() ? "localised in " : "mapped on in ")
      << s["session"]["loaded"].get<std::string>() << "\n";
  if (s.value("state", "complete") == "interrupted") o << "interrupted: stopped on request\n";
  if (s.contains("passes") && !s["passes"].empty()) {
    o << "pass  frames  tracked  lost  reloc  tracking ms  fps    RSS MiB  keyframes  points"
      << (s["passes"].front().contains("ate_rmse_m") ? "  ATE m" : "") << "\n";
    for (const auto& p : s["passes"]) {
      char row[160];
      std::snprintf(row, sizeof(row), "%4d  %6d  %6.1f%%  %4d  %5d  %11.1f  %5.1f  %7.0f  %9d  %6d",
                    p["pass"].get<int>(), p["frames"].get<int>(),
                    100.0 * p["tracked_frames"].get<int>() / std::max(1, p["frames"].get<int>()),
                    p["lost_frames"].get<int>(), p["relocalisations"].get<int>(),
                    p["tracking_median_ms"].get<double>(), p["frames_per_second"].get<double>(),
                    p["rss_end_mib"].get<double>(), p["keyframes_in_map"].get<int>(),
                    p["points_in_map"].get<int>());
      o << row;
      if (p.contains("ate_rmse_m"))
        o << "  " << std::setprecision(4) << p["ate_rmse_m"].get<double>();
      o << "\n";
    }
  }
  if (s.contains("ate_rmse_m")) {
    o << "ATE RMSE " << std::setprecision(4) << s["ate_rmse_m"].get<double>() << " m over "
      << s["eval"]["matched"].get<int>() << " poses";
    const nlohmann::json smoothing = s.value("trajectory_smoothing", nlohmann::json::object());
    if (smoothing.contains("unsmoothed_ate_rmse_m"))
      o << " (unsmoothed " << smoothing["unsmoothed_ate_rmse_m"].get<double>() << " m)";
    o << "\n";
  } else if (s.contains("eval_error"))
    o << "no ATE: " << s["eval_error"].get<std::string>() << "\n";
  return o.str();
}

}  // namespace mcslam::app
