#include "mcslam/optim/trajectory_smoothing.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "mcslam/core/error.hpp"

namespace mcslam::optim {
namespace {

/// A camera walking a circle of 1 m radius at 0.3 m/s (centripetal acceleration 0.09 m/s^2),
/// turning about its own axis as it goes, one pose every `dt` seconds (or the gaps given).
Trajectory circle(const std::vector<double>& times) {
  Trajectory out;
  for (double t : times) {
    const double a = 0.3 * t;
    const Eigen::Vector3d p(std::cos(a), std::sin(a), 0.1 * std::sin(2.0 * a));
    const Eigen::Quaterniond q(
        Eigen::AngleAxisd(a + 0.2 * std::sin(5.0 * t), Eigen::Vector3d::UnitZ()));
    out.push_back({t, SE3(q, p)});
  }
  return out;
}

std::vector<double> regular_times(int n, double dt, double start = 0.0) {
  std::vector<double> times;
  for (int i = 0; i < n; ++i) times.push_back(start + i * dt);
  return times;
}

Trajectory add_noise(const Trajectory& truth, double sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma);
  Trajectory out = truth;
  for (StampedPose& pose : out) {
    const Eigen::Vector3d p =
        pose.T_w_c.translation() + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    pose.T_w_c = SE3::from_unit_quaternion(pose.T_w_c.quaternion(), p);
  }
  return out;
}

double rms_error(const Trajectory& a, const Trajectory& b) {
  double sum = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i)
    sum += (a[i].T_w_c.translation() - b[i].T_w_c.translation()).squaredNorm();
  return std::sqrt(sum / static_cast<double>(a.size()));
}

TEST(TrajectorySmoothing, EstimatesTheNoiseAndRemovesMostOfIt) {
  const Trajectory truth = circle(regular_times(900, 1.0 / 30.0));
  const Trajectory noisy = add_noise(truth, 0.003, 7);
  TrajectorySmoothingReport report;
  const Trajectory smoothed = smooth_trajectory(noisy, {}, &report);
  ASSERT_TRUE(report.applied);
  EXPECT_NEAR(report.position_noise, 0.003, 0.0004);
  EXPECT_EQ(report.segments, 1);
  const double before = rms_error(noisy, truth);
  const double after = rms_error(smoothed, truth);
  EXPECT_NEAR(before, 0.003 * std::sqrt(3.0), 0.0005);
  EXPECT_LT(after, 0.45 * before) << before << " -> " << after;
  // A Gaussian trajectory has few poses beyond 3 sigma of the path.
  EXPECT_LT(report.downweighted, 900 / 20);
}

TEST(TrajectorySmoothing, KeepsRotationsAndTimestamps) {
  const Trajectory truth = circle(regular_times(300, 1.0 / 30.0));
  const Trajectory noisy = add_noise(truth, 0.004, 3);
  const Trajectory smoothed = smooth_trajectory(noisy, {});
  ASSERT_EQ(smoothed.size(), noisy.size());
  for (std::size_t i = 0; i < noisy.size(); ++i) {
    EXPECT_EQ(smoothed[i].timestamp, noisy[i].timestamp);
    EXPECT_EQ(smoothed[i].T_w_c.quaternion().coeffs(), noisy[i].T_w_c.quaternion().coeffs());
  }
}

TEST(TrajectorySmoothing, LeavesAConstantVelocityPathWhereItIs) {
  Trajectory line;
  for (int i = 0; i < 200; ++i)
    line.push_back({i / 30.0, SE3(Eigen::Quaterniond::Identity(),
                                  Eigen::Vector3d(0.01 * i, -0.005 * i, 1.0))});
  TrajectorySmoothingReport report;
  const Trajectory smoothed = smooth_trajectory(line, {}, &report);
  ASSERT_TRUE(report.applied);
  EXPECT_LT(rms_error(smoothed, line), 1e-9);
}

TEST(TrajectorySmoothing, FollowsUnevenFrameIntervals) {
  // Frames dropped at random (1 to 3 frame intervals), as in a --realtime run.
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> step(1, 3);
  std::vector<double> times;
  double t = 0.0;
  for (int i = 0; i < 600; ++i, t += step(rng) / 30.0) times.push_back(t);
  const Trajectory truth = circle(times);
  const Trajectory noisy = add_noise(truth, 0.003, 5);
  TrajectorySmoothingReport report;
  const Trajectory smoothed = smooth_trajectory(noisy, {}, &report);
  EXPECT_NEAR(report.position_noise, 0.003, 0.0005);
  EXPECT_LT(rms_error(smoothed, truth), 0.55 * rms_error(noisy, truth));
}

TEST(TrajectorySmoothing, DoesNotSmoothAcrossAGapOrABreak) {
  // Two pieces of path half a metre apart: after a 2 s gap (time), or next to each other in
  // time but with a break (tracking lost between them).
  for (const bool gap : {true, false}) {
    std::vector<double> times = regular_times(100, 1.0 / 30.0);
    const std::vector<double> second = regular_times(100, 1.0 / 30.0, gap ? 5.0 : 100.0 / 30.0);
    times.insert(times.end(), second.begin(), second.end());
    Trajectory path = circle(times);
    for (std::size_t i = 100; i < path.size(); ++i)
      path[i].T_w_c = SE3::from_unit_quaternion(
          path[i].T_w_c.quaternion(), path[i].T_w_c.translation() + Eigen::Vector3d(0.5, 0, 0));
    const Trajectory noisy = add_noise(path, 0.002, 13);
    TrajectorySmoothingReport report;
    const std::vector<std::size_t> breaks =
        gap ? std::vector<std::size_t>{} : std::vector<std::size_t>{100};
    const Trajectory smoothed = smooth_trajectory(noisy, {}, &report, breaks);
    EXPECT_EQ(report.segments, 2) << (gap ? "gap" : "break");
    // The poses beside the jump stay on their own side of it.
    for (std::size_t i : {std::size_t{98}, std::size_t{99}, std::size_t{100}, std::size_t{101}})
      EXPECT_LT((smoothed[i].T_w_c.translation() - path[i].T_w_c.translation()).norm(), 0.01)
          << (gap ? "gap" : "break") << " pose " << i;
  }
}

TEST(TrajectorySmoothing, APoseFarOffThePathPullsItLessThanWithoutReweighting) {
  const Trajectory truth = circle(regular_times(300, 1.0 / 30.0));
  Trajectory noisy = add_noise(truth, 0.003, 17);
  for (std::size_t i = 150; i < 153; ++i)  // three frames dragged 10 cm sideways
    noisy[i].T_w_c = SE3::from_unit_quaternion(
        noisy[i].T_w_c.quaternion(), noisy[i].T_w_c.translation() + Eigen::Vector3d(0, 0, 0.1));
  TrajectorySmoothingOptions plain;
  plain.outlier_sigmas = 1e6;
  TrajectorySmoothingReport report;
  const Trajectory robust = smooth_trajectory(noisy, {}, &report);
  const Trajectory least_squares = smooth_trajectory(noisy, plain);
  EXPECT_GE(report.downweighted, 3);
  double robust_error = 0.0, plain_error = 0.0;
  for (std::size_t i = 145; i < 158; ++i) {
    robust_error += (robust[i].T_w_c.translation() - truth[i].T_w_c.translation()).norm();
    plain_error += (least_squares[i].T_w_c.translation() - truth[i].T_w_c.translation()).norm();
  }
  EXPECT_LT(robust_error, 0.6 * plain_error);
}

TEST(TrajectorySmoothing, ReturnsTheInputWhenOffOrTooShort) {
  const Trajectory noisy = add_noise(circle(regular_times(100, 1.0 / 30.0)), 0.003, 1);
  TrajectorySmoothingOptions off;
  off.enabled = false;
  TrajectorySmoothingReport report;
  EXPECT_EQ(rms_error(smooth_trajectory(noisy, off, &report), noisy), 0.0);
  EXPECT_FALSE(report.applied);
  const Trajectory short_path(noisy.begin(), noisy.begin() + kMinSecondDifferences + 1);
  EXPECT_EQ(rms_error(smooth_trajectory(short_path, {}, &report), short_path), 0.0);
  EXPECT_FALSE(report.applied);
  EXPECT_TRUE(smooth_trajectory({}, {}, &report).empty());
}

TEST(TrajectorySmoothing, RejectsBadOptions) {
  EXPECT_FALSE(TrajectorySmoothingOptions{}.check());
  for (int k = 0; k < 4; ++k) {
    TrajectorySmoothingOptions o;
    if (k == 0) o.acceleration_density = 0.0;
    if (k == 1) o.outlier_sigmas = -1.0;
    if (k == 2) o.max_gap = std::nan("");
    if (k == 3) o.iterations = 0;
    EXPECT_TRUE(o.check()) << k;
    EXPECT_THROW(smooth_trajectory({}, o), InputError) << k;
  }
}

}  // namespace
}  // namespace mcslam::optim
