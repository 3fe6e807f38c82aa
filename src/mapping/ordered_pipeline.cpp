#include "mapping/ordered_pipeline.hpp"

#include <condition_variable>
#include <exception>
#include <mutex>
#include <system_error>
#include <thread>
#include <vector>

namespace mcslam::mapping::detail {

namespace {

/// The shared state of one gather_and_apply_in_order() call; every member is read and written
/// under `mutex`.
class Pipeline {
 public:
  Pipeline(std::size_t n, std::size_t slots, const std::function<void(std::size_t, std::size_t)>& g)
      : n_(n), slots_(slots), gather_(g), ready_(slots, n) {}

  /// A helper's loop: gathers items until none is left or the work stopped.
  void help() {
    std::unique_lock lock(mutex_);
    for (;;) {
      changed_.wait(lock, [&] { return stop_ || next_ >= n_ || next_ < applied_ + slots_; });
      const std::size_t k = claim();
      if (k == n_) return;
      gather(lock, k);
    }
  }

  /// On the applying thread: waits until item i is gathered, gathering what it may meanwhile.
  /// False when the work stopped.
  bool wait_for(std::size_t i) {
    std::unique_lock lock(mutex_);
    while (!stop_ && ready_[i % slots_] != i) {
      const std::size_t k = claim();
      if (k != n_)
        gather(lock, k);
      else
        changed_.wait(lock, [&] { return stop_ || ready_[i % slots_] == i; });
    }
    return !stop_;
  }

  /// Item i is applied: its slot is free.
  void applied(std::size_t i) {
    const std::lock_guard lock(mutex_);
    ready_[i % slots_] = n_;
    applied_ = i + 1;
    changed_.notify_all();
  }

  /// Stops the work, keeping the first failure (none: a normal end).
  void stop(std::exception_ptr failure = nullptr) {
    const std::lock_guard lock(mutex_);
    if (failure && !failure_) failure_ = std::move(failure);
    stop_ = true;
    changed_.notify_all();
  }

  std::exception_ptr failure() {
    const std::lock_guard lock(mutex_);
    return failure_;
  }

 private:
  /// Under the lock: the next item to gather when its slot is free, else n_.
  std::size_t claim() { return !stop_ && next_ < n_ && next_ < applied_ + slots_ ? next_++ : n_; }

  /// Under the lock, which it lets go of while gathering item k.
  void gather(std::unique_lock<std::mutex>& lock, std::size_t k) {
    lock.unlock();
    std::exception_ptr error;
    try {
      gather_(k, k % slots_);
    } catch (...) {
      error = std::current_exception();
    }
    lock.lock();
    if (error) {
      if (!failure_) failure_ = std::move(error);
      stop_ = true;
    } else {
      ready_[k % slots_] = k;
    }
    changed_.notify_all();
  }

  const std::size_t n_, slots_;
  const std::function<void(std::size_t, std::size_t)>& gather_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<std::size_t> ready_;  ///< the item each slot holds gathered (n_: none)
  std::size_t next_ = 0;            ///< the next item to gather
  std::size_t applied_ = 0;         ///< items applied
  bool stop_ = false;
  std::exception_ptr failure_;
};

}  // namespace

void gather_and_apply_in_order(std::size_t n, std::size_t helpers, std::size_t slots,
                               const std::function<void(std::size_t, std::size_t)>& gather,
                               const std::function<void(std::size_t, std::size_t)>& apply) {
  slots = pipeline_slots(helpers, slots);
  Pipeline pipeline(n, slots, gather);
  std::vector<std::thread> threads;
  try {
    for (std::size_t h = 0; h < helpers; ++h)
      threads.emplace_back([&pipeline] { pipeline.help(); });
  } catch (const std::system_error&) {
    // No thread to be had: this one gathers what the others do not.
  }
  for (std::size_t i = 0; i < n && pipeline.wait_for(i); ++i) {
    try {
      apply(i, i % slots);
    } catch (...) {
      pipeline.stop(std::current_exception());
      break;
    }
    pipeline.applied(i);
  }
  pipeline.stop();
  for (std::thread& t : threads) t.join();
  if (const std::exception_ptr failure = pipeline.failure()) std::rethrow_exception(failure);
}

}  // namespace mcslam::mapping::detail
