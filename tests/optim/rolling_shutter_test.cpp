// optim/rolling_shutter.hpp: the keypoint's move under a correction of the angular velocity
// (against numeric differences), and the correction recovered from a frame's own shear.

#include "mcslam/optim/rolling_shutter.hpp"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "support/test_camera.hpp"

namespace mcslam::optim {
namespace {

TEST(AngularVelocityCorrection, TheKeypointsMoveMatchesNumericDifferences) {
  const PinholeCamera camera = test::make_camera();
  const double tau = row_time(camera, 420.0, 0.03);
  EXPECT_NEAR(tau, (420.0 - 240.0) / 480.0 * 0.03, 1e-12);
  for (const Eigen::Vector3d& d :
       {Eigen::Vector3d::Zero().eval(), Eigen::Vector3d(0.4, -0.7, 0.3).eval()}) {
    const Eigen::Vector2d uv(100.0, 420.0);
    Eigen::Matrix<double, 2, 3> J;
    const Eigen::Vector2d at = shutter_corrected_uv(camera, uv, tau, d, &J);
    for (int k = 0; k < 3; ++k) {
      const double h = 1e-6;
      const Eigen::Vector3d step = Eigen::Vector3d::Unit(k) * h;
      const Eigen::Vector2d numeric = (shutter_corrected_uv(camera, uv, tau, d + step) -
                                       shutter_corrected_uv(camera, uv, tau, d - step)) /
                                      (2.0 * h);
      // First order in the correction's step (see shutter_corrected_uv): exact at d = 0, and
      // within 1 % at a frame's angles.
      EXPECT_NEAR(J(0, k), numeric(0), 1e-6 + 0.01 * numeric.norm()) << k;
      EXPECT_NEAR(J(1, k), numeric(1), 1e-6 + 0.01 * numeric.norm()) << k;
    }
    if (d.isZero()) {
      EXPECT_TRUE(at.isApprox(uv, 1e-12));
    }
  }
}

/// A frame of `count` points seen by a rolling-shutter camera turning at `omega`, its keypoints
/// moved to the middle row's time with `omega0` (the prediction), with pixel noise.
PoseProblem sheared_frame(const PinholeCamera& camera, const SE3& T_c_w, double readout,
                          const Eigen::Vector3d& omega, const Eigen::Vector3d& omega0, int count,
                          DepthTerm depth_term, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, camera.width), v(0.0, camera.height);
  std::uniform_real_distribution<double> depth(1.0, 4.0);
  std::normal_distribution<double> noise(0.0, 0.5);
  PoseProblem problem;
  const SE3 T_w_c = T_c_w.inverse();
  while (static_cast<int>(problem.points.size()) < count) {
    // The point as the middle row's camera sees it, and the row that sees it: where the
    // camera, turned by omega * tau, images it (tau depends on that row: fixed point).
    const Eigen::Vector3d p_m = camera.unproject(Eigen::Vector2d(u(rng), v(rng)), depth(rng));
    Eigen::Vector2d raw = camera.project(p_m);
    for (int k = 0; k < 5; ++k) {
      const double tau = row_time(camera, raw.y(), readout);
      raw = camera.project(so3_exp(omega * tau).toRotationMatrix() * p_m);
    }
    if (!camera.in_image(raw)) continue;
    const double tau = row_time(camera, raw.y(), readout);
    const Eigen::Vector3d corrected =
        so3_exp(-omega0 * tau).toRotationMatrix() * camera.unproject(raw, 1.0);
    PoseObservation obs;
    obs.p_w = T_w_c * p_m;
    obs.measurement.uv = camera.project(corrected) + Eigen::Vector2d(noise(rng), noise(rng));
    obs.measurement.with_depth = true;
    obs.measurement.depth_term = depth_term;
    obs.measurement.u_right = camera.right_u(obs.measurement.uv.x(), p_m.z());
    obs.measurement.information = 1.0 / (0.5 * 0.5);
    obs.measurement.right_information = 1.0 / (0.5 * 0.5);
    problem.points.push_back(obs);
  }
  return problem;
}

void finds_the_shear(DepthTerm depth_term) {
  // A camera turning at 1.5 rad/s, 30 ms readout, predicted 0.5 rad/s wrong on each axis.
  const PinholeCamera camera = test::make_camera();
  const double readout = 0.03;
  const Eigen::Vector3d omega(0.3, 1.5, -0.4);
  const Eigen::Vector3d error(0.5, -0.5, 0.5);
  const SE3 T_c_w(so3_exp(Eigen::Vector3d(0.1, -0.2, 0.05)), Eigen::Vector3d(0.2, -0.1, 0.3));
  std::mt19937 rng(7);
  PoseProblem problem =
      sheared_frame(camera, T_c_w, readout, omega, omega - error, 300, depth_term, rng);
  PoseOptimizerOptions options;
  PoseOptimizationResult result = optimize_pose(camera, T_c_w, problem, options);
  const double before =
      (result.T_c_w.inverse().translation() - T_c_w.inverse().translation()).norm();
  // Passes as the tracker runs them: estimate, move the keypoints, solve the pose again.
  Eigen::Vector3d found = Eigen::Vector3d::Zero();
  std::vector<int> inliers;
  std::vector<double> chi2;
  for (int pass = 0; pass < 4; ++pass) {
    const AngularVelocityCorrection c = estimate_angular_velocity_correction(
        camera, problem, result.inlier, result.T_c_w, readout, 0.3);
    inliers.push_back(c.points);
    chi2.push_back(c.chi2);
    apply_angular_velocity_correction(camera, readout, c.d, problem);
    result = optimize_pose(camera, result.T_c_w, problem, options);
    found += c.d;
  }
  std::printf("chi-square of each pass's correction:");
  for (double c : chi2) std::printf(" %.1f", c);
  std::printf("\n");
  const double after =
      (result.T_c_w.inverse().translation() - T_c_w.inverse().translation()).norm();
  std::printf(
      "correction found %.3f %.3f %.3f (true %.1f %.1f %.1f); camera centre %.2f -> %.2f mm\n",
      found.x(), found.y(), found.z(), error.x(), error.y(), error.z(), before * 1e3, after * 1e3);
  // Measured: 0.492 -0.494 0.498; the inliers grow as the shear is taken out (71, 158, 255, 265
  // of 300 at the passes' start poses), the camera centre 3.86 -> 0.89 mm.
  EXPECT_LT((found - error).norm(), 0.1);
  EXPECT_GT(inliers.back(), 2 * inliers.front());
  EXPECT_GT(result.num_inliers, 250);
  // Significant (the tracker's test: chi-square, 3 dof, 95 %), and less so as it is taken out.
  EXPECT_GT(chi2.front(), 7.815);
  EXPECT_LT(chi2.back(), chi2.front());
  // With u_r the shear moves the pose (3.86 mm); the disparity row does not shear, and the pose
  // from it starts at 0.74 mm. Both end at the keypoints' noise (0.89 and 1.12 mm).
  if (depth_term == DepthTerm::kRightU) {
    EXPECT_LT(after, 0.5 * before);
  }
  EXPECT_LT(after, 0.0015);
}

// With either depth row (DepthTerm): u_r moves with the keypoints, the disparity does not.
TEST(AngularVelocityCorrection, TheAngularVelocitysErrorIsFoundFromTheFramesShear) {
  for (DepthTerm depth_term : {DepthTerm::kRightU, DepthTerm::kDisparity}) {
    SCOPED_TRACE(depth_term == DepthTerm::kRightU ? "u_r" : "disparity");
    finds_the_shear(depth_term);
  }
}

}  // namespace
}  // namespace mcslam::optim
