#pragma once
// The live viewer of `mcslam run --viewer` / `mcslam ros --viewer`: a page in the browser with
// the current frame and its overlay, the 3D map, live figures and the run's controls.
//
// The frame loop hands each frame to Viewer::on_frame, which only copies what it needs (at most
// frame_hz times a second) and returns; the viewer's own thread draws the overlay, encodes the
// JPEG, reads the map and the occupancy map's snapshot (at most map_hz times a second) and
// serialises; the server's thread sends (newest wins, see viewer_server.hpp). Nothing on the frame
// loop's thread waits for a client.

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "mcslam/app/frame_observer.hpp"
#include "mcslam/app/run_control.hpp"
#include "mcslam/app/viewer_server.hpp"
#include "mcslam/core/thread_failure.hpp"
#include "mcslam/core/timing.hpp"
#include "mcslam/io/trajectory_io.hpp"

namespace mcslam::mapping {
struct OccupancySnapshot;
}  // namespace mcslam::mapping

namespace mcslam::app {

struct ViewerOptions {
  ViewerServerOptions server;
  double frame_hz = 10.0;  ///< frames sent at most this often (JPEG)
  double stats_hz = 5.0;   ///< live figures
  double map_hz = 2.0;     ///< map snapshots
  int jpeg_quality = 75;
  std::size_t max_map_points = 60000;        ///< more are thinned evenly
  std::size_t max_trajectory_points = 8000;  ///< likewise
  std::size_t max_voxels = 100000;           ///< occupied voxels sent; likewise
  std::optional<std::string> check() const;
};

/// The occupancy message (binary): bytes 0-3 the type (3) and padding, a uint32 at byte 4 the
/// length of a JSON header {"version", "width", "height", "resolution", "voxels",
/// "voxels_in_map", "floor_estimated"}, the header, then, each from a 4-byte boundary and
/// little-endian: T_world_grid (16 float32, column-major), the grid's cells (int8, row-major, row
/// 0 the lowest y), the voxels' centres (3 float32 each), their edges (float32) and their colours
/// (3 uint8 each). More than `max_voxels` voxels are thinned evenly (0: all). Exposed for tests.
std::string occupancy_message(const mapping::OccupancySnapshot& snapshot, std::size_t max_voxels);

class Viewer : public FrameObserver {
 public:
  /// Starts the server (InputError when it cannot listen, or the page's scripts are missing)
  /// and the viewer's thread. `total`: frames of the run (0: unknown, live).
  Viewer(const ViewerOptions& options, RunControl& control, std::string sequence, std::size_t total,
         const std::optional<Trajectory>& groundtruth);
  ~Viewer() override;
  Viewer(const Viewer&) = delete;
  Viewer& operator=(const Viewer&) = delete;

  int port() const { return server_->port(); }
  std::string url() const;
  void on_frame(const FrameEvent& event) override;
  /// Sends the last figures and map; the viewer no longer reads the System afterwards.
  void on_stream_end(slam::System& system) override;
  /// The viewer no longer reads the System (call before the System goes, also on an error).
  void detach();
  /// summary.json "viewer".
  nlohmann::json summary() const;
  /// The failure of the viewer's thread or its server's ("" while both run): the viewer then
  /// shows nothing more, the run goes on.
  std::string failure() const;

 private:
  struct PendingFrame {
    slam::FrameResult result;
    cv::Mat rgb;
  };
  /// A moving object's box in the world frame (the newest frame's).
  struct ObjectBox {
    Eigen::Vector3d min, max;
    bool constrained = false;
    std::string class_name;
    int track_id = -1;
  };
  void loop();
  void loop_guarded();
  void on_message(const std::string& text);
  std::string stats_json();                       // under mutex_
  std::string map_message(slam::System& system);  // under system_mutex_
  void send_frame(const PendingFrame& frame, const slam::System& system);
  /// The occupancy message when the snapshot's version changed since the last one sent.
  void send_occupancy(const slam::System& system);  // under system_mutex_
  /// The hello message; the ground truth placed in the map's frame by the first tracked pose
  /// (the pose of the ground truth nearest in time mapped onto it), raw until then.
  std::string hello_json() const;

  ViewerOptions options_;
  RunControl& control_;
  std::unique_ptr<ViewerServer> server_;

  mutable std::mutex mutex_;  // what on_frame writes and the thread reads
  std::condition_variable wake_;
  bool stop_ = false;
  bool finished_ = false;
  bool urgent_stats_ = false;
  std::optional<PendingFrame> pending_;
  std::size_t total_ = 0, done_ = 0;
  std::uint64_t frame_id_ = 0;
  double timestamp_ = 0.0;
  std::string state_ = "waiting";
  std::vector<double> tracking_ms_;  // newest last, at most kRecent
  std::vector<double> frame_s_;      // wall times of the last frames (the live rate)
  /// (wall time, the detector's passes so far) over the last few seconds: its rate.
  std::vector<std::pair<double, std::size_t>> detector_passes_;
  int box_age_ = -1, objects_ = 0, dynamic_objects_ = 0, constrained_objects_ = 0;
  std::vector<ObjectBox> object_boxes_;
  std::size_t keyframes_ = 0;
  std::vector<float> trajectory_;  // x, y, z of each tracked frame
  std::optional<SE3> pose_;
  std::string sequence_;
  Trajectory groundtruth_;
  std::optional<StampedPose> anchor_;  // the first tracked pose (for the ground truth)
  bool hello_aligned_ = false;         // the viewer's thread only
  Stopwatch wall_;
  double last_handoff_s_ = -1.0;
  std::size_t map_points_ = 0;
  std::atomic<std::size_t> frames_sent_{0}, maps_sent_{0};  // by the viewer's thread
  std::atomic<std::size_t> occupancy_sent_{0};
  bool system_known_ = false;  // the frame loop's thread only

  // Guards system_ (the thread reads the maps through it) and occupancy_version_.
  std::mutex system_mutex_;
  slam::System* system_ = nullptr;
  std::uint64_t occupancy_version_ = 0;  // of the last occupancy message sent (0: none)
  ThreadFailure failure_{"viewer (mcslam-viewer)"};
  std::thread thread_;
};

}  // namespace mcslam::app
