#pragma once
// The consumers of each processed frame of `mcslam run` (output writers, the progress bar, the
// live viewer, the ROS publisher): the frame loop reads a frame, gives it to the System and
// hands the result to each observer in turn, on the loop's thread.

#include <cstddef>
#include <optional>

#include "mcslam/slam/system.hpp"

namespace mcslam::app {

/// One processed frame as the observers see it. Valid only during on_frame().
struct FrameEvent {
  const slam::FrameResult& result;
  const slam::PreparedImages& images;
  slam::System& system;
  double rgb_timestamp = 0.0;
  std::size_t done = 0;              ///< frames processed so far, this one included
  std::size_t offered = 0;           ///< frames taken or dropped so far (this one included)
  double wait_ms = 0.0;              ///< how long the loop waited for the frame (image_load)
  std::size_t dropped_before = 0;    ///< frames dropped just before this one (real time)
  std::optional<double> latency_ms;  ///< real time: from the frame's time to its pose
};

/// Observers run on the frame loop's thread and must return quickly: an observer that needs
/// time (encoding, network) hands the data to a thread of its own.
class FrameObserver {
 public:
  virtual ~FrameObserver() = default;
  virtual void on_frame(const FrameEvent& event) = 0;
  /// After the last frame (or a stop), before System::finish().
  virtual void on_stream_end(slam::System& /*system*/) {}
};

}  // namespace mcslam::app
