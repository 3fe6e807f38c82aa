#include "mcslam/app/frame_feed.hpp"

#include <algorithm>
#include <chrono>
#include <optional>

#include "mcslam/core/worker.hpp"

namespace mcslam::app {

FrameFeed::FrameFeed(Loader load, std::vector<double> timestamps, FeedOptions options,
                     Finisher finish, FinishWanted finish_wanted)
    : load_(std::move(load)),
      finish_(std::move(finish)),
      finish_wanted_(std::move(finish_wanted)),
      timestamps_(std::move(timestamps)),
      options_(options) {
  options_.lookahead = std::max<std::size_t>(options_.lookahead, 1);
  reader_ = std::thread([this] {
    set_current_thread_name("mcslam-reader");
    read();
  });
}

FrameFeed::~FrameFeed() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  reader_.join();
}

double FrameFeed::clock_s() const {
  if (!start_) return 0.0;
  return std::chrono::duration<double>(Clock::now() - *start_).count();
}

double FrameFeed::now_s() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return clock_s();
}

std::vector<std::size_t> FrameFeed::dropped() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return dropped_;
}

FrameFeed::Slot FrameFeed::load_slot(std::size_t k) const {
  Slot slot;
  slot.index = k;
  try {
    slot.images = load_(k);
  } catch (...) {
    slot.error = std::current_exception();
  }
  return slot;
}

std::optional<std::size_t> FrameFeed::next_to_read(std::unique_lock<std::mutex>& lock,
                                                   std::size_t k) {
  // In order, keep at most `lookahead` frames ready; in real time never wait for the loop.
  if (!options_.realtime)
    changed_.wait(lock, [&] { return stop_ || ready_.size() < options_.lookahead; });
  if (stop_) return std::nullopt;
  // A camera never falls behind its clock: when the reader itself is late (its thread got too
  // little CPU), frames whose successor is already due are dropped unread, so that the loop gets
  // the newest frame and not a backlog.
  if (options_.realtime && start_) {
    const double now = clock_s();
    while (k + 1 < timestamps_.size() && timestamps_[k + 1] - timestamps_.front() <= now) {
      dropped_.push_back(k);
      ++k;
    }
  }
  return k;
}

FrameFeed::Clock::time_point FrameFeed::due_at(std::size_t k) const {
  return *start_ + std::chrono::duration_cast<Clock::duration>(
                       std::chrono::duration<double>(timestamps_[k] - timestamps_.front()));
}

bool FrameFeed::wait_for_loop(std::unique_lock<std::mutex>& lock, std::size_t k) {
  // The finisher's work (the features) waits until the loop has taken the frame before, so that
  // it overlaps the loop's work on that frame and is never spent on a frame that a newer one
  // replaces before the loop comes back: the loop takes the newest frame anyway.
  const auto loop_free = [&] { return stop_ || ready_.empty(); };
  if (k + 1 == timestamps_.size()) {
    changed_.wait(lock, loop_free);
    return true;
  }
  return changed_.wait_until(lock, due_at(k + 1), loop_free);
}

void FrameFeed::publish(Slot slot) {
  // Newest wins: a frame the loop has not taken yet is dropped (never an error, which ends the
  // feed and must reach the loop).
  if (options_.realtime)
    while (!ready_.empty() && !ready_.back().error) {
      dropped_.push_back(ready_.back().index);
      ready_.pop_back();
    }
  ready_.push_back(std::move(slot));
}

void FrameFeed::read() {
  // With a finisher, the frame after this one is loaded on a helper thread while this one waits
  // for its time and is finished, as a camera's driver decodes the next image while the consumer
  // works on this one: the reader then spends the longer of the two on a frame, not their sum
  // (measured in docs/crowd.md). Without one, loading is all the reader does.
  Slot next;  // frame k + 1, loaded by `loader` (declared first: it outlives the loader's jobs)
  bool next_posted = false;
  std::optional<Worker> loader;
  if (finish_) loader.emplace("mcslam-loader");
  for (std::size_t k = 0; k < timestamps_.size(); ++k) {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      const std::optional<std::size_t> next = next_to_read(lock, k);
      if (!next) break;
      k = *next;
    }
    Slot slot;
    if (next_posted) {
      loader->wait();  // load_slot() keeps a load's error in its slot: this does not throw
      next_posted = false;
      slot = std::move(next);                    // frame k + 1 of the iteration before
      if (slot.index != k) slot = load_slot(k);  // the reader was late and skipped it
    } else {
      slot = load_slot(k);
    }
    if (loader && !slot.error && k + 1 < timestamps_.size()) {
      loader->post([this, k, &next] { next = load_slot(k + 1); });
      next_posted = true;
    }
    std::unique_lock<std::mutex> lock(mutex_);
    if (!start_) start_ = Clock::now();  // the camera starts with its first frame
    if (options_.realtime && !slot.error) {
      slot.due_s = timestamps_[k] - timestamps_.front();
      changed_.wait_until(lock, due_at(k), [&] { return stop_; });
      if (stop_) break;
    } else {
      slot.due_s = clock_s();
    }
    const bool finishing = finish_ && !slot.error && (!finish_wanted_ || finish_wanted_());
    if (finishing && options_.realtime) {
      // A frame whose successor comes due before the loop took the one before is dropped
      // unfinished.
      const bool superseded = !wait_for_loop(lock, k);
      if (stop_) break;
      if (superseded) {
        dropped_.push_back(k);
        continue;
      }
    }
    if (finishing) {
      lock.unlock();
      try {
        finish_(slot.images);
      } catch (...) {
        slot.error = std::current_exception();
      }
      lock.lock();
      if (stop_) break;
    }
    slot.ready_s = std::max(clock_s(), slot.due_s);
    const bool error = slot.error != nullptr;
    publish(std::move(slot));
    lock.unlock();
    changed_.notify_all();
    if (error) break;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    finished_ = true;
  }
  changed_.notify_all();
}

std::optional<FedFrame> FrameFeed::next() {
  const auto begin = Clock::now();
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [&] { return !ready_.empty() || finished_; });
  if (ready_.empty()) return std::nullopt;
  Slot slot = std::move(ready_.front());
  ready_.pop_front();
  FedFrame frame;
  frame.index = slot.index;
  frame.images = std::move(slot.images);
  frame.due_s = slot.due_s;
  frame.ready_s = slot.ready_s;
  frame.dropped_before = dropped_.size() - dropped_reported_;
  dropped_reported_ = dropped_.size();
  lock.unlock();
  changed_.notify_all();
  if (slot.error) std::rethrow_exception(slot.error);
  frame.wait_ms = std::chrono::duration<double, std::milli>(Clock::now() - begin).count();
  return frame;
}

}  // namespace mcslam::app
