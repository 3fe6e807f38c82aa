#pragma once
// Controls of a running `mcslam run` from outside its frame loop (the live viewer): pause and
// resume, and switching to localisation only (no new keyframes, the map is only read) and back.
// Any thread may ask; the frame loop applies the requests between two frames.

#include <condition_variable>
#include <cstddef>
#include <functional>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <vector>

namespace mcslam::app {

class RunControl {
 public:
  /// `localize`: the state the run starts in (--localize).
  explicit RunControl(bool localize = false)
      : localize_requested_(localize), localize_applied_(localize) {}
  void pause();
  void resume();
  /// A pause was asked for and not yet resumed.
  bool paused() const;
  /// The frame loop is waiting between two frames: no frame is in flight. After pause(), the
  /// frame being processed finishes first; only then does held() turn true.
  bool held() const;
  /// Asks for localisation only (true) or mapping (false) from the next frame on.
  void request_localize(bool on);
  /// The state asked for last (what the loop applies next, or has applied).
  bool localize_requested() const;
  /// Wakes a paused loop so that it sees `stop` (call after the stop was asked for).
  void wake();

  // The frame loop's side.
  /// Waits while paused, checking `stop` at least every 100 ms. Returns the milliseconds waited.
  double wait_while_paused(const std::function<bool()>& stop);
  /// The localisation state to switch to when it differs from the one applied last; the loop
  /// records the switch as made at frame `frame`.
  std::optional<bool> take_localize_change(std::size_t frame);
  /// summary.json "controls": pauses, seconds paused, the localisation switches.
  nlohmann::json summary() const;
  double paused_ms() const;

 private:
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  bool paused_ = false;
  bool held_ = false;
  bool localize_requested_ = false;
  bool localize_applied_ = false;
  int pauses_ = 0;
  double paused_ms_ = 0.0;
  std::vector<std::pair<std::size_t, bool>> switches_;  // (frame, localize)
};

}  // namespace mcslam::app
