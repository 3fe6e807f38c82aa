#pragma once
// Local mapping: the only writer of the map. It takes keyframe requests from the tracker, adds
// landmarks from depth, links them across neighbouring keyframes, refines the neighbourhood by
// local bundle adjustment and culls redundant points and keyframes. It runs either inline
// (process(), deterministic) or on its own thread (start(), enqueue(), finish()).

#include <atomic>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <thread>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/timing.hpp"
#include "mcslam/map/map.hpp"
#include "mcslam/optim/bundle_adjustment.hpp"
#include "mcslam/slam/options.hpp"
#include "mcslam/slam/tracker.hpp"

namespace mcslam::slam {

class LocalMapper {
 public:
  LocalMapper(const PinholeCamera& camera, const MapperOptions& options, double close_depth,
              map::Map& map);
  ~LocalMapper();
  LocalMapper(const LocalMapper&) = delete;
  LocalMapper& operator=(const LocalMapper&) = delete;

  /// Processes one keyframe inline and records its stage times in `times`.
  void process(KeyFrameRequest request, StageTimes* times = nullptr);

  /// Threaded mode.
  void start();
  void enqueue(KeyFrameRequest request);
  /// Waits until the queue is empty and the thread has stopped.
  void finish();
  bool idle() const;
  std::size_t queue_size() const;

  /// Bundle adjustment of the whole map (all keyframes and points, the first keyframe fixed).
  /// Stops the mapping thread first.
  void global_bundle_adjustment();

  /// Stage times of every processed keyframe (copy; safe from any thread).
  std::vector<StageTimes> keyframe_times() const;

 private:
  void run();
  void insert_keyframe(const KeyFrameRequest& request);
  void create_points(map::KeyFrameId id);
  void cull_recent_points(map::KeyFrameId current);
  void fuse_neighbours(map::KeyFrameId id);
  int fuse_into(map::KeyFrameId target, const std::vector<map::PointId>& points);
  void local_bundle_adjustment(map::KeyFrameId id);
  void bundle_adjust_keyframes(const std::vector<map::KeyFrameId>& keyframes,
                               const optim::BundleAdjustmentOptions& options,
                               const std::atomic<bool>* abort);
  void cull_keyframes(map::KeyFrameId id);

  PinholeCamera camera_;
  MapperOptions options_;
  double close_depth_;
  map::Map& map_;
  std::vector<map::PointId> recent_points_;

  mutable std::mutex queue_mutex_;
  std::condition_variable queue_cv_;
  std::deque<KeyFrameRequest> queue_;
  bool stop_ = false;
  bool busy_ = false;
  std::atomic<bool> abort_ba_{false};
  std::thread thread_;

  mutable std::mutex times_mutex_;
  std::vector<StageTimes> times_;
};

}  // namespace mcslam::slam
