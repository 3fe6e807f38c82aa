#pragma once
// A named thread that runs jobs handed to it, for work repeated at every frame.

#include <condition_variable>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

namespace mcslam {

/// One thread that runs the jobs handed to it, one at a time, in the order given. A frame's lines
/// and planes are extracted on workers like this one while the caller extracts its points: a
/// thread started for each frame would cost its start and end every frame, and would be
/// nameless in top, perf and gdb.
///
/// post() and wait() are for one caller at a time (the thread that owns the worker); the jobs
/// run on the worker's thread. Not copyable or movable: jobs may hold pointers to it.
class Worker {
 public:
  /// Starts the thread and names it (see set_current_thread_name).
  explicit Worker(std::string name);
  /// Runs the jobs still queued, then joins the thread. Their exceptions are dropped: a caller
  /// that wants them calls wait() first.
  ~Worker();
  Worker(const Worker&) = delete;
  Worker& operator=(const Worker&) = delete;

  /// Queues `job`; returns at once.
  void post(std::function<void()> job);
  /// Blocks until every job posted so far has finished, then rethrows the first exception one of
  /// them threw since the last wait() (the other jobs still ran).
  void wait();

  const std::string& name() const { return name_; }

 private:
  void loop();

  std::string name_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<std::function<void()>> jobs_;
  bool running_ = false;  ///< a job taken from jobs_ has not finished yet
  bool stop_ = false;
  std::exception_ptr error_;
  std::thread thread_;
};

/// Names the calling thread for the system's tools (top -H, perf, gdb); Linux keeps the first 15
/// bytes. Returns false where the name cannot be set (the thread runs either way).
bool set_current_thread_name(const std::string& name);

}  // namespace mcslam
