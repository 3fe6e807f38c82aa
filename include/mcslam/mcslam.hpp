#pragma once
// mcslam as a library: the one header a program includes. It pulls in Eigen, OpenCV's core and
// a few small mcslam headers (camera, SE3, trajectory, errors), not Ceres nor the tracker; the
// pipeline behind it is mcslam::slam::System (mcslam/slam/system.hpp), reachable for what this
// facade does not offer.
//
//   #include <mcslam/mcslam.hpp>
//   mcslam::Sequence sequence = mcslam::Sequence::open("rgbd_dataset_freiburg1_xyz");
//   mcslam::Settings settings = mcslam::Settings::for_sequence(sequence.directory());
//   mcslam::System system(settings);
//   for (std::size_t k = 0; k < sequence.size(); ++k) {
//     const mcslam::Sequence::Frame f = sequence.load(k, settings.camera().depth_factor);
//     const mcslam::FrameReport r = system.process(f.rgb, f.depth, f.timestamp);
//     if (r.T_w_c) std::cout << r.timestamp << " " << r.T_w_c->translation().transpose() << "\n";
//   }
//   system.finish();
//   mcslam::write_trajectory("trajectory.txt", system.trajectory());
//
// Errors in input (files, settings, images of the wrong size or type) throw mcslam::InputError
// whose message names the file or argument and the problem.

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/data_files.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/core/trajectory.hpp"
#include "mcslam/version.hpp"

namespace mcslam {

namespace slam {
class System;
}

/// The version of the linked library, e.g. "0.1.0" (MCSLAM_VERSION_STRING is the headers').
std::string version();

/// What tracking made of a frame.
enum class State { kNotInitialized, kOk, kLost };
/// "not_initialized", "ok" or "lost" (as in mcslam run's frames.csv).
const char* to_string(State state);

/// The camera and every option of a run, as `mcslam run` resolves them. Copyable.
class Settings {
 public:
  /// Default options and no camera (width 0): give one with set_camera() or load_file().
  Settings();
  ~Settings();
  Settings(const Settings& other);
  Settings& operator=(const Settings& other);
  Settings(Settings&&) noexcept;
  Settings& operator=(Settings&&) noexcept;

  /// A camera preset by name (tum_fr1, tum_fr2, tum_fr3, bonn) with default options.
  static Settings preset(const std::string& name);
  /// What `mcslam run DIR --config FILE` uses: the preset chosen by the folder's name, then
  /// DIR/camera.yaml, then `settings_file` (when not "").
  static Settings for_sequence(const std::string& sequence_dir,
                               const std::string& settings_file = "");

  /// A settings file (mcslam's keys, or ORB-SLAM2's) over these settings. Unknown keys, wrong
  /// types and invalid values throw InputError naming the file.
  void load_file(const std::string& path);
  /// The same for settings text, e.g. "orb.num_features: 1500\nsystem.sequential: true\n";
  /// `name` stands for the file name in messages.
  void load_yaml(const std::string& yaml, const std::string& name = "<settings>");

  const PinholeCamera& camera() const;
  void set_camera(const PinholeCamera& camera);
  /// Sequential: the mapper and loop closer run inline (deterministic); otherwise on threads.
  bool sequential() const;
  void set_sequential(bool sequential);
  /// The bag-of-words vocabulary file ("": none, then no loop closing).
  std::string vocabulary() const;
  void set_vocabulary(const std::string& path);
  void set_loop_closing(bool enabled);
  /// Object boxes from an ONNX detector (a YOLOv8/YOLO11 or YOLOX export; the models are not
  /// part of mcslam), `confidence` its threshold; or from a detections file (perception/
  /// detection.hpp). At most one of the two; "" removes it.
  void set_detector(const std::string& model_path, std::optional<double> confidence = {});
  void set_detections_file(const std::string& path);
  const std::string& detector_model() const;
  const std::string& detections_file() const;

  /// Every setting in mcslam's YAML keys (it loads back with load_yaml).
  std::string to_yaml() const;

  struct Data;
  const Data& data() const { return *d_; }

 private:
  std::unique_ptr<Data> d_;
};

/// One frame's outcome (mcslam::slam::FrameResult, abridged).
struct FrameReport {
  std::uint64_t frame_id = 0;
  double timestamp = 0.0;
  State state = State::kNotInitialized;
  bool keyframe = false;
  bool relocalised = false;
  std::optional<SE3> T_w_c;  ///< the camera's pose in the world when tracked
  /// With tracker.pose_filter.lag > 0: the pose of the frame `lag` tracked frames back,
  /// smoothed with the frames since, and that frame's timestamp.
  std::optional<StampedPose> lagged;
  int features = 0, lines = 0, planes = 0;  ///< extracted
  int matches = 0, inliers = 0;             ///< points
  int objects = 0, dynamic_objects = 0;     ///< boxes this frame, and those found moving
  int dynamic_points = 0;                   ///< features taken out as moving
  double tracking_ms = 0.0;
};

/// The map's landmarks in the world frame, sorted by id.
struct MapSnapshot {
  std::vector<Eigen::Vector3d> points;
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> lines;  ///< segment endpoints
  std::vector<Eigen::Vector4d> planes;                             ///< n_x n_y n_z d, |n| = 1
  Trajectory keyframes;
};

/// The 2D occupancy grid of the floor (nav_msgs/OccupancyGrid's convention): cells row-major,
/// row 0 the lowest y, -1 unknown, 0 free, 100 occupied; a cell's lower-left corner is at
/// (col, row) * resolution in the grid frame, p_world = T_world_grid * p_grid.
struct OccupancyGridSnapshot {
  int width = 0, height = 0;
  double resolution = 0.05;
  Eigen::Matrix4d T_world_grid = Eigen::Matrix4d::Identity();
  std::vector<std::int8_t> cells;
};

/// The SLAM system: feed RGB-D frames, read poses and the map.
class System {
 public:
  /// Throws InputError for an invalid camera or options, an unreadable vocabulary or detector.
  explicit System(const Settings& settings);
  ~System();
  System(const System&) = delete;
  System& operator=(const System&) = delete;

  /// One frame: `rgb` CV_8UC3 (BGR) or CV_8UC1; `depth` CV_32FC1 in metres or CV_16UC1 in the
  /// camera's raw units (divided by camera().depth_factor), 0 = missing; both of the camera's
  /// size. Throws InputError for images of another size or type; never for their content.
  /// The images are not kept: the caller may reuse its buffers as soon as it returns.
  FrameReport process(const cv::Mat& rgb, const cv::Mat& depth, double timestamp,
                      std::optional<double> depth_timestamp = std::nullopt);
  /// Lets the mapper finish its queue, then adjusts the whole map (the final global bundle
  /// adjustment); call before reading the final trajectory or map. The destructor only stops
  /// the background threads.
  void finish();

  /// Tracked frames at their final (refined) poses, positions smoothed with a motion prior
  /// (setting trajectory.smoothing; optim::smooth_trajectory).
  Trajectory trajectory() const;
  /// The same poses before smoothing.
  Trajectory unsmoothed_trajectory() const;
  Trajectory keyframe_trajectory() const;
  /// Tracked frames at the poses tracking gave them at the time.
  Trajectory online_trajectory() const;
  /// The lagged poses as they were given out (FrameReport::lagged), the last `lag` after
  /// finish(); empty without tracker.pose_filter.lag.
  Trajectory lagged_trajectory() const;
  MapSnapshot map() const;
  /// The dense map (docs/mapping.md): the floor grid and the occupied voxels' centres (world
  /// frame), as integrated so far (complete after finish()); empty with mapping.enabled off.
  OccupancyGridSnapshot grid() const;
  std::vector<Eigen::Vector3d> occupied_voxels() const;
  /// The map as a session file (`mcslam run --load-session` reads it); after finish().
  void save_session(const std::string& path) const;
  const Settings& settings() const { return settings_; }

  /// The pipeline itself (include mcslam/slam/system.hpp to use it).
  slam::System& pipeline() { return *system_; }
  const slam::System& pipeline() const { return *system_; }

 private:
  Settings settings_;
  std::unique_ptr<slam::System> system_;
};

/// A TUM-layout RGB-D folder (rgb.txt, depth.txt, optional groundtruth.txt and camera.yaml).
class Sequence {
 public:
  /// Throws InputError naming the folder or file when it cannot be read. `associations`: a TUM
  /// associate.py output to pair the images with instead of matching timestamps.
  static Sequence open(const std::string& directory, const std::string& associations = "");

  struct Frame {
    cv::Mat rgb;    ///< CV_8UC3, BGR
    cv::Mat depth;  ///< CV_32FC1, metres
    double timestamp = 0.0, depth_timestamp = 0.0;
  };
  const std::string& directory() const;
  std::size_t size() const;
  double timestamp(std::size_t index) const;
  /// Frame `index`, its depth divided by `depth_factor` (raw units per metre).
  Frame load(std::size_t index, double depth_factor) const;
  /// Ground truth from groundtruth.txt, when there is one.
  std::optional<Trajectory> groundtruth() const;
  std::vector<std::string> warnings() const;

  struct Data;

 private:
  std::shared_ptr<const Data> d_;
};

/// Accuracy of `estimate` against `groundtruth` (as `mcslam eval`): ATE after a rigid
/// alignment, RPE over one frame and over one second.
struct Evaluation {
  double ate_rmse_m = 0.0, ate_mean_m = 0.0, ate_median_m = 0.0, ate_max_m = 0.0;
  double rpe_frame_trans_rmse_m = 0.0, rpe_frame_rot_rmse_deg = 0.0;
  double rpe_1s_trans_rmse_m = 0.0, rpe_1s_rot_rmse_deg = 0.0;
  std::size_t matched = 0, estimate_poses = 0, groundtruth_poses = 0;
  SE3 T_gt_est;      ///< the alignment applied to the estimate
  std::string text;  ///< a short table
  std::string json;  ///< every number (mcslam eval --json)
};
/// Throws InputError when no pose associates (within max_time_difference seconds).
Evaluation evaluate(const Trajectory& groundtruth, const Trajectory& estimate,
                    double max_time_difference = 0.02);

/// TUM trajectory files ("timestamp tx ty tz qx qy qz qw" per line). Throw InputError.
Trajectory read_trajectory(const std::string& path);
void write_trajectory(const std::string& path, const Trajectory& trajectory);

namespace detail {
// The installed CMake package and mcslam.pc define MCSLAM_PACKAGE_DATA_DIR (their prefix's
// share/mcslam, wherever the prefix has been moved): a program that includes this header looks
// there for the default vocabulary (see data_file_candidates in core/data_files.hpp).
#ifdef MCSLAM_PACKAGE_DATA_DIR
inline const bool package_data_dir_set = (set_data_dir_hint(MCSLAM_PACKAGE_DATA_DIR), true);
#endif
}  // namespace detail

}  // namespace mcslam
