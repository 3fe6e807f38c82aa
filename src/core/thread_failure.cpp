#include "mcslam/core/thread_failure.hpp"

namespace mcslam {

std::string describe_exception(const std::exception_ptr& e) {
  if (!e) return "no exception";
  try {
    std::rethrow_exception(e);
  } catch (const std::exception& x) {
    return x.what();
  } catch (...) {
    return "an exception that is not a std::exception";
  }
}

void ThreadFailure::set(std::exception_ptr e) {
  std::lock_guard<std::mutex> guard(mutex_);
  if (exception_) return;
  exception_ = std::move(e);
  failed_.store(true, std::memory_order_release);
}

std::exception_ptr ThreadFailure::exception() const {
  std::lock_guard<std::mutex> guard(mutex_);
  return exception_;
}

std::string ThreadFailure::message() const {
  const std::exception_ptr e = exception();
  if (!e) return "";
  return "the " + thread_ + " thread failed: " + describe_exception(e);
}

void ThreadFailure::throw_if_failed() const {
  if (failed()) throw BackgroundThreadError(message());
}

}  // namespace mcslam
