#pragma once
// The frames of `mcslam run`, read, decoded and undistorted on a thread of their own, off the
// frame loop.
//
// In order (the default): every frame in turn; the reader keeps a few frames ready, and the loop
// waits only when the reader is behind.
// Real time (--realtime): frames become available at their timestamps, as a camera delivers them
// (the reader prepares each one ahead of its time and releases it at that time). The loop takes
// the newest available frame; one that a newer frame replaces before the loop took it is
// dropped, as a camera driver drops what a slow consumer misses. The clock starts when the first
// frame is ready. Work that needs the frame to exist (feature extraction) runs on the reader's
// thread too, once the frame is due, and counts in its latency; meanwhile the frame after is
// loaded on a helper thread.

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "mcslam/slam/system.hpp"

namespace mcslam::app {

struct FeedOptions {
  bool realtime = false;
  /// In order: how many prepared frames the reader keeps ready (at least 1).
  std::size_t lookahead = 2;
};

struct FedFrame {
  std::size_t index = 0;  ///< in the feed's list of frames
  slam::PreparedImages images;
  /// When the frame was due (real time: its timestamp on the feed's clock) and when it was
  /// ready, in seconds since the feed's clock started; ready > due when preparing it was late.
  double due_s = 0.0;
  double ready_s = 0.0;
  double wait_ms = 0.0;            ///< how long next() waited for it
  std::size_t dropped_before = 0;  ///< frames dropped since the frame taken before
};

class FrameFeed {
 public:
  /// Prepares frame k (reads, decodes, undistorts); may throw InputError, which next() rethrows
  /// when the loop reaches that frame.
  using Loader = std::function<slam::PreparedImages(std::size_t)>;
  /// Work on a prepared frame that may only start once the frame is due, as a camera's image
  /// exists only then (in order: right after loading): the run's feature extraction, which then
  /// overlaps the loop's tracking of the frame before. On the reader's thread; what it throws,
  /// next() rethrows as the loader's.
  using Finisher = std::function<void(slam::PreparedImages&)>;
  /// Whether the finisher has work for the frame that is due now (checked then, on the
  /// reader's thread; it must not call the feed). A frame it has none for is handed over as
  /// without a finisher: in real time it does not wait for the loop to take the frame before.
  using FinishWanted = std::function<bool()>;

  /// `timestamps`: capture time (s) of each frame, non-decreasing; in real time frame k is due
  /// timestamps[k] - timestamps[0] seconds after the clock starts. Starts the reader thread.
  FrameFeed(Loader load, std::vector<double> timestamps, FeedOptions options, Finisher finish = {},
            FinishWanted finish_wanted = {});
  /// Stops the reader (between two frames) and joins it.
  ~FrameFeed();
  FrameFeed(const FrameFeed&) = delete;
  FrameFeed& operator=(const FrameFeed&) = delete;

  /// The next frame (real time: the newest available one), waiting for it when none is ready;
  /// nullopt once every frame was taken or dropped. Rethrows the loader's exception.
  std::optional<FedFrame> next();
  /// Seconds on the feed's clock (0 until the first frame is ready).
  double now_s() const;
  /// Frames dropped so far (real time only) and their indices.
  std::vector<std::size_t> dropped() const;

 private:
  struct Slot {
    std::size_t index = 0;
    slam::PreparedImages images;
    std::exception_ptr error;
    double due_s = 0.0;
    double ready_s = 0.0;
  };
  using Clock = std::chrono::steady_clock;

  void read();
  /// Frame k loaded, or the loader's exception.
  Slot load_slot(std::size_t k) const;
  /// Under the lock: the frame to read from k on (in order once fewer than `lookahead` frames
  /// are ready; in real time past those whose successor is already due, which are dropped), or
  /// nullopt when the feed stops.
  std::optional<std::size_t> next_to_read(std::unique_lock<std::mutex>& lock, std::size_t k);
  /// When frame k is due on the feed's clock (which has started).
  Clock::time_point due_at(std::size_t k) const;
  /// Under the lock, real time: waits until the loop has taken every ready frame; false when
  /// frame k + 1 comes due first. Returns at once when the feed stops.
  bool wait_for_loop(std::unique_lock<std::mutex>& lock, std::size_t k);
  /// Under the lock: the slot to the loop (in real time it replaces a frame not taken yet).
  void publish(Slot slot);
  double clock_s() const;  // under mutex_

  Loader load_;
  Finisher finish_;
  FinishWanted finish_wanted_;
  std::vector<double> timestamps_;
  FeedOptions options_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<Slot> ready_;
  std::vector<std::size_t> dropped_;
  std::size_t dropped_reported_ = 0;  // dropped_.size() when next() last returned
  std::optional<std::chrono::steady_clock::time_point> start_;
  bool finished_ = false;  // the reader has published its last frame (or an error)
  bool stop_ = false;
  std::thread reader_;
};

}  // namespace mcslam::app
