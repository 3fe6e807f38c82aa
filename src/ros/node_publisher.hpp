#pragma once
// What the ROS node publishes of each frame and of the dense map (private to the ros module; no
// ROS types: it talks to the Transport).

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>
#include <vector>

#include "mcslam/core/timing.hpp"
#include "mcslam/ros/node_options.hpp"
#include "transport.hpp"

namespace mcslam::mapping {
class MappingWorker;
}  // namespace mcslam::mapping
namespace mcslam::slam {
class System;
struct FrameResult;
struct PreparedImages;
}  // namespace mcslam::slam

namespace mcslam::ros::detail {

/// The grid (with its tf map -> floor) and the occupied voxels, from a thread of its own: taking
/// the map's snapshot waits for the map's lock, which the mapping thread holds while it
/// integrates a keyframe, and then builds the grid and the voxel list (20-130 ms measured on Bonn
/// crowd, 25 000 voxels, on the shared 2-core machine); the frame's path must not wait for that.
/// Each is published at most once per its period (grid_period_s, cloud_period_s) and only when
/// the map's version changed since the last one.
class MapPublisher {
 public:
  MapPublisher(Transport& transport, const NodeOptions& options);
  ~MapPublisher();
  MapPublisher(const MapPublisher&) = delete;
  MapPublisher& operator=(const MapPublisher&) = delete;

  /// From the frame's thread, per frame (cheap): the map to publish from (null: none, the map
  /// is disabled) and the frame's stamp for the messages. The map must stay valid until detach().
  void update(const mapping::MappingWorker* worker, double timestamp);
  /// Stops reading the map: returns once a publication in progress is over. Then the thread
  /// publishes nothing more.
  void detach();
  /// After detach(), on the caller's thread: the map when it changed since the last one sent.
  void publish_final(const mapping::MappingWorker& worker);
  /// Adds its figures to the summary's "ros" section (after detach()).
  void report(nlohmann::json& ros) const;

 private:
  void loop();
  /// Publishes what is due; whether it published anything.
  bool publish(const mapping::MappingWorker& worker, double timestamp, bool final);

  Transport& transport_;
  const NodeOptions& options_;
  std::mutex mutex_;  ///< guards worker_, timestamp_ and stop_
  std::condition_variable wake_;
  const mapping::MappingWorker* worker_ = nullptr;
  double timestamp_ = 0.0;
  bool stop_ = false;
  /// Held while the map is read and published: detach() waits for it. The members below are
  /// used under it (by the thread, or after detach() by the caller).
  std::mutex publishing_;
  Stopwatch grid_watch_, voxel_watch_;
  std::optional<std::uint64_t> grid_version_, voxel_version_;
  std::size_t grids_ = 0, voxel_clouds_ = 0;
  std::vector<double> publish_ms_;
  std::thread thread_;  ///< last: started when the rest is ready
};

/// Everything the node publishes, driven by the run's callbacks (RunRequest::on_frame, on_end,
/// on_detach), on the run's thread except the map (MapPublisher).
class FramePublisher {
 public:
  FramePublisher(Transport& transport, const NodeOptions& options);

  void on_frame(const slam::FrameResult& r, const slam::PreparedImages& images,
                const slam::System& system);
  /// The final map (when it changed since the last one published), and the "ros" section of the
  /// summary; the failed odom lookups, if any, on stderr.
  void on_end(const slam::System& system, nlohmann::json& summary);
  void on_detach() { map_.detach(); }

 private:
  void publish_pose(double timestamp, const SE3& T_w_c);
  void publish_people(const slam::FrameResult& r);

  Transport& transport_;
  const NodeOptions& options_;
  Stopwatch cloud_watch_, path_watch_, warn_watch_;
  bool cloud_sent_ = false;
  bool people_shown_ = false;
  std::size_t poses_ = 0, lagged_poses_ = 0, odom_failures_ = 0, people_arrays_ = 0;
  MapPublisher map_;
};

}  // namespace mcslam::ros::detail
