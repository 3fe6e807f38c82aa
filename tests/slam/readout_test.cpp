// camera.readout_time: auto: the readout-time estimator's Jacobian, and the estimate recovered
// by SLAM on small rolling-shutter renders of either readout direction.

#include "mcslam/slam/readout.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "mcslam/core/se3.hpp"
#include "mcslam/eval/metrics.hpp"
#include "mcslam/slam/readout_calibration.hpp"
#include "mcslam/slam/system.hpp"
#include "mcslam/synth/sequence.hpp"
#include "support/small_room.hpp"

namespace mcslam::slam {
namespace {

PinholeCamera small_camera() {
  PinholeCamera c;
  c.fx = c.fy = 262.5;
  c.cx = 159.5;
  c.cy = 119.5;
  c.width = 320;
  c.height = 240;
  return c;
}

TEST(ReadoutJacobian, MatchesNumericDifferences) {
  const PinholeCamera camera = small_camera();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3d p_a(u(rng), 0.7 * u(rng), 2.5 + u(rng));
    const SE3 T_b_a(so3_exp(Eigen::Vector3d(0.1 * u(rng), 0.1 * u(rng), 0.1 * u(rng))),
                    Eigen::Vector3d(0.05 * u(rng), 0.05 * u(rng), 0.05 * u(rng)));
    CameraTwist motion, motion_a;
    motion.omega = Eigen::Vector3d(1.5 * u(rng), 1.5 * u(rng), 1.5 * u(rng));
    motion.nu = Eigen::Vector3d(u(rng), u(rng), u(rng));
    motion_a.omega = Eigen::Vector3d(1.5 * u(rng), 1.5 * u(rng), 1.5 * u(rng));
    motion_a.nu = Eigen::Vector3d(u(rng), u(rng), u(rng));
    const double v = 120.0 + 110.0 * u(rng);
    const double s = (v - 0.5 * camera.height) / camera.height;
    const double s_a = 0.5 * u(rng);
    const Eigen::Vector3d q = T_b_a * p_a;
    // The residual: the keypoint (point q seen at row v) moved back over tau = s r by the
    // rotation and translation, minus the projection of the anchor's point moved back likewise
    // and then by the left perturbation xi = (t, theta) of frame b.
    const auto residual = [&](const Eigen::Matrix<double, 7, 1>& x) -> Eigen::Vector2d {
      const Eigen::Vector3d compensated =
          so3_exp(-motion.omega * s * x(6)) * q - motion.nu * s * x(6);
      const Eigen::Vector3d anchor =
          T_b_a * (so3_exp(-motion_a.omega * s_a * x(6)) * p_a - motion_a.nu * s_a * x(6));
      const Eigen::Vector3d moved = so3_exp(x.segment<3>(3)) * anchor + x.head<3>();
      return camera.project(compensated) - camera.project(moved);
    };
    const Eigen::Matrix<double, 2, 7> J =
        readout_jacobian(camera, T_b_a, p_a, s_a, motion_a, v, motion);
    for (int k = 0; k < 7; ++k) {
      Eigen::Matrix<double, 7, 1> d = Eigen::Matrix<double, 7, 1>::Zero();
      const double h = 1e-6;
      d(k) = h;
      const Eigen::Vector2d numeric = (residual(d) - residual(-d)) / (2.0 * h);
      EXPECT_NEAR((numeric - J.col(k)).norm(), 0.0, 1e-5 * (1.0 + numeric.norm()))
          << "column " << k << " trial " << trial;
    }
  }
}

TEST(ReadoutOptions, CheckRejectsBadValues) {
  ReadoutOptions o;
  EXPECT_FALSE(o.check());
  o.max_std = 0.0;
  EXPECT_TRUE(o.check());
  o = ReadoutOptions{};
  o.min_points = 3;
  EXPECT_TRUE(o.check());
  o = ReadoutOptions{};
  o.max_readout = 0.5;
  EXPECT_TRUE(o.check());
}

TEST(PinholeCamera, AcceptsNegativeReadoutTimes) {
  PinholeCamera c = small_camera();
  c.readout_time = -0.02;
  EXPECT_FALSE(c.check());
  c.readout_time = -0.2;
  EXPECT_TRUE(c.check());
}

/// SLAM with camera.readout_time: auto on a 320x240 render at speed 2 (up to ~60 deg/s) whose
/// rows are read over `readout` seconds (bottom to top when negative).
ReadoutReport estimate(double readout, int frames) {
  synth::SynthOptions o = test::small_room(frames);
  o.speed = 2.0;
  o.readout_time = readout;
  const synth::SyntheticSequence seq(o);
  PinholeCamera camera = seq.camera();
  camera.readout_time = 0.0;
  camera.readout_auto = true;
  SystemOptions options;
  options.sequential = true;
  System system(camera, options);
  int tracked = 0;
  for (int i = 0; i < seq.size(); ++i) {
    const synth::RenderedFrame f = seq.frame(i);
    tracked += system.process(f.rgb, f.depth, seq.timestamp(i)).state == TrackingState::kOk ? 1 : 0;
  }
  system.finish();
  const ReadoutReport r = system.readout_report();
  const eval::EvalReport ate = eval::evaluate(seq.groundtruth(), system.trajectory());
  std::printf(
      "readout %+.0f ms: estimated %+.2f +- %.2f ms from %d frames (%s), used %+.2f ms; "
      "%d/%d tracked, ATE %.1f mm\n",
      readout * 1e3, r.estimate * 1e3, r.std * 1e3, r.frames_used,
      r.confident ? "confident" : "not confident", r.readout_time * 1e3, tracked, seq.size(),
      ate.ate.translation.rmse * 1e3);
  return r;
}

class ReadoutRecovery : public ::testing::TestWithParam<double> {};

TEST_P(ReadoutRecovery, EstimateWithin3Ms) {
  const double readout = GetParam();
  // Measured: -18.98, +0.04, +10.41 and +29.83 ms for -20, 0, 10 and 30 ms, std 0.64-0.65 ms,
  // confident after 30 of the 83-84 frames used.
  const ReadoutReport r = estimate(readout, 90);
  EXPECT_TRUE(r.automatic);
  EXPECT_GE(r.frames_used, 30);
  EXPECT_NEAR(r.estimate, readout, 0.003);
  EXPECT_TRUE(r.confident);
  // Compensation uses the estimate only when it is significantly non-zero.
  if (readout == 0.0)
    EXPECT_NEAR(r.readout_time, 0.0, 0.003);
  else
    EXPECT_NEAR(r.readout_time, readout, 0.003);
}

INSTANTIATE_TEST_SUITE_P(Readouts, ReadoutRecovery, ::testing::Values(-0.02, 0.0, 0.01, 0.03),
                         [](const ::testing::TestParamInfo<double>& info) {
                           const int ms = static_cast<int>(std::lround(info.param * 1000.0));
                           return (ms < 0 ? "minus" : "plus") + std::to_string(std::abs(ms)) + "ms";
                         });

/// ATE (m) of SLAM with a fixed readout on a render read over `true_readout`.
double ate_with_fixed(const synth::SyntheticSequence& seq, double readout) {
  PinholeCamera camera = seq.camera();
  camera.readout_time = readout;
  SystemOptions options;
  options.sequential = true;
  System system(camera, options);
  for (int i = 0; i < seq.size(); ++i) {
    const synth::RenderedFrame f = seq.frame(i);
    system.process(f.rgb, f.depth, seq.timestamp(i));
  }
  system.finish();
  return eval::evaluate(seq.groundtruth(), system.trajectory()).ate.translation.rmse;
}

// The calibration pass from a start of the wrong sign (a preset's +20 ms on a camera that reads
// bottom to top): it finds the readout, and a run from it is no worse than no compensation.
TEST(ReadoutCalibration, FindsTheReadoutFromAWrongStart) {
  synth::SynthOptions o = test::small_room(90);
  o.speed = 2.0;
  o.readout_time = -0.02;
  const synth::SyntheticSequence seq(o);
  PinholeCamera camera = seq.camera();
  camera.readout_time = 0.02;
  camera.readout_auto = true;
  const auto frame = [&](std::size_t k) {
    const synth::RenderedFrame f = seq.frame(static_cast<int>(k));
    return RecordedFrame{f.rgb, f.depth, seq.timestamp(static_cast<int>(k)), std::nullopt};
  };
  const ReadoutCalibration c =
      calibrate_readout(camera, SystemOptions{}, static_cast<std::size_t>(seq.size()), frame);
  const double ate_calibrated = ate_with_fixed(seq, c.readout_time);
  const double ate_none = ate_with_fixed(seq, 0.0);
  std::printf(
      "calibration: %+.2f +- %.2f ms after %d frames (%.2f s); ATE %.1f mm, without "
      "compensation %.1f mm\n",
      c.readout_time * 1e3, c.report.std * 1e3, c.frames, c.sequence_s, ate_calibrated * 1e3,
      ate_none * 1e3);
  EXPECT_TRUE(c.report.confident);
  // It stops once confident (30 turning frames), well before the sequence's end.
  EXPECT_LT(c.frames, seq.size());
  EXPECT_NEAR(c.readout_time, -0.02, 0.003);
  EXPECT_LE(ate_calibrated, ate_none);
}

TEST(ReadoutCalibration, StopsAfterCalibrationSeconds) {
  synth::SynthOptions o = test::small_room(40);
  const synth::SyntheticSequence seq(o);
  PinholeCamera camera = seq.camera();
  camera.readout_time = 0.015;
  SystemOptions options;
  options.readout.calibration_seconds = 0.5;
  const auto frame = [&](std::size_t k) {
    const synth::RenderedFrame f = seq.frame(static_cast<int>(k));
    return RecordedFrame{f.rgb, f.depth, seq.timestamp(static_cast<int>(k)), std::nullopt};
  };
  const ReadoutCalibration c =
      calibrate_readout(camera, options, static_cast<std::size_t>(seq.size()), frame);
  // 0.5 s at the render's frame rate, and no confident estimate from so few frames: the run
  // then starts from the configured value.
  EXPECT_LE(c.sequence_s, 0.5);
  EXPECT_LT(c.frames, seq.size());
  EXPECT_FALSE(c.report.confident);
  EXPECT_DOUBLE_EQ(c.readout_time, 0.015);
}

}  // namespace
}  // namespace mcslam::slam
