#include "mcslam/optim/pose_noise.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>

namespace mcslam::optim {
namespace {

constexpr double kFrameInterval = 1.0 / 30.0;

/// A handheld camera: the centre swings at up to 0.4 m/s, the camera turns at up to 1 rad/s,
/// both changing smoothly (accelerations about 1 m/s^2 and 2 rad/s^2).
void handheld_pose_at(double t, Eigen::Matrix3d& R_c_w, Eigen::Vector3d& c) {
  c = Eigen::Vector3d(0.2 * std::sin(2.0 * t), 0.05 * std::sin(3.0 * t), 0.1 * t);
  R_c_w = (Eigen::AngleAxisd(0.5 * std::sin(2.0 * t), Eigen::Vector3d::UnitY()) *
           Eigen::AngleAxisd(0.2 * std::sin(1.5 * t), Eigen::Vector3d::UnitX()))
              .toRotationMatrix()
              .transpose();
}

/// A covariance on [dc; dtheta] with a loose direction (a shift along x against a turn about
/// y), as a frame's pose has it: 0.6 mm and 0.5 mrad, 4 mm along the valley.
Matrix6d frame_covariance() {
  Vector6d u;
  u << 1.0, 0.0, 0.0, 0.0, -1.0, 0.0;
  u.normalize();
  Matrix6d cov = Matrix6d::Identity() * 0.0006 * 0.0006;
  cov.block<3, 3>(3, 3) = Eigen::Matrix3d::Identity() * 0.0005 * 0.0005;
  cov += 0.004 * 0.004 * u * u.transpose();
  return cov;
}

struct NoiseFeed {
  double stamp_jitter = 0.0;  ///< seconds, uniform +- about the 30 Hz grid
  double noise_factor = 1.0;  ///< the noise's sigma over the claimed covariance's
  double outliers = 0.0;      ///< share of frames off by 20 sigma
};

/// Feeds `frames` poses of handheld_pose_at with noise noise_factor^2 * claimed and returns the
/// estimate.
double estimate_factor(int frames, unsigned seed, const NoiseFeed& feed, PoseNoiseEstimate& noise) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  const Matrix6d cov = frame_covariance();
  const Matrix6d L = cov.llt().matrixL();
  const Matrix6d information = cov.inverse();
  for (int k = 0; k < frames; ++k) {
    const double t = 5.0 + k * kFrameInterval + feed.stamp_jitter * uniform(rng);
    Eigen::Matrix3d R;
    Eigen::Vector3d c;
    handheld_pose_at(t, R, c);
    Vector6d n;
    for (int i = 0; i < 6; ++i) n(i) = normal(rng);
    double f = feed.noise_factor;
    if (feed.outliers > 0.0 && std::abs(uniform(rng)) < feed.outliers) f *= 20.0;
    const Vector6d e = f * (L * n);
    const Eigen::Vector3d dtheta = e.tail<3>();
    noise.add(t, so3_exp(dtheta).toRotationMatrix() * R, c + e.head<3>(), information);
  }
  return noise.variance_factor();
}

TEST(PoseNoise, ThirdDifferencesVanishOnAnyQuadraticWhateverTheSpacing) {
  const auto even = third_difference_coefficients({0.0, 1.0, 2.0, 3.0});
  ASSERT_TRUE(even);
  EXPECT_NEAR((*even - Eigen::Vector4d(-1.0, 3.0, -3.0, 1.0)).norm(), 0.0, 1e-12);
  const Eigen::Vector4d t(10.0, 10.031, 10.068, 10.099);  // stamps 31, 37, 31 ms apart
  const auto a = third_difference_coefficients(t);
  ASSERT_TRUE(a);
  for (int power = 0; power <= 2; ++power)
    EXPECT_NEAR(a->dot(t.array().pow(power).matrix()), 0.0, 1e-6) << "power " << power;
  // A cubic keeps its third derivative: 6 h^3 for t^3 with the mean spacing h.
  const double h = (t[3] - t[0]) / 3.0;
  EXPECT_NEAR(a->dot(t.array().pow(3).matrix()), 6.0 * h * h * h, 1e-9);
  EXPECT_FALSE(third_difference_coefficients({1.0, 1.0, 2.0, 3.0}));
  EXPECT_FALSE(third_difference_coefficients({1.0, 1.0, 1.0, 1.0}));
}

TEST(PoseNoise, FindsTheFactorByWhichTheCovarianceUnderstatesTheNoise) {
  for (const double factor : {1.0, 3.0, 8.0}) {
    PoseNoiseEstimate noise(1.0);
    NoiseFeed feed;
    feed.noise_factor = factor;
    feed.stamp_jitter = 0.002;
    const double found = estimate_factor(300, 11, feed, noise);
    // 30 differences in the window: the median's spread is about a quarter of the value.
    EXPECT_GT(found, 0.6 * factor * factor) << factor;
    EXPECT_LT(found, 1.6 * factor * factor) << factor;
    EXPECT_NEAR(static_cast<double>(noise.values()), 30.0, 1.0);  // a second at 30 Hz
  }
}

TEST(PoseNoise, TheCamerasOwnMotionDoesNotCountAsNoise) {
  // Far less noise than claimed (a render's keypoints): the path's accelerations, which a
  // second difference would count, leave the third differences at the noise's level.
  PoseNoiseEstimate noise(1.0);
  NoiseFeed feed;
  feed.noise_factor = 0.3;
  const double found = estimate_factor(300, 12, feed, noise);
  EXPECT_LT(found, 0.3);
}

TEST(PoseNoise, AFewFramesFarOffDoNotMoveTheEstimate) {
  PoseNoiseEstimate clean(1.0), dirty(1.0);
  NoiseFeed feed;
  feed.noise_factor = 2.0;
  const double without = estimate_factor(300, 13, feed, clean);
  feed.outliers = 0.03;
  const double with = estimate_factor(300, 13, feed, dirty);
  // 3 % of the frames 20 sigma off spoil 12 % of the differences (each frame enters four):
  // the median moves by a fraction of its own spread, a mean would move 50-fold.
  EXPECT_LT(with, 1.5 * without);
}

TEST(PoseNoise, StartsItsDifferencesAgainAfterABreakAndKeepsItsValues) {
  PoseNoiseEstimate noise(10.0);
  const Matrix6d information = frame_covariance().inverse();
  Eigen::Matrix3d R;
  Eigen::Vector3d c;
  for (int k = 0; k < 12; ++k) {
    handheld_pose_at(k * kFrameInterval, R, c);
    noise.add(k * kFrameInterval, R, c, information);
  }
  EXPECT_EQ(noise.values(), 9u);
  const double before = noise.variance_factor();
  // After a break, a pose 1 m away (a relocalisation) enters no difference with the ones before.
  noise.break_sequence();
  for (int k = 0; k < 3; ++k) {
    handheld_pose_at(1.0 + k * kFrameInterval, R, c);
    noise.add(1.0 + k * kFrameInterval, R, c + Eigen::Vector3d(1.0, 0.0, 0.0), information);
  }
  EXPECT_EQ(noise.values(), 9u);
  EXPECT_DOUBLE_EQ(noise.variance_factor(), before);
  // Values older than the window leave it (after a gap, which breaks the sequence too).
  noise.break_sequence();
  handheld_pose_at(20.0, R, c);
  noise.add(20.0, R, c, information);
  EXPECT_EQ(noise.values(), 0u);
  EXPECT_DOUBLE_EQ(noise.variance_factor(), 1.0);  // too few values: the covariance as it is
}

// A map moved under the tracker moves the poses kept for the differences: the next pose, in the
// moved world, continues them as if nothing had moved.
TEST(PoseNoise, FollowsTheWorldWhenTheMapMoves) {
  const Matrix6d information = frame_covariance().inverse();
  const SE3 W = SE3::exp((Vector6d() << 0.2, -0.1, 0.05, 0.1, -0.2, 0.3).finished());
  PoseNoiseEstimate moved(1.0), still(1.0);
  Eigen::Matrix3d R;
  Eigen::Vector3d c;
  for (int k = 0; k < 12; ++k) {
    handheld_pose_at(k * kFrameInterval, R, c);
    still.add(k * kFrameInterval, R, c, information);
    if (k == 6) moved.move_world(W);
    if (k < 6) {
      moved.add(k * kFrameInterval, R, c, information);
    } else {
      // The same pose in the moved world: centre W c, R_c_w R_W^T; its information on the
      // centre turned with the world.
      Matrix6d J = Matrix6d::Identity();
      J.block<3, 3>(0, 0) = W.rotation();
      moved.add(k * kFrameInterval, R * W.rotation().transpose(), W * c,
                J * information * J.transpose());
    }
  }
  EXPECT_EQ(moved.values(), still.values());
  EXPECT_NEAR(moved.variance_factor(), still.variance_factor(), 1e-6);
}

TEST(PoseNoise, APoseWithoutAFiniteInformationBreaksTheSequence) {
  PoseNoiseEstimate noise(1.0);
  Matrix6d information = frame_covariance().inverse();
  Eigen::Matrix3d R;
  Eigen::Vector3d c;
  for (int k = 0; k < 3; ++k) {
    handheld_pose_at(k * kFrameInterval, R, c);
    noise.add(k * kFrameInterval, R, c, information);
  }
  information(0, 0) = std::numeric_limits<double>::quiet_NaN();
  handheld_pose_at(3 * kFrameInterval, R, c);
  noise.add(3 * kFrameInterval, R, c, information);
  EXPECT_EQ(noise.values(), 0u);
}

}  // namespace
}  // namespace mcslam::optim
