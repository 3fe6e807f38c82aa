#include "mcslam/slam/readout_calibration.hpp"

#include <chrono>

#include "mcslam/slam/system.hpp"

namespace mcslam::slam {

ReadoutCalibration calibrate_readout(const PinholeCamera& camera, const SystemOptions& options,
                                     std::size_t count,
                                     const std::function<RecordedFrame(std::size_t)>& frame) {
  const auto start = std::chrono::steady_clock::now();
  PinholeCamera cam = camera;
  cam.readout_auto = true;
  SystemOptions o = options;
  o.sequential = true;
  o.place.loop.enabled = false;
  o.localize = false;
  ReadoutCalibration out;
  out.readout_time = camera.readout_time;
  System system(cam, o);
  double first = 0.0;
  for (std::size_t k = 0; k < count; ++k) {
    const RecordedFrame f = frame(k);
    if (k == 0) first = f.timestamp;
    if (f.timestamp - first > options.readout.calibration_seconds) break;
    system.process(f.rgb, f.depth, f.timestamp, f.depth_timestamp);
    ++out.frames;
    out.sequence_s = f.timestamp - first;
    if (system.readout_report().confident) break;
  }
  system.finish();
  out.report = system.readout_report();
  if (out.report.confident) out.readout_time = out.report.readout_time;
  out.wall_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace mcslam::slam
