#pragma once
// Loop closing in the ORB-SLAM2 manner, for RGB-D (SE(3): depth fixes the scale):
//  1. detection: the keyframe database's entries that score at least as well as the keyframe's
//     own covisible neighbours, grouped by covisibility, and consistent over
//     LoopOptions::min_consistency consecutive keyframes;
//  2. verification: matches through the vocabulary's direct index, an SE(3) by RANSAC from 3D-3D
//     correspondences (the keyframe's depth against the candidate's map points), then a guided
//     search in the candidate's neighbourhood;
//  3. correction, on the local mapper's thread (the map's one writer): the keyframe and its
//     neighbours moved to where the loop says, duplicated points and lines fused, the essential
//     graph (keyframe order, strong covisibility, loops) optimised, and every landmark moved with
//     the keyframe it hangs on;
//  4. a bundle adjustment of the whole map, in the background, merged back by the mapper.
// Features of dynamic and constrained objects take no part: they are neither in the bags of
// words nor matched.
//
// Threaded: start(), enqueue() (from the mapper, after each keyframe), finish(). Inline:
// process().

#include <atomic>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/core/thread_failure.hpp"
#include "mcslam/core/timing.hpp"
#include "mcslam/map/map.hpp"
#include "mcslam/place/vocabulary.hpp"
#include "mcslam/slam/options.hpp"

namespace mcslam::slam {

class LocalMapper;

/// One verified loop, ready for correction.
struct LoopClosure {
  map::KeyFrameId keyframe = map::kNoId;  // the new keyframe
  map::KeyFrameId matched = map::kNoId;   // the old one it sees again
  /// The new keyframe's pose (T_c_w) in the old keyframe's frame of reference.
  SE3 T_c_w;
  /// Inlier correspondences: feature of the new keyframe -> map point of the old place.
  std::vector<std::pair<int, map::PointId>> matches;
};

/// A verified loop candidate, accepted or not, for the report.
struct LoopEvent {
  map::KeyFrameId keyframe = map::kNoId;
  map::KeyFrameId matched = map::kNoId;
  double timestamp = 0.0;          // of the new keyframe
  double matched_timestamp = 0.0;  // of the old one
  double score = 0.0;              // bag-of-words score
  int matches = 0;                 // through the direct index, with depth on both sides
  int ransac_inliers = 0;
  int inliers = 0;  // after the guided search
  bool accepted = false;
  std::string reason;  // why a candidate was rejected
  /// The correction at the new keyframe: camera centre shift (m) and rotation (deg).
  double correction_m = 0.0;
  double correction_deg = 0.0;
  double verify_ms = 0.0;
  double correct_ms = 0.0;
  /// The pose graph had no usable solution: the loop's own keyframes were corrected and fused,
  /// the rest of the map was left where it was.
  bool pose_graph_failed = false;
  int fused_points = 0;
};

/// Figures of the loop closer for the summary.
struct LoopStatistics {
  /// Candidates that went on to geometric verification (enough matches through the vocabulary).
  std::vector<LoopEvent> events;
  /// Consistent candidates with too few matches through the vocabulary to try geometry.
  int unmatched_candidates = 0;
  std::vector<double> detection_ms;  // per keyframe: database query, grouping, consistency
  int full_ba_runs = 0;
  int full_ba_aborted = 0;
  int full_ba_failed = 0;     // the solver found no usable solution: nothing was applied
  int pose_graph_failed = 0;  // loop corrections whose pose graph could not be solved
  std::vector<double> full_ba_ms;
};

class LoopCloser {
 public:
  LoopCloser(const PinholeCamera& camera, const LoopOptions& options,
             const TrackerOptions& tracker_options, const MapperOptions& mapper_options,
             std::shared_ptr<const place::Vocabulary> vocabulary, const map::Map& map,
             LocalMapper& mapper);
  ~LoopCloser();
  LoopCloser(const LoopCloser&) = delete;
  LoopCloser& operator=(const LoopCloser&) = delete;

  /// Inline: detection, verification, correction and the full bundle adjustment.
  void process(map::KeyFrameId keyframe);

  /// Starts the thread, its nice value raised by `niceness` (SystemOptions::background_niceness).
  void start(int niceness = 0);
  void enqueue(map::KeyFrameId keyframe);
  /// Processes what is queued (a running full bundle adjustment is stopped), then stops.
  void finish();
  /// The thread's failure: once its body threw, keyframes are no longer searched for loops.
  const ThreadFailure& failure() const { return failure_; }
  /// Testing the failure path: the search after this many keyframes throws
  /// std::runtime_error (`mcslam run --inject-failure loop:N`). -1: never.
  void inject_failure_at(std::int64_t keyframes) { fail_after_keyframes_ = keyframes; }

  LoopStatistics statistics() const;

 private:
  struct Group {
    std::vector<map::KeyFrameId> members;  // sorted
    int consistency = 0;
  };
  void run();
  /// Candidates consistent over enough keyframes, best first, with their scores.
  std::vector<std::pair<map::KeyFrameId, double>> detect(map::KeyFrameId keyframe);
  std::optional<LoopClosure> verify(map::KeyFrameId keyframe, map::KeyFrameId candidate,
                                    LoopEvent& event) const;
  void full_bundle_adjustment();

  PinholeCamera camera_;
  LoopOptions options_;
  TrackerOptions tracker_options_;
  MapperOptions mapper_options_;  // the full bundle adjustment's depth residual
  std::shared_ptr<const place::Vocabulary> vocabulary_;
  const map::Map& map_;
  LocalMapper& mapper_;

  std::vector<Group> groups_;  // candidate groups of the previous keyframe
  map::KeyFrameId last_loop_ = map::kNoId;
  std::size_t keyframes_seen_ = 0;
  std::size_t keyframes_at_last_loop_ = 0;

  mutable std::mutex queue_mutex_;
  std::condition_variable queue_cv_;
  std::deque<map::KeyFrameId> queue_;
  bool stop_ = false;
  std::atomic<bool> abort_ba_{false};
  std::thread thread_;
  ThreadFailure failure_{"loop closer (mcslam-loop)"};
  std::int64_t fail_after_keyframes_ = -1;

  mutable std::mutex stats_mutex_;
  LoopStatistics stats_;
};

}  // namespace mcslam::slam
