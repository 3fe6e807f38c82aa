#pragma once
// What a background thread (mapper, loop closer, detector, viewer) does when its body throws: it
// keeps the exception instead of letting it reach std::terminate, stops its own work, and the
// owner surfaces it to the caller (System::process() and finish() throw BackgroundThreadError).

#include <atomic>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <string>

namespace mcslam {

/// A background thread failed: the message names the thread and what it threw. The outputs
/// made so far stay readable (trajectories, records); the failed stage does no more work.
class BackgroundThreadError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// "what()" of any exception, or a fixed text for one that is not a std::exception.
std::string describe_exception(const std::exception_ptr& e);

/// The first failure of one thread. Written by that thread, read by any: set() keeps the first
/// exception only; failed() is a lock-free check for the per-frame path.
class ThreadFailure {
 public:
  explicit ThreadFailure(std::string thread_name) : thread_(std::move(thread_name)) {}

  /// Keeps `e` unless a failure is already kept.
  void set(std::exception_ptr e);
  bool failed() const { return failed_.load(std::memory_order_acquire); }
  std::exception_ptr exception() const;
  /// "the mapper thread (mcslam-mapper) failed: <what>", or "" without a failure.
  std::string message() const;
  /// Throws BackgroundThreadError with message() when failed.
  void throw_if_failed() const;
  const std::string& thread() const { return thread_; }

 private:
  std::string thread_;
  std::atomic<bool> failed_{false};
  mutable std::mutex mutex_;
  std::exception_ptr exception_;
};

}  // namespace mcslam
