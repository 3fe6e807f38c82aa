#pragma once
// `mcslam run`: a whole sequence through the SLAM system, with its outputs on disk.

#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "mcslam/app/viewer.hpp"
#include "mcslam/io/frame_source.hpp"
#include "mcslam/slam/system.hpp"

namespace mcslam::app {

/// One frame of a live stream (a camera or the ROS node's topics).
struct LiveFrame {
  cv::Mat rgb;    ///< CV_8UC3 BGR
  cv::Mat depth;  ///< CV_32FC1, metres
  double rgb_timestamp = 0.0;
  double depth_timestamp = 0.0;
  std::size_t dropped_before = 0;  ///< frames the source dropped since the one before
};

/// A stream of frames whose number is not known ahead. next() blocks until a frame arrives and
/// returns nullopt when the stream ends (the run then writes its outputs as for a sequence).
class LiveSource {
 public:
  virtual ~LiveSource() = default;
  virtual std::optional<LiveFrame> next() = 0;
  /// A name for summary.json and messages, e.g. "ros:/camera/rgb/image_color".
  virtual std::string describe() const = 0;
  virtual io::CameraHints camera_hints() const { return {}; }
};

struct RunRequest {
  /// A TUM-layout folder; ignored when `source` or `live` is set.
  std::string sequence_dir;
  /// Frames from elsewhere (e.g. a ROS bag, ros::BagSource) instead of sequence_dir.
  std::shared_ptr<const io::FrameSource> source;
  /// A live stream instead (the ROS node); not with repeat > 1, realtime or max_frames.
  std::shared_ptr<LiveSource> live;
  /// Called on the run's thread after each frame with its result and images (the ROS node
  /// publishes from here).
  std::function<void(const slam::FrameResult&, const slam::PreparedImages&, slam::System&)>
      on_frame;
  /// Called on the run's thread once, after the last frame and System::finish() (its maps are
  /// complete), with the summary before summary.json is written; also after a failure
  /// (summary["state"] says "failed"). The ROS node publishes its final map and adds its "ros"
  /// section here.
  std::function<void(slam::System&, nlohmann::json& summary)> on_end;
  /// Called on the run's thread on every way out of the run (also when it ends with an
  /// exception), before the System is destroyed; must not throw. Code that reads the System from
  /// threads of its own (the ROS node's map publisher) lets go of it here.
  std::function<void()> on_detach;
  /// The camera preset by name (--camera-preset: tum_fr1, tum_fr2, tum_fr3, bonn) instead of the
  /// one chosen by the folder or file name.
  std::optional<std::string> camera_preset;
  std::string output_dir;
  std::optional<std::string> config_path;
  std::optional<std::string> associations_path;
  /// Overrides system.sequential when set.
  std::optional<bool> sequential;
  /// Process at most this many frames (0: all).
  int max_frames = 0;
  /// Start at this frame of the sequence (0: the first), as if the recording began there: the
  /// run, its ground truth scoring and its outputs cover frames first_frame onwards.
  int first_frame = 0;
  /// Progress bar on stderr.
  bool progress = false;
  /// Also write map.ply and map.json (see map/export.hpp).
  bool save_map = false;
  /// Feature kinds to use, overriding the configuration: a comma-separated subset of
  /// "points,lines,planes".
  std::optional<std::string> features;
  /// Object boxes: an ONNX detector model (YOLOv8/YOLO11 or YOLOX export), or a detections file
  /// (perception/detection.hpp); at most one. Without either, geometry only (one warning).
  std::optional<std::string> model;
  std::optional<std::string> detections;
  /// Detector confidence threshold (default: DetectorOptions).
  std::optional<double> confidence;
  /// Each frame waits for its own detection (default: only in sequential mode).
  bool wait_for_detections = false;
  /// Turn Algorithm 1 / Algorithm 2 off while keeping the boxes (for ablations).
  bool no_dynamics = false;
  bool no_constraints = false;
  /// No dense occupancy map (mapping.enabled false): no occupancy.bt, grid.* files.
  bool no_occupancy = false;
  /// The bag-of-words vocabulary (overrides place.vocabulary); loop closing off (loop.enabled).
  std::optional<std::string> vocabulary;
  bool no_loop_closing = false;
  /// Write the map as a session file at the end (--save-session); start from one
  /// (--load-session: same camera, ORB settings and vocabulary), only reading it (--localize).
  std::optional<std::string> save_session;
  std::optional<std::string> load_session;
  bool localize = false;
  /// Testing the failure path: "THREAD:N" makes a background thread throw (System::inject_failure;
  /// the run then ends with BackgroundThreadError after writing its outputs so far).
  std::optional<std::string> inject_failure;
  /// Also write overlays/<frame>.jpg: annotated frames as in the paper's Fig. 7.
  bool save_overlays = false;
  /// Play the sequence this many times in a row as one stream (a soak run): pass k's timestamps
  /// (and its ground truth) are shifted by k sequence lengths, so the camera jumps back to the
  /// start at each pass. The summary gets per-pass figures (speed, memory, map size, ATE).
  int repeat = 1;
  /// Deliver frames at their timestamps, as a live camera would (--realtime): a reader thread
  /// releases each frame at its time and the run takes the newest, dropping what it could not
  /// take in time. Dropped frames, latency (frame time to pose) and the detector's actual rate
  /// go into timings.csv and summary.json (`realtime`). Not with repeat > 1.
  bool realtime = false;
  /// Asked between frames; when it returns true the run stops early, writes every output for the
  /// frames processed so far and marks them interrupted (Ctrl-C in the command-line app).
  std::function<bool()> stop_requested;
  /// Serve the live viewer (--viewer [PORT], --viewer-bind ADDR): the current frame with its
  /// overlay, the 3D map, live figures, pause/resume and localisation only (app/viewer.hpp).
  /// summary.json then has "viewer" and "controls" (pauses, the localisation switches).
  std::optional<ViewerOptions> viewer;
};

/// Annotates an (undistorted) colour image as in the paper's Fig. 7: static points green, lines
/// red, dynamic boxes red (their features grey), constrained boxes and their points yellow,
/// static boxes white; class, score and state labels.
void draw_overlay(cv::Mat& bgr, const slam::FrameResult& result);

/// Parses a --features list ("points,lines,planes" or a subset); throws InputError naming the
/// unknown kind.
void apply_feature_list(const std::string& list, bool& points, bool& lines, bool& planes);

/// Runs the sequence and writes into output_dir: trajectory.txt, trajectory_online.txt,
/// keyframes.txt, timings.csv, summary.json, config.yaml; with boxes objects.json (per frame:
/// each object's box, track, state and the figures behind Algorithms 1 and 2); with save_map
/// map.ply and map.json; with save_overlays overlays/. Returns the summary. Throws InputError
/// for bad input.
///
/// Every file is replaced atomically (write, fsync, rename), so a crash or a kill never leaves a
/// torn file. status.json says how far the run got: {"state": "running"} with the frames done,
/// rewritten every few seconds together with a partial trajectory_online.txt (its first line
/// says "# partial: ..."); "complete", "interrupted" (stop_requested) or "failed" (with the
/// error) at the end. Files of an earlier run in the same folder are replaced only when this run
/// writes them.
nlohmann::json run_sequence(const RunRequest& request);

/// One line per figure a person wants to see after a run.
std::string summary_text(const nlohmann::json& summary);

}  // namespace mcslam::app
