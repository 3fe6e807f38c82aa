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
#include "run_summary.hpp"

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

/// Everything run_sequence prepares for the frame loop.
struct PreparedRun {
  std::string source_path;
  std::shared_ptr<const io::FrameSource> source;  // null for a live stream
  std::vector<std::string> warnings;
  slam::RunConfig config;
  StreamPlan plan;
  std::size_t total = 0;  // frames to play (--max-frames)
  std::optional<Trajectory> groundtruth;
  map::Session initial;  // the loaded session's map and dense map, or none
  std::unique_ptr<slam::DetectionSource> detection_source;
  std::optional<slam::ReadoutCalibration> calibration;
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

/// The System's source of boxes, with its description for the summary ("" for none).
std::string attach_detection_source(slam::System& system, const RunRequest& request,
                                    std::unique_ptr<slam::DetectionSource> detection_source) {
  if (!detection_source) return std::string();
  std::string description = detection_source->describe();
  system.set_detection_source(std::move(detection_source), request.wait_for_detections);
  return description;
}

/// The viewer reads the System from its own thread: it lets go before the System goes, also
/// when the run ends with an error.
struct DetachViewer {
  Viewer* viewer;
  ~DetachViewer() {
    if (viewer) viewer->detach();
  }
};

/// So do the callbacks' own threads (the ROS node's map publisher): RunRequest::on_detach.
struct DetachCallbacks {
  const std::function<void()>& detach;
  ~DetachCallbacks() {
    if (detach) detach();
  }
};

/// The observers of each frame's result; `list` has them in the order they see it.
struct RunObservers {
  RunObservers(const RunRequest& request, const std::filesystem::path& out,
               const slam::System& system, const StreamPlan& plan, std::size_t total,
               RunStatus& status, Viewer* viewer)
      : objects(system.detection_source()
                    ? std::optional<std::string>((out / "objects.json").string())
                    : std::nullopt),
        overlays(request.save_overlays
                     ? std::optional<OverlayWriter>(std::in_place, out / "overlays")
                     : std::nullopt),
        callback(request.on_frame ? std::optional<CallbackObserver>(std::in_place, request.on_frame)
                                  : std::nullopt),
        passes(plan.passes > 1 ? std::optional<PassRecorder>(std::in_place, recorder,
                                                             plan.frames_per_pass, total)
                               : std::nullopt),
        checkpoints(out, status, request.live != nullptr, total),
        progress(request.progress ? std::optional<ProgressObserver>(std::in_place, total, recorder)
                                  : std::nullopt) {
    list = {&recorder, &objects};
    if (overlays) list.push_back(&*overlays);
    if (callback) list.push_back(&*callback);
    if (passes) list.push_back(&*passes);
    list.push_back(&checkpoints);
    if (progress) list.push_back(&*progress);
    if (viewer) list.push_back(viewer);
  }

  FrameRecorder recorder;
  ObjectsRecorder objects;
  std::optional<OverlayWriter> overlays;
  std::optional<CallbackObserver> callback;
  std::optional<PassRecorder> passes;
  Checkpointer checkpoints;
  std::optional<ProgressObserver> progress;
  std::vector<FrameObserver*> list;
};

/// How a run ended: the frame loop's outcome, what failed (the loop or the System's finish),
/// and the wall time of both.
struct RunEnd {
  Streamed streamed;
  std::string failure;
  double wall_s = 0.0;
};

/// Plays the stream, finishes the System and saves the session (not of a failed run's map).
RunEnd play_stream(const RunRequest& request, FrameInput& input, slam::System& system,
                   RunObservers& observers, RunControl* control, Viewer* viewer,
                   const Stopwatch& wall) {
  RunEnd end;
  end.streamed = stream_frames(request, input, system, observers.list, control, viewer);
  end.failure = end.streamed.failure;
  if (end.failure.empty()) {
    try {
      system.finish();
    } catch (const std::exception& e) {
      end.failure = e.what();
    }
  }
  end.wall_s = wall.elapsed_ms() / 1000.0;
  // A failed thread may have left the map half-changed: no session is made of it.
  if (request.save_session && end.failure.empty()) system.save_session(*request.save_session);
  return end;
}

/// The trajectory files' first line when the run stopped early ("" when it did not).
std::string end_note(const RunEnd& end, std::size_t total) {
  const std::string at = std::to_string(end.streamed.offered) + " of " + std::to_string(total);
  if (!end.failure.empty()) return "failed after frame " + at + ": " + end.failure;
  if (end.streamed.interrupted) return "interrupted after frame " + at + " (stopped on request)";
  return std::string();
}

/// The final and the unsmoothed trajectory of a run, and how the smoothing went.
struct RunTrajectories {
  Trajectory final_poses, unsmoothed;
  optim::TrajectorySmoothingReport smoothing;
};

/// trajectory.txt, trajectory_unsmoothed.txt, trajectory_online.txt, trajectory_lagged.txt
/// (with a lag), keyframes.txt, timings.csv.
RunTrajectories write_trajectories(const std::filesystem::path& out, const slam::System& system,
                                   const std::string& note, const FrameRecorder& recorder,
                                   bool realtime) {
  RunTrajectories t;
  t.final_poses = system.trajectory(&t.smoothing);
  t.unsmoothed = system.unsmoothed_trajectory();
  io::write_tum_trajectory((out / "trajectory.txt").string(), t.final_poses, note);
  io::write_tum_trajectory((out / "trajectory_unsmoothed.txt").string(), t.unsmoothed, note);
  io::write_tum_trajectory((out / "trajectory_online.txt").string(), system.online_trajectory(),
                           note);
  if (system.options().tracker.pose_filter.lag > 0)
    io::write_tum_trajectory((out / "trajectory_lagged.txt").string(), system.lagged_trajectory(),
                             note);
  io::write_file_atomic((out / "keyframes.txt").string(),
                        format_tum_keyframes(system.keyframe_trajectory()));
  io::write_file_atomic((out / "timings.csv").string(), recorder.timings_csv(realtime));
  return t;
}

/// The readout time used (summary "readout") and config.yaml with the settings as resolved.
void write_readout(nlohmann::json& summary, const std::filesystem::path& out,
                   const slam::RunConfig& config,
                   const std::optional<slam::ReadoutCalibration>& calibration,
                   const slam::System& system) {
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
}

/// The map's size (summary) and, with --save-map, map.ply and map.json, read under the map's lock.
void write_map(nlohmann::json& summary, const std::filesystem::path& out,
               const slam::System& system, bool save_map) {
  auto lock = system.map().read_lock();
  summary["keyframes_in_map"] = system.map().num_keyframes();
  summary["points_in_map"] = system.map().num_points();
  summary["lines_in_map"] = system.map().num_lines();
  summary["planes_in_map"] = system.map().num_planes();
  if (save_map) {
    io::write_file_atomic((out / "map.ply").string(), map::map_to_ply(system.map()));
    io::write_file_atomic((out / "map.json").string(),
                          map::map_to_json(system.map()).dump(1) + "\n");
  }
}

/// How the run went and what it made: state, settings, tracking, loops and the map; writes
/// config.yaml, the map files and the occupancy outputs on the way.
nlohmann::json summary_of_run(const RunRequest& request, const PreparedRun& run,
                              const slam::System& system, const RunEnd& end,
                              const FrameRecorder& recorder) {
  const std::filesystem::path out(request.output_dir);
  const slam::RunConfig& config = run.config;
  nlohmann::json summary;
  summary["state"] = !end.failure.empty()       ? "failed"
                     : end.streamed.interrupted ? "interrupted"
                                                : "complete";
  if (!end.failure.empty()) summary["failure"] = end.failure;
  summary["sequence"] = run.source_path;
  summary["camera_source"] = config.camera_source;
  write_readout(summary, out, config, run.calibration, system);
  summary["sequential"] = config.options.sequential;
  add_tracking_figures(summary, recorder, end.streamed.done);
  summary["loops"] = loops_json(system.loop_statistics(), config.options.place);
  summary["solver_failures"] = solver_failures_json(system.solver_statistics());
  summary["session"] = {{"loaded", request.load_session.value_or("")},
                        {"localize", config.options.localize},
                        {"saved", request.save_session.value_or("")}};
  summary["keyframes_inserted"] = recorder.keyframes_inserted;
  write_map(summary, out, system, request.save_map);
  if (system.occupancy() && end.failure.empty())
    summary["occupancy"] = write_occupancy_outputs(*system.occupancy(), out);
  summary["features"] = {{"points", config.options.use.points},
                         {"lines", config.options.use.lines},
                         {"planes", config.options.use.planes}};
  summary["per_frame_counts"] = per_frame_counts_json(recorder);
  return summary;
}

/// Speed, memory, the viewer and stage times (summary.json); `viewer_failure` is the viewer's
/// failure ("" for none).
void add_speed(nlohmann::json& summary, const RunEnd& end, const FrameRecorder& recorder,
               const slam::System& system, bool sequential, const RunControl* control,
               const Viewer* viewer, const std::string& viewer_failure) {
  summary["wall_time_s"] = end.wall_s;
  // Time spent paused from the viewer does not count against the frame rate.
  const double running_s = end.wall_s - (control ? control->paused_ms() / 1000.0 : 0.0);
  summary["frames_per_second"] = running_s > 0 ? end.streamed.done / running_s : 0.0;
  if (control) summary["controls"] = control->summary();
  if (viewer) summary["viewer"] = viewer->summary();
  if (!viewer_failure.empty()) summary["viewer_failure"] = viewer_failure;
  summary["peak_rss_mib"] = peak_rss_mib();
  if (!sequential) summary["mapper_stages"] = mapper_stages_json(system);
  summary["stages"] = stages_json(recorder);
}

/// The trajectories against the ground truth (summary "eval", "ate_rmse_m", ...) and, on a
/// synthetic sequence, the dense map against the scene.
void add_eval(nlohmann::json& summary, const PreparedRun& run, const slam::System& system,
              const RunTrajectories& t) {
  if (!run.groundtruth || t.final_poses.empty()) return;
  try {
    const eval::EvalReport report = eval::evaluate(*run.groundtruth, t.final_poses);
    if (summary.contains("occupancy") && run.plan.passes == 1)
      score_synthetic_map(summary["occupancy"], run.source_path, t.final_poses, report.ate.T_gt_est,
                          *system.occupancy());
    summary["eval"] = eval::to_json(report);
    summary["ate_rmse_m"] = report.ate.translation.rmse;
    if (t.smoothing.applied)
      summary["trajectory_smoothing"]["unsmoothed_ate_rmse_m"] =
          eval::evaluate(*run.groundtruth, t.unsmoothed).ate.translation.rmse;
    const Trajectory online = system.online_trajectory();
    if (!online.empty())
      summary["online_ate_rmse_m"] = eval::evaluate(*run.groundtruth, online).ate.translation.rmse;
    const Trajectory lagged = system.lagged_trajectory();
    if (!lagged.empty())
      summary["lagged_ate_rmse_m"] = eval::evaluate(*run.groundtruth, lagged).ate.translation.rmse;
  } catch (const InputError& e) {
    summary["eval_error"] = e.what();
  }
}

/// One pass of a --repeat run: its figures and its own ATE (its own alignment) from the final
/// trajectory.
nlohmann::json pass_json(const PassFigures& p, std::size_t k, const PreparedRun& run,
                         const Trajectory& trajectory) {
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
  const StreamPlan& plan = run.plan;
  const double begin = plan.first + k * plan.period - 0.5 * plan.gap;
  const double end = plan.last + k * plan.period + 0.5 * plan.gap;
  Trajectory part;
  for (const StampedPose& pose : trajectory)
    if (pose.timestamp >= begin && pose.timestamp < end) part.push_back(pose);
  if (run.groundtruth && !part.empty()) {
    try {
      row["ate_rmse_m"] = eval::evaluate(*run.groundtruth, part).ate.translation.rmse;
    } catch (const InputError&) {
    }
  }
  return row;
}

/// Hands the summary to the caller, writes summary.json and status.json, and throws what
/// stopped the run (a failure, then the viewer's).
void finish_run(const RunRequest& request, slam::System& system, nlohmann::json& summary,
                const RunEnd& end, RunStatus& status, const std::string& viewer_failure) {
  const std::filesystem::path out(request.output_dir);
  if (request.on_end) request.on_end(system, summary);
  io::write_file_atomic((out / "summary.json").string(), summary.dump(2) + "\n");
  if (!end.failure.empty()) {
    status.failed(end.failure);
    throw BackgroundThreadError(end.failure + "; the outputs of the " +
                                std::to_string(end.streamed.done) + " frames before it are in " +
                                out.string());
  }
  status.finished(end.streamed.interrupted, end.streamed.offered);
  if (!viewer_failure.empty())
    throw BackgroundThreadError(viewer_failure + " (SLAM went on without it; the outputs are in " +
                                out.string() + ")");
}

/// Runs the System over the prepared stream and writes every output; summary.json's content.
nlohmann::json run_frames(const RunRequest& request, PreparedRun& run, RunStatus& status,
                          Viewer* viewer, RunControl* control) {
  slam::System system(run.config.camera, run.config.options, std::move(run.initial.map),
                      std::move(run.initial.dense));
  const std::string detection_description =
      attach_detection_source(system, request, std::move(run.detection_source));
  if (request.inject_failure) inject_failure(system, *request.inject_failure);
  const DetachViewer detach_viewer{viewer};
  const DetachCallbacks detach_callbacks{request.on_detach};
  RunObservers observers(request, request.output_dir, system, run.plan, run.total, status, viewer);

  const Stopwatch wall;
  FrameInput input(request, run.source.get(), run.plan, run.total, system, run.config.camera);
  const RunEnd end = play_stream(request, input, system, observers, control, viewer, wall);
  const RunTrajectories trajectories = write_trajectories(
      request.output_dir, system, end_note(end, run.total), observers.recorder, request.realtime);

  nlohmann::json summary = summary_of_run(request, run, system, end, observers.recorder);
  summary["dynamics"] =
      dynamics_json(observers.objects, system, run.config, detection_description, end.wall_s);
  observers.objects.commit();
  if (request.realtime)
    summary["realtime"] = realtime_json(observers.recorder, end.streamed.offered, end.streamed.done,
                                        input.dropped().size());
  if (const int lag = run.config.options.tracker.pose_filter.lag; lag > 0)
    summary["lagged_pose"] =
        lagged_pose_json(observers.recorder, lag, system.lagged_trajectory().size());
  const std::string viewer_failure = viewer ? viewer->failure() : std::string();
  add_speed(summary, end, observers.recorder, system, run.config.options.sequential, control,
            viewer, viewer_failure);
  summary["warnings"] = run.warnings;
  summary["trajectory_smoothing"] = {
      {"applied", trajectories.smoothing.applied},
      {"position_noise_m", trajectories.smoothing.position_noise},
      {"segments", trajectories.smoothing.segments},
      {"downweighted", trajectories.smoothing.downweighted},
      {"rms_change_m", trajectories.smoothing.rms_change},
      {"acceleration_density", run.config.options.trajectory.acceleration_density}};
  add_eval(summary, run, system, trajectories);
  if (run.plan.passes > 1) {
    summary["repeat"] = run.plan.passes;
    nlohmann::json rows = nlohmann::json::array();
    for (std::size_t k = 0; k < observers.passes->passes().size(); ++k)
      rows.push_back(pass_json(observers.passes->passes()[k], k, run, trajectories.final_poses));
    summary["passes"] = rows;
  }
  finish_run(request, system, summary, end, status, viewer_failure);
  return summary;
}

/// The checks of a request that need no file.
void check_request(const RunRequest& request) {
  if (request.repeat < 1) throw InputError("--repeat: must be at least 1");
  if (request.realtime && request.repeat > 1)
    throw InputError("--realtime: not with --repeat (a soak run plays frames as fast as it can)");
  if (request.live &&
      (request.realtime || request.repeat > 1 || request.max_frames > 0 || request.first_frame > 0))
    throw InputError(
        "a live stream runs without --realtime, --repeat, --max-frames and --first-frame");
  if (request.first_frame < 0) throw InputError("--first-frame: must be at least 0");
}

/// The run's settings: the sequence's (or --config's) with the request's overrides and the
/// effective values of the settings read as auto.
slam::RunConfig resolve_config(const RunRequest& request, const std::string& source_path,
                               const io::FrameSource* source) {
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
  return config;
}

/// The frames to play (from --first-frame, --repeat times) and their ground truth.
void plan_frames(const RunRequest& request, PreparedRun& run) {
  const std::vector<io::FrameEntry> entries =
      run.source ? run.source->frames() : std::vector<io::FrameEntry>{};
  if (request.first_frame > 0 && static_cast<std::size_t>(request.first_frame) >= entries.size())
    throw InputError(run.source_path + ": --first-frame " + std::to_string(request.first_frame) +
                     " is past the sequence's last frame (it has " +
                     std::to_string(entries.size()) + ")");
  run.plan = plan_stream(entries, request.repeat, static_cast<std::size_t>(request.first_frame));
  // Ground truth is read before the run so that a broken file is reported at once.
  run.groundtruth = run.source ? run.source->groundtruth() : std::nullopt;
  if (run.groundtruth) {
    if (is_bonn(run.source_path)) run.groundtruth = eval::bonn_marker_to_camera(*run.groundtruth);
    if (request.repeat > 1) run.groundtruth = repeat_groundtruth(*run.groundtruth, run.plan);
  }
  run.total = run.plan.frames.size();
  if (request.max_frames > 0)
    run.total = std::min(run.total, static_cast<std::size_t>(request.max_frames));
}

/// The ablations of the request, the loaded session's map and the source of boxes.
void prepare_map_and_boxes(const RunRequest& request, PreparedRun& run) {
  slam::RunConfig& config = run.config;
  // OpenCV's thread pool is process-wide: the application sets it (SystemOptions).
  if (config.options.opencv_threads > 0) cv::setNumThreads(config.options.opencv_threads);
  if (request.no_dynamics) config.options.tracker.dynamics.enabled = false;
  if (request.no_constraints) config.options.tracker.dynamics.constraints = false;
  if (request.no_occupancy) config.options.occupancy_enabled = false;
  // A recorded sequence without a viewer or a frame callback (the ROS node's) reads its map
  // only at the end, and the final bundle adjustment rebuilds it from the keyframes anyway:
  // they are integrated once, at the end. A run that localises integrates its views as they
  // come (they are not stored).
  std::string& integration = config.options.occupancy.integration;
  if (integration == "auto") {
    const bool watched = request.viewer || request.on_frame || request.live;
    integration = watched || config.options.localize ? "live" : "at_end";
  }
  if (request.load_session) run.initial = load_compatible_session(*request.load_session, config);
  run.detection_source = make_detection_source(request, config.camera, config.options);
  if (!run.detection_source)
    std::cerr << "mcslam: warning: no --model or --detections given: running on geometry only, "
                 "without dynamic-object handling\n";
}

/// camera.readout_time: auto on a recorded sequence: its start is tracked once to estimate the
/// readout, and the run starts from that estimate (slam/readout_calibration.hpp). Not in real
/// time (a live camera is not replayed) nor in a loaded map (made with a fixed readout).
void run_readout_calibration(const RunRequest& request, PreparedRun& run) {
  slam::RunConfig& config = run.config;
  const bool wanted = run.source && config.camera.readout_auto && !request.realtime &&
                      !run.initial.map && config.options.readout.calibration_seconds > 0.0;
  if (!wanted) return;
  const auto frame = [&](std::size_t k) {
    const io::FrameEntry& entry = run.plan.frames[k];
    const io::RgbdImages raw = load_checked(*run.source, run.plan, k, config.camera);
    return slam::RecordedFrame{raw.rgb, raw.depth, entry.rgb_timestamp, entry.depth_timestamp};
  };
  run.calibration = slam::calibrate_readout(config.camera, config.options, run.total, frame);
  const slam::ReadoutCalibration& calibration = *run.calibration;
  // A confident estimate is used as a fixed value from the first frame on. Going on
  // estimating (in epochs, as without the pass) and switching to each new estimate cost
  // more than it gave on freiburg1_rpy: the later estimates settle at +-26 ms where the
  // pass's +21.6 / -20.2 ms (forwards / played backwards) gave 0.0105 / 0.0107 m and the
  // switching run 0.0109 / 0.0854 m (a map made of frames compensated differently).
  if (calibration.report.confident) {
    config.camera.readout_time = calibration.readout_time;
    config.camera.readout_auto = false;
  }
  if (request.progress)
    std::cerr << "mcslam: readout time " << std::fixed << std::setprecision(1)
              << 1e3 * calibration.readout_time << " ms to start from ("
              << (calibration.report.confident ? "estimated" : "no confident estimate")
              << " over the first " << calibration.frames << " frames in " << std::setprecision(1)
              << calibration.wall_ms / 1e3 << " s)\n";
}

/// The live viewer with --viewer, listening before the run starts so that a port in use is
/// reported at once; null without.
std::unique_ptr<Viewer> start_viewer(const RunRequest& request, const PreparedRun& run,
                                     std::optional<RunControl>& control) {
  if (!request.viewer) return nullptr;
  control.emplace(run.config.options.localize);
  auto viewer = std::make_unique<Viewer>(*request.viewer, *control, run.source_path, run.total,
                                         run.groundtruth);
  const std::string& bind = request.viewer->server.bind;
  if (bind != "127.0.0.1" && bind != "::1")
    std::cerr << "mcslam: warning: the viewer listens on " << bind
              << ", not only on this machine: anyone who can reach it can watch and pause "
                 "the run (see docs/viewer.md for an SSH tunnel instead)\n";
  std::cerr << "mcslam: viewer at " << viewer->url() << "\n";
  return viewer;
}

}  // namespace

nlohmann::json run_sequence(const RunRequest& request) {
  namespace fs = std::filesystem;
  check_request(request);
  PreparedRun run;
  run.source = request.source;
  if (!run.source && !request.live) {
    io::SequenceOptions seq_options;
    if (request.associations_path) seq_options.associations_file = *request.associations_path;
    run.source = io::FolderSource::open(request.sequence_dir, seq_options);
  }
  run.source_path = request.live ? request.live->describe()
                                 : fs::path(run.source->path()).lexically_normal().string();
  run.warnings = run.source ? run.source->warnings() : std::vector<std::string>{};
  for (const auto& warning : run.warnings) std::cerr << "mcslam: warning: " << warning << "\n";
  run.config = resolve_config(request, run.source_path, run.source.get());
  io::ensure_directory(request.output_dir);
  const fs::path out(request.output_dir);
  io::write_file_atomic((out / "config.yaml").string(), slam::to_yaml(run.config));
  plan_frames(request, run);
  prepare_map_and_boxes(request, run);
  if (request.save_overlays) io::ensure_directory((out / "overlays").string());

  RunStatus status((out / "status.json").string(), run.total);
  try {
    run_readout_calibration(request, run);
    std::optional<RunControl> control;
    const std::unique_ptr<Viewer> viewer = start_viewer(request, run, control);
    return run_frames(request, run, status, viewer.get(), control ? &*control : nullptr);
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
