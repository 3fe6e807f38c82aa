#pragma once
// Pose-only optimisation of one frame against fixed world points (Ceres, Huber loss, rounds of
// outlier rejection by a chi-square test, as ORB-SLAM2's PoseOptimization).

#include <optional>
#include <string>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/optim/reprojection.hpp"

namespace mcslam::optim {

struct PoseOptimizerOptions {
  int rounds = 4;
  int iterations_per_round = 10;
  /// Rounds that use the Huber loss; later rounds are plain least squares on the inliers.
  int robust_rounds = 2;
  /// Chi-square thresholds at 95%: 3 dof (u, v, u_r) and 2 dof (u, v).
  double chi2_rgbd = 7.815;
  double chi2_mono = 5.991;
  std::optional<std::string> check() const;
};

struct PoseObservation {
  Eigen::Vector3d p_w = Eigen::Vector3d::Zero();
  PointMeasurement measurement;
};

struct PoseOptimizationResult {
  SE3 T_c_w;
  std::vector<bool> inlier;  // per observation
  int num_inliers = 0;
};

PoseOptimizationResult optimize_pose(const PinholeCamera& camera, const SE3& initial_T_c_w,
                                     const std::vector<PoseObservation>& observations,
                                     const PoseOptimizerOptions& options);

}  // namespace mcslam::optim
