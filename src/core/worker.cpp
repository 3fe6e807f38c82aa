#include "mcslam/core/worker.hpp"

#include <utility>

#if defined(__linux__)
#include <pthread.h>
#endif

namespace mcslam {

bool set_current_thread_name(const std::string& name) {
#if defined(__linux__)
  // The kernel's limit is 16 bytes with the terminating zero.
  return ::pthread_setname_np(::pthread_self(), name.substr(0, 15).c_str()) == 0;
#else
  (void)name;
  return false;
#endif
}

Worker::Worker(std::string name) : name_(std::move(name)) {
  thread_ = std::thread([this] {
    set_current_thread_name(name_);  // best effort: the worker runs either way
    loop();
  });
}

Worker::~Worker() {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  thread_.join();
}

void Worker::post(std::function<void()> job) {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    jobs_.push_back(std::move(job));
  }
  changed_.notify_all();
}

void Worker::wait() {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [this] { return jobs_.empty() && !running_; });
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
}

void Worker::loop() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    changed_.wait(lock, [this] { return stop_ || !jobs_.empty(); });
    if (jobs_.empty()) return;  // stopping, and nothing left to run
    std::function<void()> job = std::move(jobs_.front());
    jobs_.pop_front();
    running_ = true;
    lock.unlock();
    std::exception_ptr error;
    try {
      job();
    } catch (...) {
      error = std::current_exception();
    }
    lock.lock();
    running_ = false;
    if (error && !error_) error_ = error;
    // wait() and the next post() both listen on this one condition.
    changed_.notify_all();
  }
}

}  // namespace mcslam
