// End-to-end: SLAM on a rolling-shutter synthetic sequence, with and without compensating the
// readout (PinholeCamera::readout_time).

#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <utility>
#include <vector>

#include "mcslam/eval/metrics.hpp"
#include "mcslam/slam/system.hpp"
#include "mcslam/synth/sequence.hpp"

namespace mcslam::slam {
namespace {

constexpr double kReadout = 0.03;

struct RollingSequence {
  std::vector<synth::RenderedFrame> frames;
  Trajectory groundtruth;
  PinholeCamera camera;
};

/// 120 frames at speed 3 (up to ~90 deg/s), Kinect-like depth noise, rows read over 30 ms.
const RollingSequence& rolling_sequence() {
  static const RollingSequence sequence = [] {
    synth::SynthOptions o;
    o.frames = 120;
    o.speed = 3.0;
    o.depth_noise = true;
    o.readout_time = kReadout;
    const synth::SyntheticSequence seq(o);
    RollingSequence s;
    for (int i = 0; i < seq.size(); ++i) s.frames.push_back(seq.frame(i));
    s.groundtruth = seq.groundtruth();
    s.camera = seq.camera();
    return s;
  }();
  return sequence;
}

struct ShutterRun {
  int tracked = 0;
  eval::EvalReport report;
  eval::EvalReport online;
};

ShutterRun run(const RollingSequence& seq, double readout_time, bool refine = true) {
  PinholeCamera camera = seq.camera;
  camera.readout_time = readout_time;
  SystemOptions options;
  options.sequential = true;
  options.tracker.refine_rolling_shutter = refine;
  System system(camera, options);
  ShutterRun r;
  for (std::size_t i = 0; i < seq.frames.size(); ++i) {
    const FrameResult fr =
        system.process(seq.frames[i].rgb, seq.frames[i].depth, seq.groundtruth[i].timestamp);
    r.tracked += fr.state == TrackingState::kOk ? 1 : 0;
  }
  system.finish();
  r.report = eval::evaluate(seq.groundtruth, system.trajectory());
  r.online = eval::evaluate(seq.groundtruth, system.online_trajectory());
  return r;
}

/// Each run once per process: the tests run as one ctest group (tests/slam/CMakeLists.txt) and
/// share the compensated, refined run.
const ShutterRun& shared_run(double readout_time, bool refine = true) {
  static std::map<std::pair<double, bool>, ShutterRun> runs;
  const auto key = std::make_pair(readout_time, refine);
  auto it = runs.find(key);
  if (it == runs.end()) it = runs.emplace(key, run(rolling_sequence(), readout_time, refine)).first;
  return it->second;
}

TEST(RollingShutter, CompensationLowersTheTrajectoryErrorOnFastRotation) {
  const RollingSequence& seq = rolling_sequence();
  ASSERT_EQ(seq.camera.readout_time, kReadout);
  const ShutterRun& plain = shared_run(0.0);
  const ShutterRun& compensated = shared_run(kReadout);
  const double ate_plain = plain.report.ate.translation.rmse;
  const double ate_compensated = compensated.report.ate.translation.rmse;
  std::printf(
      "rolling shutter %.0f ms, speed 3: ATE %.2f mm without compensation (%d/%zu tracked), "
      "%.2f mm with compensation (%d/%zu tracked)\n",
      1000.0 * kReadout, 1000.0 * ate_plain, plain.tracked, seq.frames.size(),
      1000.0 * ate_compensated, compensated.tracked, seq.frames.size());
  // Measured: 102 mm without, 23.4 mm with compensation, 120/120 tracked both ways (the same path
  // with a global shutter: 2.6 mm). Where the camera turns livelier than the pose filter's
  // densities (they are lifted) the keypoints are moved with the last two steps' rate; with the
  // filter's rate at every frame, which lags such a camera, 61 mm. The residual comes mostly from
  // what the keypoint correction leaves out: the translation during the readout (up to 2 m/s here)
  // and the error of the angular velocity it uses (predicted from the frames before, refined where
  // the frame's own shear says it is wrong: the next test).
  EXPECT_GE(plain.tracked, 114);
  EXPECT_GE(compensated.tracked, 114);
  EXPECT_LT(ate_compensated, 0.5 * ate_plain) << "without:\n"
                                              << eval::to_text(plain.report) << "with:\n"
                                              << eval::to_text(compensated.report);
  EXPECT_LT(ate_compensated, 0.045) << eval::to_text(compensated.report);
}

TEST(RollingShutter, TheFramesOwnShearCorrectsThePredictedAngularVelocity) {
  // The keypoints are moved with the angular velocity of the last frames; the camera's turn
  // changes faster than that (and the second frame has none): tracker.refine_rolling_shutter
  // estimates the error from each frame's own shear and solves its pose again.
  const ShutterRun& predicted = shared_run(kReadout, false);
  const ShutterRun& refined = shared_run(kReadout, true);
  std::printf(
      "ATE %.2f mm (online %.2f mm, RPE over one frame %.2f mm) with the predicted angular "
      "velocity; %.2f mm (%.2f mm, %.2f mm) refined from each frame's shear\n",
      1e3 * predicted.report.ate.translation.rmse, 1e3 * predicted.online.ate.translation.rmse,
      1e3 * predicted.online.rpe_frame.translation.rmse, 1e3 * refined.report.ate.translation.rmse,
      1e3 * refined.online.ate.translation.rmse, 1e3 * refined.online.rpe_frame.translation.rmse);
  // Measured: online ATE 32.5 -> 30.6 mm, trajectory.txt 24.8 -> 23.4 mm (docs/rolling-shutter.md).
  // The refinement changes each frame's pose, which is what the online figures score; the final
  // trajectory is the bundle adjustment's, which averages much of a frame's shear error out over
  // the keyframes that see a point. Frame to frame the refined poses are rougher here (RPE over
  // one frame 7.7 -> 9.9 mm): on this render the refined rate is further from the truth than the
  // predicted one, and the filter smooths the predicted rate's steadier poses better.
  EXPECT_GE(refined.tracked, predicted.tracked);
  EXPECT_LT(refined.online.ate.translation.rmse, 0.97 * predicted.online.ate.translation.rmse);
  EXPECT_LT(refined.online.rpe_frame.translation.rmse,
            1.4 * predicted.online.rpe_frame.translation.rmse);
  EXPECT_LT(refined.report.ate.translation.rmse, predicted.report.ate.translation.rmse);
}

}  // namespace
}  // namespace mcslam::slam
