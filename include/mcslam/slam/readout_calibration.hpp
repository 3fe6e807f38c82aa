#pragma once
// A calibration pass for camera.readout_time: auto. The estimator (readout.hpp) becomes
// confident after about a second of turning, and what the frames before that were compensated
// with stays in the map: starting from a wrong value (a preset's +20 ms on a camera that reads
// bottom to top) that first second costs more than no compensation. When the frames can be
// read twice (a recorded sequence), the pass tracks the sequence's start on its own, geometry
// only and mapping inline, until the estimate is confident; the run proper then starts from
// that estimate (and goes on refining it). A live camera cannot be replayed: there the
// estimate starts from the configured value.

#include <functional>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "mcslam/core/camera.hpp"
#include "mcslam/slam/options.hpp"
#include "mcslam/slam/readout.hpp"

namespace mcslam::slam {

/// One recorded frame's raw images (as System::process takes them) and capture times.
struct RecordedFrame {
  cv::Mat rgb;
  cv::Mat depth;
  double timestamp = 0.0;
  std::optional<double> depth_timestamp;
};

struct ReadoutCalibration {
  ReadoutReport report;     ///< the pass's estimator at its end
  int frames = 0;           ///< frames the pass tracked (or tried to)
  double sequence_s = 0.0;  ///< the span of the sequence it used (s)
  double wall_ms = 0.0;     ///< what it took
  /// The readout the run proper starts from: the pass's readout in use when it became
  /// confident (the estimate, or 0 when not significantly non-zero); otherwise the camera's.
  double readout_time = 0.0;
};

/// Tracks frames 0, 1, ... of `count` (read through `frame`, which may throw InputError) with a
/// system of `camera` (readout_auto) and `options` made geometry-only, inline and without loop
/// closing, until its readout estimate is confident or options.readout.calibration_seconds of
/// the sequence have passed.
ReadoutCalibration calibrate_readout(const PinholeCamera& camera, const SystemOptions& options,
                                     std::size_t count,
                                     const std::function<RecordedFrame(std::size_t)>& frame);

}  // namespace mcslam::slam
