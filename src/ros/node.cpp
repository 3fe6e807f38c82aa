#include "mcslam/ros/node.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

#include "mcslam/core/error.hpp"
#include "mcslam/core/timing.hpp"
#include "mcslam/mapping/worker.hpp"
#include "transport.hpp"

namespace mcslam::ros {
namespace {

/// The synchronised colour + depth pairs, handed from the ROS callback thread to the run.
class TopicSource : public app::LiveSource {
 public:
  explicit TopicSource(const NodeOptions& options) : options_(options) {}

  void push(app::LiveFrame frame) {
    {
      std::lock_guard lock(mutex_);
      if (closed_) return;
      if (!options_.keep_all) {
        pending_dropped_ += queue_.size();
        queue_.clear();
      } else if (queue_.size() >= options_.max_queue) {
        queue_.pop_front();
        ++pending_dropped_;
      }
      queue_.push_back(std::move(frame));
    }
    changed_.notify_all();
  }
  void set_intrinsics(const io::CameraHints::Intrinsics& k, const std::string& name) {
    std::lock_guard lock(mutex_);
    if (hints_.intrinsics) return;
    hints_.intrinsics = k;
    hints_.intrinsics_name = name;
  }
  bool have_intrinsics() const {
    std::lock_guard lock(mutex_);
    return hints_.intrinsics.has_value();
  }
  /// Ends the stream. On request (no error) next() returns nullopt at once; after an error the
  /// frames received before it are processed first.
  void close(const std::string& error = {}) {
    {
      std::lock_guard lock(mutex_);
      closed_ = true;
      if (error_.empty() && !error.empty()) {
        error_ = error;
        drain_ = true;
      }
    }
    changed_.notify_all();
  }
  std::string error() const {
    std::lock_guard lock(mutex_);
    return error_;
  }

  std::optional<app::LiveFrame> next() override {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [this] { return closed_ || !queue_.empty(); });
    if (queue_.empty() || (closed_ && !drain_)) return std::nullopt;
    app::LiveFrame frame = std::move(queue_.front());
    queue_.pop_front();
    frame.dropped_before = pending_dropped_;
    pending_dropped_ = 0;
    return frame;
  }
  std::string describe() const override { return "ros:" + options_.topics.rgb; }
  io::CameraHints camera_hints() const override {
    std::lock_guard lock(mutex_);
    return hints_;
  }

 private:
  NodeOptions options_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<app::LiveFrame> queue_;
  std::size_t pending_dropped_ = 0;
  bool closed_ = false;
  bool drain_ = false;
  std::string error_;
  io::CameraHints hints_;
};

std::vector<detail::CloudPoint> map_points(const map::Map& map) {
  std::vector<detail::CloudPoint> points;
  auto lock = map.read_lock();
  points.reserve(map.points().size());
  for (const auto& [id, point] : map.points())
    points.push_back({static_cast<float>(point.p_w.x()), static_cast<float>(point.p_w.y()),
                      static_cast<float>(point.p_w.z()), point.color});
  return points;
}

/// What the node publishes of each frame and at the end of the run, on the run's thread. The
/// frame's path stays cheap: the dense map's snapshot is taken only when its grid or voxels are
/// due (MappingWorker builds a snapshot once per map version), and converted into messages only
/// when its version changed since the last one published.
class FramePublisher {
 public:
  FramePublisher(detail::Transport& transport, const NodeOptions& options)
      : transport_(transport), options_(options) {}

  void on_frame(const slam::FrameResult& r, const slam::PreparedImages& images,
                const slam::System& system) {
    last_timestamp_ = r.timestamp;
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
      transport_.publish_cloud(detail::Transport::Cloud::kMapPoints, r.timestamp,
                               map_points(system.map()));
      cloud_watch_.restart();
      cloud_sent_ = true;
    }
    if (const mapping::MappingWorker* worker = system.occupancy())
      publish_map(r.timestamp, *worker, false);
    publish_people(r);
  }

  /// The final map (when it changed since the last one published), and the "ros" section of the
  /// summary.
  void on_end(const slam::System& system, nlohmann::json& summary) {
    if (system.occupancy() && summary.value("state", "") != "failed")
      publish_map(last_timestamp_, *system.occupancy(), true);
    summary["ros"] = {{"map_frame", options_.map_frame},
                      {"camera_frame", options_.camera_frame},
                      {"floor_frame", options_.floor_frame},
                      {"odom_frame", options_.odom_frame},
                      {"poses_published", poses_},
                      {"odom_lookup_failures", odom_failures_},
                      {"grids_published", grids_},
                      {"voxel_clouds_published", voxel_clouds_},
                      {"people_arrays_published", people_arrays_}};
    if (odom_failures_ > 0)
      std::cerr << "mcslam ros: " << odom_failures_ << " of " << poses_ << " poses had no tf "
                << options_.odom_frame << " -> " << options_.camera_frame << ": no "
                << options_.map_frame << " -> " << options_.odom_frame
                << " was sent for them (summary.json \"ros\")\n";
  }

 private:
  void publish_pose(double timestamp, const SE3& T_w_c) {
    ++poses_;
    const std::string failure = transport_.publish_pose(timestamp, T_w_c);
    if (failure.empty()) return;
    ++odom_failures_;
    if (odom_failures_ > 1 && warn_watch_.elapsed_ms() < 1000.0) return;
    std::cerr << "mcslam ros: warning: no tf " << options_.odom_frame << " -> "
              << options_.camera_frame << " at " << std::fixed << std::setprecision(6) << timestamp
              << std::defaultfloat << " (" << failure << "): no " << options_.map_frame << " -> "
              << options_.odom_frame << " sent (" << odom_failures_ << " so far)\n";
    warn_watch_.restart();
  }

  void publish_map(double timestamp, const mapping::MappingWorker& worker, bool final) {
    const bool grid_due =
        final || !grid_version_ || grid_watch_.elapsed_ms() >= 1000.0 * options_.grid_period_s;
    const bool voxels_due =
        final || !voxel_version_ || voxel_watch_.elapsed_ms() >= 1000.0 * options_.cloud_period_s;
    if (!grid_due && !voxels_due) return;
    const std::shared_ptr<const mapping::OccupancySnapshot> snapshot = worker.snapshot();
    if (snapshot->version == 0) return;  // nothing integrated yet
    const mapping::OccupancyGrid& grid = snapshot->grid;
    if (grid_due && grid_version_ != snapshot->version && grid.width > 0 && grid.height > 0) {
      transport_.publish_grid(timestamp, detail::grid_message(grid));
      grid_version_ = snapshot->version;
      grid_watch_.restart();
      ++grids_;
    }
    if (voxels_due && voxel_version_ != snapshot->version) {
      transport_.publish_cloud(detail::Transport::Cloud::kOccupiedVoxels, timestamp,
                               detail::voxel_points(snapshot->voxels));
      voxel_version_ = snapshot->version;
      voxel_watch_.restart();
      ++voxel_clouds_;
    }
  }

  /// The frame's moving objects, while someone listens; after the last frame that had some, one
  /// array with only the DELETEALL, so that they disappear.
  void publish_people(const slam::FrameResult& r) {
    if (!transport_.people_wanted()) return;
    const std::vector<detail::MarkerSpec> markers = detail::people_markers(r.objects);
    if (markers.empty() && !people_shown_) return;
    transport_.publish_people(r.timestamp, markers);
    people_shown_ = !markers.empty();
    ++people_arrays_;
  }

  detail::Transport& transport_;
  const NodeOptions& options_;
  Stopwatch cloud_watch_, path_watch_, grid_watch_, voxel_watch_, warn_watch_;
  bool cloud_sent_ = false;
  bool people_shown_ = false;
  std::optional<std::uint64_t> grid_version_, voxel_version_;
  double last_timestamp_ = 0.0;
  std::size_t poses_ = 0, odom_failures_ = 0, grids_ = 0, voxel_clouds_ = 0, people_arrays_ = 0;
};

/// A tf2 frame id: not empty, no whitespace, no leading '/' (tf2 rejects those).
std::optional<std::string> frame_name_problem(const std::string& setting, const std::string& name) {
  if (name.empty()) return setting + " must not be empty";
  if (std::any_of(name.begin(), name.end(), [](unsigned char c) { return std::isspace(c); }))
    return setting + " '" + name + "' must not contain whitespace";
  if (name.front() == '/')
    return setting + " '" + name + "' must not start with '/' (tf2 frame ids do not)";
  return std::nullopt;
}

}  // namespace

std::optional<std::string> NodeOptions::check() const {
  if (auto e = topics.check()) return e;
  if (prefix.empty() || prefix.front() != '/') return "the output prefix must start with '/'";
  std::vector<std::pair<std::string, std::string>> frames = {
      {"map_frame (--map-frame)", map_frame},
      {"camera_frame (--camera-frame)", camera_frame},
      {"floor_frame (--floor-frame)", floor_frame}};
  if (!odom_frame.empty()) frames.emplace_back("odom_frame (--odom-frame)", odom_frame);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (auto e = frame_name_problem(frames[i].first, frames[i].second)) return e;
    for (std::size_t j = 0; j < i; ++j)
      if (frames[i].second == frames[j].second)
        return frames[j].first + " and " + frames[i].first + " are both '" + frames[i].second +
               "': the frames must differ";
  }
  if (!(odom_timeout_s >= 0.0 && odom_timeout_s <= 1.0))
    return "odom_timeout_s (--odom-timeout) must be between 0 and 1 second (each frame waits "
           "up to this long for the odom tf)";
  if (max_queue < 1) return "max_queue must be at least 1";
  if (sync_queue < 1) return "sync_queue must be at least 1";
  if (!(cloud_period_s > 0.0)) return "cloud_period_s must be positive";
  if (!(grid_period_s > 0.0)) return "grid_period_s (--grid-period) must be positive";
  if (!(master_timeout_s > 0.0)) return "master_timeout_s must be positive";
  return std::nullopt;
}

nlohmann::json run_node(app::RunRequest request, const NodeOptions& options,
                        const std::function<bool()>& stop_requested) {
  namespace fs = std::filesystem;
  if (auto e = options.check()) throw InputError("ros: " + *e);
  if (!detail::Transport::init(options, stop_requested)) {
    if (stop_requested()) return {};
    throw InputError("cannot reach the ROS master at " + detail::Transport::master_uri() +
                     " (start roscore, or set ROS_MASTER_URI)");
  }
  auto source = std::make_shared<TopicSource>(options);
  detail::Transport::Callbacks callbacks;
  callbacks.frame = [&source](detail::TransportFrame f) {
    app::LiveFrame frame;
    frame.rgb = std::move(f.rgb);
    frame.depth = std::move(f.depth);
    frame.rgb_timestamp = f.rgb_timestamp;
    frame.depth_timestamp = f.depth_timestamp;
    source->push(std::move(frame));
  };
  callbacks.camera_info = [&source](const io::CameraHints::Intrinsics& k, const std::string& name) {
    source->set_intrinsics(k, name);
  };
  callbacks.error = [&source](const std::string& error) { source->close(error); };
  detail::Transport transport(options, callbacks);

  // Ends the stream on request (SIGINT) or when ROS shuts down.
  std::atomic<bool> run_over{false};
  std::thread watcher([&] {
    while (!run_over && !stop_requested() && detail::Transport::ok())
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    source->close();
  });
  const auto finish = [&] {
    run_over = true;
    source->close();
    if (watcher.joinable()) watcher.join();
    transport.shutdown();
  };

  nlohmann::json summary;
  std::optional<fs::path> scratch;
  try {
    if (!options.topics.camera_info.empty()) {
      std::cerr << "mcslam ros: waiting for " << options.topics.camera_info << "\n";
      while (!source->have_intrinsics() && source->error().empty() && !stop_requested() &&
             detail::Transport::ok())
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      if (!source->have_intrinsics()) {
        finish();
        if (const std::string error = source->error(); !error.empty()) throw InputError(error);
        return summary;
      }
    }
    if (request.output_dir.empty()) {
      scratch = fs::temp_directory_path() / ("mcslam-ros-" + std::to_string(::getpid()));
      request.output_dir = scratch->string();
    }
    FramePublisher publisher(transport, options);
    request.live = source;
    request.on_frame = [&publisher](const slam::FrameResult& r, const slam::PreparedImages& images,
                                    slam::System& system) {
      publisher.on_frame(r, images, system);
    };
    request.on_end = [&publisher](slam::System& system, nlohmann::json& run_summary) {
      publisher.on_end(system, run_summary);
    };
    summary = app::run_sequence(request);
    transport.publish_path();
  } catch (...) {
    finish();
    if (scratch) fs::remove_all(*scratch);
    throw;
  }
  finish();
  if (scratch) fs::remove_all(*scratch);
  if (const std::string error = source->error(); !error.empty()) throw InputError(error);
  return summary;
}

}  // namespace mcslam::ros
