#pragma once
// Pose-only optimisation of one frame against fixed world points, lines and planes, and the
// features of constrained moving objects (constraint_residual.hpp): Levenberg-Marquardt on the
// pose's tangent (pose_solver.hpp) under a Huber loss, in rounds of outlier rejection by a
// chi-square test, as ORB-SLAM2's PoseOptimization.

#include <optional>
#include <string>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/optim/constraint_residual.hpp"
#include "mcslam/optim/line_residual.hpp"
#include "mcslam/optim/plane_residual.hpp"
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
  /// Lines: 2 dof (the two endpoint distances); planes: 3 dof.
  double chi2_line = 5.991;
  double chi2_plane = 7.815;
  /// Constrained moving-object points (9) and lines (10): 1 dof each.
  double chi2_constraint = 3.841;
  std::optional<std::string> check() const;
};

struct PoseObservation {
  Eigen::Vector3d p_w = Eigen::Vector3d::Zero();
  PointMeasurement measurement;
};

struct PoseLineObservation {
  Eigen::Vector3d start_w = Eigen::Vector3d::Zero();
  Eigen::Vector3d end_w = Eigen::Vector3d::Zero();
  LineMeasurement measurement;
};

struct PosePlaneObservation {
  Eigen::Vector4d plane_w = Eigen::Vector4d(0.0, 0.0, 1.0, 1.0);  // [n, d], |n| = 1
  PlaneMeasurement measurement;
};

/// Everything one frame observes of fixed landmarks, and of constrained moving objects.
struct PoseProblem {
  std::vector<PoseObservation> points;
  std::vector<PoseLineObservation> lines;
  std::vector<PosePlaneObservation> planes;
  /// Features of objects that slid on a plane (residuals (9), (10)). They fix only the height
  /// above and the tilt to their plane, so they are no substitute for the landmarks above.
  std::vector<ConstrainedPointMeasurement> constrained_points;
  std::vector<ConstrainedLineMeasurement> constrained_lines;
};

struct PoseOptimizationResult {
  SE3 T_c_w;
  std::vector<bool> inlier;  // per point observation
  std::vector<bool> line_inlier;
  std::vector<bool> plane_inlier;
  std::vector<bool> constrained_point_inlier;
  std::vector<bool> constrained_line_inlier;
  int num_inliers = 0;  // points
  int num_line_inliers = 0;
  int num_plane_inliers = 0;
  int num_constrained_point_inliers = 0;
  int num_constrained_line_inliers = 0;
  /// A round found no usable solution (its cost could not be evaluated at its start pose):
  /// T_c_w is the last usable pose (the initial one when the first round failed) and
  /// must not be taken for an optimised one.
  bool failed = false;
  /// Point observations left out of a round because the point was behind the camera (or within
  /// 1 micrometre of its centre) at that round's start pose; they are outliers of that round.
  int behind_camera = 0;
  /// The last round's J^T W J on the pose's tangent (se3_manifold.hpp): the pose's information.
  Matrix6d information = Matrix6d::Zero();
};

/// Optimises the pose against points, lines, planes and constrained moving-object features
/// together (residuals (6) to (10), cost (11)), each under a Huber loss at its own chi-square
/// threshold.
PoseOptimizationResult optimize_pose(const PinholeCamera& camera, const SE3& initial_T_c_w,
                                     const PoseProblem& problem,
                                     const PoseOptimizerOptions& options);

/// Points only.
PoseOptimizationResult optimize_pose(const PinholeCamera& camera, const SE3& initial_T_c_w,
                                     const std::vector<PoseObservation>& observations,
                                     const PoseOptimizerOptions& options);

}  // namespace mcslam::optim
