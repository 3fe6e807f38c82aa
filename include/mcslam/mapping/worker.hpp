#pragma once
// The occupancy map on a thread of its own: keyframes and corrections are queued and integrated
// in the order given, never in the caller's path; readers (viewer, ROS node, Python) take
// immutable snapshots from any thread.

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "mcslam/mapping/occupancy_map.hpp"

namespace mcslam {
class Worker;
class ThreadFailure;
}  // namespace mcslam

namespace mcslam::mapping {

/// What readers see of the map at one moment.
struct OccupancySnapshot {
  /// Changes integrated so far (keyframes inserted, corrections that rebuilt).
  std::uint64_t version = 0;
  OccupancyGrid grid;  ///< over the floor set with set_floor(), else the estimated one
  std::vector<OccupiedVoxel> voxels;
  OccupancyStats stats;
};

/// enqueue(), correct(), wait() and finish() are for one caller (the thread that owns the
/// worker, as core's Worker); snapshot(), with_map(), pending() and set_floor() for any thread.
class MappingWorker {
 public:
  /// Starts the thread (named thread_name). Throws InputError when options.check() fails.
  explicit MappingWorker(const OccupancyOptions& options = {},
                         const std::string& thread_name = "mcslam-mapping");
  /// Integrates what is still queued, then stops the thread; a failure is not thrown here.
  ~MappingWorker();
  MappingWorker(const MappingWorker&) = delete;
  MappingWorker& operator=(const MappingWorker&) = delete;

  /// Queues a keyframe; returns at once. Its images are copied (VGA depth, masks and colour: 2.5
  /// MB, 1-10 ms on a loaded 2-core machine), so the caller may reuse them. After a failure the
  /// keyframe is dropped.
  void enqueue(const KeyframeDepth& keyframe);
  /// Queues a keyframe without copying its images: they are shared, and the caller must not
  /// write them afterwards (a frame's images are immutable once built).
  void enqueue_shared(KeyframeDepth keyframe);
  /// Queues stored keyframe samples (a saved session's dense map) to be integrated in order.
  void restore(std::vector<KeyframeSamples> keyframes);
  /// Queues a view to be integrated without being stored (OccupancyMap::integrate_transient);
  /// its images are shared, as with enqueue_shared.
  void enqueue_transient(KeyframeDepth view);
  /// Queues new poses (T_w_c) of stored keyframes, applied after the keyframes queued before:
  /// OccupancyMap::correct (the map rebuilds when one moved). The rebuild runs on a copy of the
  /// map, off the lock (a rebuild takes ~5-10 ms per stored keyframe): readers keep the map
  /// before the correction until the rebuilt one replaces it. A map::MapCorrection holds T_c_w:
  /// pass the sparse map's keyframe poses after it applied the correction, inverted (all of
  /// them, or those that moved).
  void correct(std::unordered_map<KeyframeId, SE3> T_w_c, bool listed_only = false);
  /// The floor the grid is computed over (from the sparse map's planes); nullopt: estimated.
  void set_floor(std::optional<FloorPlane> floor);
  /// Planes that may be the floor (the sparse map's horizontal planes below the cameras): the
  /// grid stands on the one that agrees with the voxels (choose_floor), without set_floor().
  /// Queued like a keyframe (applied after what is queued before it), so that it never waits
  /// for an integration; any thread may call it.
  void set_floor_candidates(std::vector<FloorPlane> candidates);

  /// The map now (any thread). Built on demand when the map changed since the last one (the
  /// grid and the voxel list: milliseconds to tens of milliseconds, during which the mapping
  /// thread waits), otherwise the same shared snapshot.
  std::shared_ptr<const OccupancySnapshot> snapshot() const;
  /// snapshot()->grid.
  OccupancyGrid grid() const { return snapshot()->grid; }
  /// Runs fn on the map under its lock (any thread), e.g. to export it.
  void with_map(const std::function<void(const OccupancyMap&)>& fn) const;
  /// Keyframes and corrections queued and not integrated yet.
  std::size_t pending() const;

  /// Blocks until everything queued so far is integrated and the map settled
  /// (OccupancyMap::settle()). Throws std::runtime_error ("the
  /// mapping thread (<name>) failed: <what>") when the thread failed.
  void wait();
  /// wait(), then stops the thread: later keyframes and corrections are dropped. Throws as
  /// wait() does. The destructor finishes too, without throwing.
  void finish();
  bool failed() const;
  /// "" without a failure.
  std::string failure_message() const;

 private:
  /// Queues body on the thread; its exception is kept in failure_, and after one nothing runs.
  void post_guarded(std::function<void()> body);
  /// Queues OccupancyMap::integrate_pending() and settle().
  void settle();
  /// A job on the map under its lock.
  void run(const std::function<void(OccupancyMap&)>& job);
  /// On the thread: `change` applied to a copy of the map off the lock (a rebuild takes long,
  /// and snapshot() may be called meanwhile), the copy swapped in under it. Only the thread
  /// writes map_, so it may read it without the lock.
  void change_off_lock(const std::function<void(OccupancyMap&)>& change);

  mutable std::mutex map_mutex_;  ///< guards map_, version_, floor_ and the cached snapshot
  OccupancyMap map_;
  std::uint64_t version_ = 0;
  std::optional<FloorPlane> floor_;
  std::vector<FloorPlane> floor_candidates_;
  mutable std::shared_ptr<const OccupancySnapshot> cached_;
  std::unique_ptr<ThreadFailure> failure_;
  std::atomic<std::size_t> pending_{0};
  std::unique_ptr<Worker> worker_;  ///< last: stopped (its queue run) before the rest goes
};

}  // namespace mcslam::mapping
