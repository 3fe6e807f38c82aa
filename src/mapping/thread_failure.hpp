#pragma once
// The first failure of the mapping thread, kept for its owner.
//
// A local stand-in for core/thread_failure.hpp's ThreadFailure (which is not on this branch
// yet): the same interface, so that the worker switches to the core class (and throws its
// BackgroundThreadError, a std::runtime_error too) when the branches meet.

#include <atomic>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <string>
#include <utility>

namespace mcslam::mapping::detail {

inline std::string describe_exception(const std::exception_ptr& e) {
  try {
    std::rethrow_exception(e);
  } catch (const std::exception& ex) {
    return ex.what();
  } catch (...) {
    return "an exception that is not a std::exception";
  }
}

class ThreadFailure {
 public:
  explicit ThreadFailure(std::string thread_name) : thread_(std::move(thread_name)) {}

  void set(std::exception_ptr e) {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (exception_) return;
    exception_ = std::move(e);
    failed_.store(true, std::memory_order_release);
  }
  bool failed() const { return failed_.load(std::memory_order_acquire); }
  std::string message() const {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (!exception_) return "";
    return "the mapping thread (" + thread_ + ") failed: " + describe_exception(exception_);
  }
  void throw_if_failed() const {
    if (failed()) throw std::runtime_error(message());
  }

 private:
  std::string thread_;
  std::atomic<bool> failed_{false};
  mutable std::mutex mutex_;
  std::exception_ptr exception_;
};

}  // namespace mcslam::mapping::detail
