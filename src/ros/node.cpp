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
#include <iostream>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

#include "mcslam/core/error.hpp"
#include "mcslam/core/timing.hpp"
#include "node_publisher.hpp"
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
    detail::FramePublisher publisher(transport, options);
    request.live = source;
    request.on_frame = [&publisher](const slam::FrameResult& r, const slam::PreparedImages& images,
                                    slam::System& system) {
      publisher.on_frame(r, images, system);
    };
    request.on_end = [&publisher](slam::System& system, nlohmann::json& run_summary) {
      publisher.on_end(system, run_summary);
    };
    request.on_detach = [&publisher] { publisher.on_detach(); };
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
