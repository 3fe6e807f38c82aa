#include "mcslam/app/run_control.hpp"

#include <chrono>

#include "mcslam/core/timing.hpp"

namespace mcslam::app {

void RunControl::pause() {
  std::lock_guard<std::mutex> lock(mutex_);
  pauses_ += paused_ ? 0 : 1;
  paused_ = true;
}

void RunControl::resume() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    paused_ = false;
  }
  changed_.notify_all();
}

bool RunControl::paused() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return paused_;
}

bool RunControl::held() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return held_;
}

void RunControl::request_localize(bool on) {
  std::lock_guard<std::mutex> lock(mutex_);
  localize_requested_ = on;
}

bool RunControl::localize_requested() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return localize_requested_;
}

void RunControl::wake() { changed_.notify_all(); }

double RunControl::wait_while_paused(const std::function<bool()>& stop) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (!paused_) return 0.0;
  Stopwatch watch;
  held_ = true;
  while (paused_ && !(stop && stop())) changed_.wait_for(lock, std::chrono::milliseconds(100));
  held_ = false;
  const double ms = watch.elapsed_ms();
  paused_ms_ += ms;
  return ms;
}

std::optional<bool> RunControl::take_localize_change(std::size_t frame) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (localize_requested_ == localize_applied_) return std::nullopt;
  localize_applied_ = localize_requested_;
  switches_.emplace_back(frame, localize_applied_);
  return localize_applied_;
}

double RunControl::paused_ms() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return paused_ms_;
}

nlohmann::json RunControl::summary() const {
  std::lock_guard<std::mutex> lock(mutex_);
  nlohmann::json switches = nlohmann::json::array();
  for (const auto& [frame, on] : switches_)
    switches.push_back({{"frame", frame}, {"localize", on}});
  return {{"pauses", pauses_},
          {"paused_s", paused_ms_ / 1000.0},
          {"localize_switches", switches},
          {"localize_at_end", localize_applied_}};
}

}  // namespace mcslam::app
