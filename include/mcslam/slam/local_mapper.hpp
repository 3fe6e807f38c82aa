#pragma once
// Local mapping: the only writer of the map. It takes keyframe requests from the tracker, adds
// landmarks from depth, links them across neighbouring keyframes, refines the neighbourhood by
// local bundle adjustment and culls redundant points and keyframes. It runs either inline
// (process(), deterministic) or on its own thread (start(), enqueue(), finish()).

#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/thread_failure.hpp"
#include "mcslam/core/timing.hpp"
#include "mcslam/io/undistort.hpp"
#include "mcslam/map/correction.hpp"
#include "mcslam/map/map.hpp"
#include "mcslam/optim/bundle_adjustment.hpp"
#include "mcslam/place/vocabulary.hpp"
#include "mcslam/slam/loop_closer.hpp"
#include "mcslam/slam/options.hpp"
#include "mcslam/slam/tracker.hpp"

namespace mcslam::slam {

class LocalMapper {
 public:
  /// The tracker's options give the measurement weights and matching thresholds of lines and
  /// planes, so that tracking and mapping judge them alike.
  LocalMapper(const PinholeCamera& camera, const MapperOptions& options,
              const TrackerOptions& tracker_options, double close_depth, map::Map& map);
  ~LocalMapper();
  LocalMapper(const LocalMapper&) = delete;
  LocalMapper& operator=(const LocalMapper&) = delete;

  /// New keyframes get a bag of words of this vocabulary (with the direct index `levels_up`
  /// levels above the words) and enter the map's keyframe database; so do the keyframes already
  /// in the map (a loaded session). Call before the first keyframe.
  void set_vocabulary(std::shared_ptr<const place::Vocabulary> vocabulary, int levels_up);
  /// The keyframes' colour images (KeyFrameRequest::color) are the camera's raw images: the
  /// mapper undistorts them with this before new points take their colour. Without it they
  /// are taken as undistorted. Call before the first keyframe.
  void set_undistorter(std::shared_ptr<const io::Undistorter> undistorter);
  /// Called on the mapper's thread after each keyframe is processed (loop detection).
  void set_keyframe_listener(std::function<void(map::KeyFrameId)> listener);
  /// Called on the mapper's thread after each keyframe is processed, with the request (its
  /// depth and dynamic regions), the colour image undistorted, and the keyframe's pose after
  /// the local bundle adjustment: what the dense map integrates. Before the first keyframe.
  using OccupancySink =
      std::function<void(const KeyFrameRequest&, const cv::Mat& colour, const SE3& T_w_c)>;
  void set_occupancy_sink(OccupancySink sink);
  /// Called on the mapper's thread after a correction moved keyframes (a loop, a full bundle
  /// adjustment merged, the final one): the dense map rebuilds what moved.
  void set_correction_listener(std::function<void()> listener);
  /// Runs `task` on the mapper's thread between two keyframes and waits for it (inline when
  /// the mapper has no thread). Tasks may write the map: the mapper is then its writer. What the
  /// task throws is thrown here; so is the mapper's failure when its thread has failed (the
  /// task then does not run).
  void run_task(const std::function<void()>& task);
  /// Corrects the map for a verified loop (see LoopCloser). Mapper's thread only (run_task).
  /// Returns false, with event.reason, when the loop can no longer be applied.
  bool close_loop(const LoopClosure& loop, const LoopOptions& options, LoopEvent& event);
  /// Moves keyframes and landmarks (a merged full bundle adjustment). Mapper's thread only.
  void correct(const map::MapCorrection& correction);

  /// Processes one keyframe inline and records its stage times in `times`.
  void process(KeyFrameRequest request, StageTimes* times = nullptr);

  /// Threaded mode; the thread's nice value is raised by `niceness` (see
  /// SystemOptions::background_niceness).
  void start(int niceness = 0);
  void enqueue(KeyFrameRequest request);
  /// Waits until the queue is empty and the thread has stopped.
  void finish();
  /// The thread's failure: once its body threw, the mapper processes nothing more (keyframes
  /// enqueued after it are dropped, waiting tasks get the failure) and this holds the exception.
  const ThreadFailure& failure() const { return failure_; }
  /// Testing the failure path: processing the keyframe of this request id throws
  /// std::runtime_error (`mcslam run --inject-failure mapper:N`). -1: never.
  void inject_failure_at(std::int64_t keyframe) { fail_at_keyframe_ = keyframe; }
  bool idle() const;
  /// Waits until the queue is empty and nothing is running (threaded mode; returns at once
  /// otherwise).
  void wait_idle();
  /// Waits until the keyframe of this request id is in the map with its new points, lines and
  /// plane associations (its fusion and bundle adjustment may still be running). Returns at once
  /// without a thread, and when the thread has failed (a keyframe it will never insert).
  void wait_inserted(map::KeyFrameId id);
  std::size_t queue_size() const;

  /// Bundle adjustment of the whole map (all keyframes and points, the first keyframe fixed).
  /// Stops the mapping thread first.
  void global_bundle_adjustment();

  /// Stage times of every processed keyframe (copy; safe from any thread).
  std::vector<StageTimes> keyframe_times() const;
  /// Bundle adjustments (local and global) whose solver found no usable solution; nothing of
  /// them was applied. Safe from any thread.
  int ba_failures() const { return ba_failures_.load(); }

 private:
  void run();
  /// The keyframe's bag of words (its moving objects' points left out).
  std::shared_ptr<const place::BowImage> bag_of_words(const map::KeyFrame& kf) const;
  void insert_keyframe(const KeyFrameRequest& request);
  void create_points(map::KeyFrameId id, const cv::Mat& color);
  /// New map lines from the keyframe's 3D segments that no map line explains.
  void create_lines(map::KeyFrameId id);
  /// Frame planes not matched by the tracker: matched to a map plane here, or new map planes.
  void associate_planes(map::KeyFrameId id);
  void cull_recent_points(map::KeyFrameId current);
  void cull_recent_lines(map::KeyFrameId current);
  void fuse_neighbours(map::KeyFrameId id);
  int fuse_into(map::KeyFrameId target, const std::vector<map::PointId>& points);
  int fuse_lines_into(map::KeyFrameId target, const std::vector<map::LineId>& lines);
  /// Merges map planes that coincide (within plane_merge_angle_deg and plane_merge_distance).
  void merge_planes();
  void local_bundle_adjustment(map::KeyFrameId id);
  void bundle_adjust_keyframes(const std::vector<map::KeyFrameId>& keyframes,
                               const optim::BundleAdjustmentOptions& options,
                               const std::atomic<bool>* abort);
  void cull_keyframes(map::KeyFrameId id);

  PinholeCamera camera_;
  MapperOptions options_;
  std::shared_ptr<const place::Vocabulary> vocabulary_;
  std::shared_ptr<const io::Undistorter> undistorter_;
  int direct_levels_up_ = 3;
  std::function<void(map::KeyFrameId)> listener_;
  OccupancySink occupancy_sink_;
  std::function<void()> correction_listener_;
  /// The map's version right after the last correction: keyframe requests made before it
  /// carry poses of the uncorrected map.
  std::uint64_t corrected_version_ = 0;
  double close_depth_;
  map::Map& map_;
  std::vector<map::PointId> recent_points_;
  std::vector<map::LineId> recent_lines_;
  TrackerOptions tracker_options_;

  mutable std::mutex queue_mutex_;
  std::condition_variable queue_cv_;
  std::condition_variable idle_cv_;
  std::deque<KeyFrameRequest> queue_;
  /// A task waiting for the mapper's thread; its waiter sleeps on `done`.
  struct PendingTask {
    std::function<void()> run;
    std::mutex mutex;
    std::condition_variable cv;
    bool done = false;
    std::exception_ptr error;
    void complete(std::exception_ptr e);
  };
  std::deque<std::shared_ptr<PendingTask>> tasks_;
  /// The thread body that catches: a failure is kept, the queue dropped, the waiters released.
  void run_guarded();
  ThreadFailure failure_{"mapper (mcslam-mapper)"};
  std::int64_t fail_at_keyframe_ = -1;
  bool stop_ = false;
  bool busy_ = false;
  std::atomic<bool> abort_ba_{false};
  /// The newest keyframe inserted (process: after its points, lines and planes), under
  /// queue_mutex_; idle_cv_ tells wait_inserted.
  std::optional<map::KeyFrameId> inserted_;
  std::atomic<int> ba_failures_{0};
  std::thread thread_;

  mutable std::mutex times_mutex_;
  std::vector<StageTimes> times_;
};

}  // namespace mcslam::slam
