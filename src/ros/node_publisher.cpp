#include "node_publisher.hpp"

#include <chrono>
#include <iomanip>
#include <iostream>
#include <memory>
#include <string>

#include "mcslam/app/run.hpp"
#include "mcslam/mapping/worker.hpp"
#include "mcslam/slam/system.hpp"
#include "node_messages.hpp"

namespace mcslam::ros::detail {
namespace {

std::vector<CloudPoint> map_points(const map::Map& map) {
  std::vector<CloudPoint> points;
  auto lock = map.read_lock();
  points.reserve(map.points().size());
  for (const auto& [id, point] : map.points())
    points.push_back({static_cast<float>(point.p_w.x()), static_cast<float>(point.p_w.y()),
                      static_cast<float>(point.p_w.z()), point.color});
  return points;
}

}  // namespace

MapPublisher::MapPublisher(Transport& transport, const NodeOptions& options)
    : transport_(transport), options_(options), thread_([this] { loop(); }) {}

MapPublisher::~MapPublisher() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
    worker_ = nullptr;
  }
  wake_.notify_all();
  thread_.join();
}

void MapPublisher::update(const mapping::MappingWorker* worker, double timestamp) {
  std::lock_guard lock(mutex_);
  if (stop_) return;
  worker_ = worker;
  timestamp_ = timestamp;
}

void MapPublisher::detach() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
    worker_ = nullptr;
  }
  wake_.notify_all();
  std::lock_guard wait_for_publication(publishing_);
}

void MapPublisher::loop() {
  // Checked ten times a second: a publication is late by at most 0.1 s on its period.
  constexpr auto kTick = std::chrono::milliseconds(100);
  std::unique_lock lock(mutex_);
  while (!stop_) {
    wake_.wait_for(lock, kTick, [this] { return stop_; });
    if (stop_ || !worker_) continue;
    const mapping::MappingWorker* worker = worker_;
    const double timestamp = timestamp_;
    // Taken before the state's lock is let go: detach() clears worker_, then waits for this.
    std::lock_guard publishing(publishing_);
    lock.unlock();
    const Stopwatch watch;
    if (publish(*worker, timestamp, false)) publish_ms_.push_back(watch.elapsed_ms());
    lock.lock();
  }
}

void MapPublisher::publish_final(const mapping::MappingWorker& worker) {
  double timestamp = 0.0;
  {
    std::lock_guard lock(mutex_);
    timestamp = timestamp_;
  }
  std::lock_guard publishing(publishing_);
  publish(worker, timestamp, true);
}

bool MapPublisher::publish(const mapping::MappingWorker& worker, double timestamp, bool final) {
  const bool grid_due =
      final || !grid_version_ || grid_watch_.elapsed_ms() >= 1000.0 * options_.grid_period_s;
  const bool voxels_due =
      final || !voxel_version_ || voxel_watch_.elapsed_ms() >= 1000.0 * options_.cloud_period_s;
  if (!grid_due && !voxels_due) return false;
  const std::shared_ptr<const mapping::OccupancySnapshot> snapshot = worker.snapshot();
  if (snapshot->version == 0) return false;  // nothing integrated yet
  const mapping::OccupancyGrid& grid = snapshot->grid;
  bool published = false;
  if (grid_due && grid_version_ != snapshot->version && grid.width > 0 && grid.height > 0) {
    transport_.publish_grid(timestamp, grid_message(grid));
    grid_version_ = snapshot->version;
    grid_watch_.restart();
    ++grids_;
    published = true;
  }
  if (voxels_due && voxel_version_ != snapshot->version) {
    transport_.publish_cloud(Transport::Cloud::kOccupiedVoxels, timestamp,
                             voxel_points(snapshot->voxels));
    voxel_version_ = snapshot->version;
    voxel_watch_.restart();
    ++voxel_clouds_;
    published = true;
  }
  return published;
}

void MapPublisher::report(nlohmann::json& ros) const {
  ros["grids_published"] = grids_;
  ros["voxel_clouds_published"] = voxel_clouds_;
  // What the map thread spent on each publication (snapshot, conversion, publishing).
  const SampleStats cost = compute_stats(publish_ms_);
  ros["map_publish_ms"] = {{"median", cost.median}, {"max", cost.max}};
}

FramePublisher::FramePublisher(Transport& transport, const NodeOptions& options)
    : transport_(transport), options_(options), map_(transport, options) {}

void FramePublisher::on_frame(const slam::FrameResult& r, const slam::PreparedImages& images,
                              const slam::System& system) {
  map_.update(system.occupancy(), r.timestamp);
  if (r.lagged) {
    transport_.publish_lagged_pose(r.lagged->timestamp, r.lagged->T_w_c);
    ++lagged_poses_;
  }
  if (r.T_w_c) {
    publish_pose(r.timestamp, *r.T_w_c);
    if (path_watch_.elapsed_ms() > 200.0) {
      transport_.publish_path();
      path_watch_.restart();
    }
  }
  if (transport_.image_wanted()) {
    cv::Mat overlay = system.undistort(images.rgb);
    if (overlay.channels() == 3) {
      overlay = overlay.clone();
      app::draw_overlay(overlay, r);
      transport_.publish_image(r.timestamp, overlay);
    }
  }
  if (!cloud_sent_ || cloud_watch_.elapsed_ms() > 1000.0 * options_.cloud_period_s) {
    transport_.publish_cloud(Transport::Cloud::kMapPoints, r.timestamp, map_points(system.map()));
    cloud_watch_.restart();
    cloud_sent_ = true;
  }
  publish_people(r);
}

void FramePublisher::on_end(const slam::System& system, nlohmann::json& summary) {
  map_.detach();
  if (system.occupancy() && summary.value("state", "") != "failed")
    map_.publish_final(*system.occupancy());
  nlohmann::json ros = {{"map_frame", options_.map_frame},
                        {"camera_frame", options_.camera_frame},
                        {"floor_frame", options_.floor_frame},
                        {"odom_frame", options_.odom_frame},
                        {"poses_published", poses_},
                        {"lagged_poses_published", lagged_poses_},
                        {"odom_lookup_failures", odom_failures_},
                        {"people_arrays_published", people_arrays_}};
  map_.report(ros);
  summary["ros"] = ros;
  if (odom_failures_ > 0)
    std::cerr << "mcslam ros: " << odom_failures_ << " of " << poses_ << " poses had no tf "
              << options_.odom_frame << " -> " << options_.camera_frame << ": no "
              << options_.map_frame << " -> " << options_.odom_frame
              << " was sent for them (summary.json \"ros\")\n";
}

void FramePublisher::publish_pose(double timestamp, const SE3& T_w_c) {
  ++poses_;
  const std::string failure = transport_.publish_pose(timestamp, T_w_c);
  if (failure.empty()) return;
  ++odom_failures_;
  if (odom_failures_ > 1 && warn_watch_.elapsed_ms() < 1000.0) return;  // at most once a second
  std::cerr << "mcslam ros: warning: no tf " << options_.odom_frame << " -> "
            << options_.camera_frame << " at " << std::fixed << std::setprecision(6) << timestamp
            << std::defaultfloat << " (" << failure << "): no " << options_.map_frame << " -> "
            << options_.odom_frame << " sent (" << odom_failures_ << " so far)\n";
  warn_watch_.restart();
}

void FramePublisher::publish_people(const slam::FrameResult& r) {
  // While someone listens; after the last frame that had moving objects, one array with only
  // the DELETEALL, so that they disappear.
  if (!transport_.people_wanted()) return;
  const std::vector<MarkerSpec> markers = people_markers(r.objects);
  if (markers.empty() && !people_shown_) return;
  transport_.publish_people(r.timestamp, markers);
  people_shown_ = !markers.empty();
  ++people_arrays_;
}

}  // namespace mcslam::ros::detail
