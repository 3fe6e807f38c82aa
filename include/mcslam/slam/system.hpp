#pragma once
// The SLAM system facade: feed RGB-D frames, read poses, the map and timings.
//
//   System system(camera, options);
//   for (...) { FrameResult r = system.process(rgb, depth_metres, timestamp); }
//   system.finish();
//   Trajectory t = system.trajectory();
//
// Threads. process(), finish(), save_session() and readout_report() are called from one thread
// (the caller's pipeline thread). prepare() may run on any thread alongside process().
// trajectory(), online_trajectory(), keyframe_trajectory(), mapper_times(), loop_statistics()
// and solver_statistics() may be called from any thread at any time. The map is read under
// map().read_lock(). process() copies what it keeps of the images it is given (the detector's
// thread gets its own copy), so a caller may reuse its buffers as soon as process() returns.
// The destructor stops the background threads without the final global bundle adjustment:
// call finish() for it.
//
// Failures. When a background thread (mapper, loop closer, detector) throws, it stops its own
// work and keeps the exception; the next process() or finish() throws BackgroundThreadError
// naming the thread and the exception. What was made until then stays readable (trajectory(),
// online_trajectory(), the map), so that a caller can write its outputs before it gives up.

#include <atomic>
#include <deque>
#include <memory>
#include <mutex>
#include <opencv2/core.hpp>
#include <optional>
#include <unordered_map>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/timing.hpp"
#include "mcslam/core/trajectory.hpp"
#include "mcslam/map/map.hpp"
#include "mcslam/mapping/worker.hpp"
#include "mcslam/slam/detection_source.hpp"
#include "mcslam/slam/loop_closer.hpp"
#include "mcslam/slam/options.hpp"
#include "mcslam/slam/readout.hpp"
#include "mcslam/slam/tracker.hpp"

namespace mcslam::io {
class Undistorter;
}

namespace mcslam::slam {

class FrameBuilder;
struct DetectedFeatures;
class LocalMapper;
class LoopCloser;

/// Optimisations whose solver found no usable solution (none of them was applied).
struct SolverStatistics {
  int pose_failures = 0;               ///< tracking's pose optimisations (the estimate failed)
  int bundle_adjustment_failures = 0;  ///< local and final global bundle adjustments
  int full_ba_failures = 0;            ///< the loop closer's full bundle adjustments
  int pose_graph_failures = 0;         ///< loop corrections whose pose graph had no solution
};

struct FrameResult {
  std::uint64_t frame_id = 0;
  double timestamp = 0.0;
  TrackingState state = TrackingState::kNotInitialized;
  bool relocalised = false;
  /// Set when the frame was lost and relocalisation was tried (how, and what it found).
  std::optional<RelocalisationInfo> relocalisation;
  bool keyframe = false;
  int features = 0;  // ORB points
  int lines = 0;     // line segments
  int planes = 0;    // planes
  int matches = 0;   // points
  int inliers = 0;
  int line_matches = 0;
  int line_inliers = 0;
  int plane_inliers = 0;
  std::optional<SE3> T_w_c;  // when tracked
  /// What the motion model made of the frame's own pose (tracker.pose_filter).
  optim::FilterOutcome online_pose = optim::FilterOutcome::kOff;
  /// With tracker.pose_filter.lag > 0: an earlier frame's pose, smoothed with the frames since
  /// (its own timestamp; the frame `lag` tracked frames back).
  std::optional<StampedPose> lagged;
  StageTimes times;  // what the caller waited for, per stage
  /// The frame's features (undistorted pixels) and what each one is, for overlays.
  std::shared_ptr<const features::FrameFeatures> frame_features;
  std::vector<FeatureLabel> point_labels;
  std::vector<FeatureLabel> line_labels;
  /// Objects with the decisions of Algorithms 1 and 2 (boxes in undistorted pixels).
  std::vector<ObjectReport> objects;
  bool detections_used = false;  // the frame had boxes (its own or an earlier frame's)
  bool detections_fresh = false;
  int detections_age = 0;           // frames between the detected image and this one
  std::optional<double> detect_ms;  // the forward pass that produced a fresh detection
  int constrained_point_residuals = 0;
  int constrained_line_residuals = 0;
  double dynamics_threshold = 0.0;  // epsilon_d used by Algorithm 1 (pixels)
  /// When a new detection arrived: mean IoU with it of the previous detection carried forward to
  /// its frame, and of the same boxes only grown (-1: not measured this frame).
  double propagation_iou = -1.0;
  double stale_iou = -1.0;
  int mover_regions = 0;      // moving regions found without a box
  int mover_points = 0;       // features they took out
  double readout_time = 0.0;  // the rolling-shutter readout the keypoints were compensated with
};

/// A frame's images as the pipeline takes them, made by System::prepare (which may run on
/// another thread while System::process works on the frame before).
struct PreparedImages {
  cv::Mat rgb;    ///< the raw colour (BGR) or grey image: for the detector and keyframe colours
  cv::Mat gray;   ///< undistorted grey image
  cv::Mat depth;  ///< undistorted depth, CV_32FC1 in metres
  double prepare_ms = 0.0;  ///< what prepare() took (grey conversion and undistortion)
  /// Empty when the frame is usable; otherwise why not (wrong size or type): it is then lost.
  std::string problem;
  /// The frame's motion-independent features when System::extract_features found them ahead
  /// (null: process() extracts them itself).
  std::shared_ptr<const DetectedFeatures> features;
};

class System {
 public:
  /// Throws InputError when the camera or the options are invalid, or the vocabulary file
  /// (options.place.vocabulary, when not "") cannot be read.
  /// `initial_map`, when given, is a map made earlier (a loaded session, built with the same
  /// camera, ORB settings and vocabulary: the caller checks): tracking starts by relocalising
  /// into it, then mapping goes on in it (or, with options.localize, it is only read).
  /// `initial_dense`: the session's dense map (map::Session::dense), rebuilt on the mapping
  /// thread and extended: with new keyframes, or with options.localize by a tracked view every
  /// occupancy.localize_view_period seconds, integrated but not stored (the sparse map does not
  /// move in localisation, so nothing is rebuilt; the memory stays the octree's).
  System(const PinholeCamera& camera, const SystemOptions& options,
         std::unique_ptr<map::Map> initial_map = nullptr,
         std::vector<mapping::KeyframeSamples> initial_dense = {});
  ~System();
  System(const System&) = delete;
  System& operator=(const System&) = delete;

  /// One frame: `rgb` is CV_8UC3 (BGR) or CV_8UC1, `depth` CV_32FC1 in metres (0 = missing),
  /// both raw (undistorted here when the camera has distortion) and of the camera's size.
  /// Never throws for image content; a frame of the wrong size or type is reported as lost.
  /// `depth_timestamp` is when the depth image was taken (default: with the colour image); the
  /// difference is compensated with the tracked motion when compensate_depth_time is on.
  FrameResult process(const cv::Mat& rgb, const cv::Mat& depth, double timestamp,
                      std::optional<double> depth_timestamp = std::nullopt);
  /// The same for images made by prepare(); its time is listed as the concurrent stage
  /// `prepare` (the frame did not wait for it), where process(rgb, depth, ...) lists the
  /// `undistort` stage it ran inline.
  FrameResult process(const PreparedImages& images, double timestamp,
                      std::optional<double> depth_timestamp = std::nullopt);

  /// Grey conversion and undistortion of one frame's raw images (see process()). Reads only
  /// what the constructor made, so it may run on any thread, alongside process(). Never throws
  /// for image content: a wrong size or type is reported in PreparedImages::problem.
  PreparedImages prepare(const cv::Mat& rgb, const cv::Mat& depth) const;

  /// Finds the frame's points, lines and planes now, into images.features, so that process()
  /// only finishes them with the camera's motion: a run calls it on its reader's thread, and the
  /// next frame's extraction overlaps the tracking of the frame before. It has its own
  /// extractors: one thread at a time may call it, alongside process(). Does nothing (process()
  /// then extracts) when images.problem is set, when options.extract_ahead is off, when the
  /// points depend on the frame before (orb.moving_density > 0), or while frames wait for
  /// their own boxes (the cold start): process() then extracts while the detector runs, where
  /// extracting ahead would add the extraction to the wait. Stage times: orb_extract,
  /// line_extract and plane_extract, listed by process() as concurrent (the frame did not wait
  /// for them).
  void extract_features(PreparedImages& images) const;
  /// False when extract_features() does nothing (extract_ahead off, or orb.moving_density > 0).
  bool can_extract_ahead() const;
  /// Whether extract_features() would extract the next frame now: can_extract_ahead(), and the
  /// frame will not wait for its own boxes. Any thread.
  bool extracts_ahead_now() const;

  /// Boxes for every later frame come from `source` (a model on its own thread, or a file);
  /// without one the system runs on geometry alone. With `wait`, each frame waits for its own
  /// detection (deterministic; the default in sequential mode).
  void set_detection_source(std::unique_ptr<DetectionSource> source, bool wait);
  const DetectionSource* detection_source() const { return detections_.get(); }

  /// The colour image as the features see it (undistorted), for drawing.
  cv::Mat undistort(const cv::Mat& rgb) const;

  /// Lets the mapper finish its queue. Call before reading the final trajectory. Throws
  /// BackgroundThreadError (after stopping the threads, without the final bundle adjustment)
  /// when a background thread has failed.
  void finish();
  /// The dense occupancy map (null with options.occupancy_enabled off): snapshots of the grid
  /// and the voxels from any thread; complete once finish() has returned.
  const mapping::MappingWorker* occupancy() const { return occupancy_.get(); }
  /// The first failure of a background thread, "" while none has failed. Any thread.
  std::string background_failure() const;
  /// Testing the failure path (`mcslam run --inject-failure THREAD:N`): "mapper" throws while
  /// processing keyframe N, "loop" when searching after N keyframes, "detector" at pass N.
  void inject_failure(const std::string& thread, std::int64_t at);

  /// Tracked frames, each placed relative to its reference keyframe's final (refined) pose,
  /// positions smoothed as options().trajectory says (optim::smooth_trajectory); `report`, when
  /// given, receives what the smoothing did.
  Trajectory trajectory(optim::TrajectorySmoothingReport* report = nullptr) const;
  /// The same poses before smoothing.
  Trajectory unsmoothed_trajectory() const;
  Trajectory keyframe_trajectory() const;
  /// Tracked frames at the poses tracking gave them at the time (what a robot saw online).
  Trajectory online_trajectory() const;
  /// The lagged poses (tracker.pose_filter.lag > 0; empty otherwise) as they were given out,
  /// and after finish() the last `lag` too.
  Trajectory lagged_trajectory() const;
  /// The map (read it under map().read_lock() while the system runs threaded).
  const map::Map& map() const { return *map_; }
  /// Stage times of each processed keyframe in the mapper.
  std::vector<StageTimes> mapper_times() const;
  /// Loops detected, accepted and rejected, and the loop closer's timings (empty without loop
  /// closing).
  LoopStatistics loop_statistics() const;
  /// Solver failures so far (see SolverStatistics).
  SolverStatistics solver_statistics() const;
  /// Writes the map as a session file (map/session.hpp), with the dense map's stored keyframes
  /// (after what is queued for it is integrated); call after finish(). Throws InputError.
  void save_session(const std::string& path) const;
  /// The vocabulary in use (null without one).
  const place::Vocabulary* vocabulary() const { return vocabulary_.get(); }
  const PinholeCamera& camera() const { return camera_; }
  /// The rolling-shutter readout time in use and, with camera.readout_time: auto, how it was
  /// estimated. Call from the thread that calls process().
  ReadoutReport readout_report() const;
  const SystemOptions& options() const { return options_; }
  /// Switches to localisation only (tracking inserts no keyframe, so the map is only read) or
  /// back to mapping, from the next frame on. Call from the thread that calls process().
  void set_localize(bool localize);

 private:
  /// The tracked frames relative to their reference keyframes; `after_loss`, when given,
  /// receives the indices of the poses that follow untracked frames.
  Trajectory corrected_trajectory(std::vector<std::size_t>* after_loss) const;
  struct FrameRecord {
    double timestamp = 0.0;
    bool tracked = false;
    map::KeyFrameId reference = map::kNoId;
    SE3 T_c_ref;
    SE3 T_c_w;  // at tracking time, used when the reference cannot be resolved
  };

  PinholeCamera camera_;
  SystemOptions options_;
  std::shared_ptr<const io::Undistorter> undistorter_;
  std::unique_ptr<FrameBuilder> builder_;
  std::unique_ptr<FrameBuilder> ahead_builder_;  // extract_features(), on the caller's thread
  std::unique_ptr<map::Map> map_;
  /// The dense map: declared before the mapper, whose thread feeds it, so that it goes after.
  std::unique_ptr<mapping::MappingWorker> occupancy_;
  std::unique_ptr<Tracker> tracker_;
  std::shared_ptr<const place::Vocabulary> vocabulary_;
  std::unique_ptr<LocalMapper> mapper_;
  std::unique_ptr<LoopCloser> loop_closer_;
  std::unique_ptr<DetectionSource> detections_;
  std::unique_ptr<ReadoutEstimator> readout_;  // with camera.readout_auto
  bool wait_for_detections_ = true;
  /// Whether the next frame will wait for its own boxes (process() publishes it for
  /// extract_features() on the reader's thread).
  std::atomic<bool> next_frame_waits_for_boxes_{false};
  /// Whether the next frame waits for its own boxes: a detection source, and waiting always
  /// (--wait-detections, sequential) or while the first map is built (cold start).
  bool frame_waits_for_boxes() const;
  mutable std::mutex records_mutex_;  // process() appends; the trajectory readers copy
  std::vector<FrameRecord> records_;
  Trajectory lagged_;                  // under records_mutex_
  std::atomic<int> pose_failures_{0};  // the tracker's count, published after each frame
  std::uint64_t next_frame_id_ = 0;
  /// What is known of the camera's motion around the frame (depth time, rolling shutter) and
  /// where moving objects are expected in it.
  FrameMotion frame_motion(double timestamp, std::optional<double> depth_timestamp) const;
  /// The frame's features: finished from images.features when extract_features() found them,
  /// extracted here otherwise.
  Frame build_frame(const PreparedImages& images, FrameResult& result,
                    const FrameMotion& motion) const;
  /// The frame's boxes from the detection source (its own when `wait`), into frame.objects and
  /// the result's detection fields.
  void attach_boxes(Frame& frame, bool wait, FrameResult& result) const;
  /// A tracked frame's inliers to the readout estimator (camera.readout_time: auto); a lost
  /// frame resets it.
  void observe_readout(const Frame& frame, const FrameMotion& motion,
                       const TrackingOutcome& outcome);
  /// The boxes of the last frame's moving objects (for the next frame's feature budget).
  void remember_moving_regions(const FrameResult& result);
  /// The tracker's outcome for the frame into its result (the objects moved out of `outcome`).
  void report_tracking(const Frame& frame, TrackingOutcome& outcome, FrameResult& result) const;
  /// A new keyframe to the mapper, with the colour and depth it keeps: processed inline with
  /// `sequential` (its stages timed into the result), queued for the mapper's thread otherwise.
  void hand_over_keyframe(KeyFrameRequest keyframe, const PreparedImages& images,
                          FrameResult& result);
  void add_record(const FrameRecord& record, const std::optional<StampedPose>& lagged = {});
  std::vector<FrameRecord> records() const;
  /// Lets the mapper and the loop closer finish their queues and stops their threads.
  void stop_threads();
  /// Feeds the dense map from the mapper's keyframes and corrections.
  void connect_occupancy();
  /// In localisation only: the tracked frame's depth to the dense map as a view that is
  /// integrated, not stored, at most every occupancy.localize_view_period seconds.
  void add_localize_view(const cv::Mat& depth, const FrameResult& result);
  std::optional<double> last_localize_view_;
  /// Each moving object's world box and velocity (ObjectReport::world_box, velocity).
  void place_moving_objects(const cv::Mat& depth, const SE3& T_w_c, FrameResult& result);
  /// Box centres (time, centre) of the moving objects' tracks over the last half second.
  std::unordered_map<int, std::deque<std::pair<double, Eigen::Vector3d>>> object_tracks_;
  /// Throws BackgroundThreadError when a background thread has failed.
  void throw_if_background_failed() const;
  std::vector<FrameMotion::MovingRegion> expected_moving_regions(double timestamp) const;

  std::vector<FrameMotion::MovingRegion> moving_regions_;
  double moving_regions_time_ = 0.0;
  bool started_in_map_ = false;  // a map made earlier was given (no cold start)
  int keyframes_made_ = 0;       // keyframes this System inserted
  bool finished_ = false;
};

}  // namespace mcslam::slam
