#pragma once
// Pose-graph optimisation (loop closing's essential graph): keyframe poses T_c_w linked by
// relative-pose measurements. An edge (i, j) measures T_i_j = T_i * T_j^-1 (camera j in camera
// i); its residual is the 6-vector
//   r = [t_e; 2 * sign(w_e) * vec(q_e)] / sigma,   E = T_i_j_measured^-1 * T_i * T_j^-1,
// i.e. the translation and (to first order) the rotation vector of the discrepancy E, with the
// translation in metres over sigma_translation and the rotation in radians over sigma_rotation.
// RGB-D sees scale, so the graph is SE(3), not Sim(3).

#include <ceres/cost_function.h>

#include <optional>
#include <string>
#include <vector>

#include "mcslam/core/se3.hpp"

namespace mcslam::optim {

struct PoseGraphEdge {
  int i = 0;
  int j = 0;
  SE3 T_i_j;  // measured T_i * T_j^-1
  /// Scales both standard deviations (e.g. < 1 for loop edges found with many inliers).
  double weight = 1.0;
};

struct PoseGraphProblem {
  std::vector<SE3> poses;  // T_c_w
  std::vector<bool> fixed;
  std::vector<PoseGraphEdge> edges;
};

struct PoseGraphOptions {
  int iterations = 20;
  double sigma_translation = 0.01;  // metres
  double sigma_rotation = 0.01;     // radians
  int num_threads = 1;
  std::optional<std::string> check() const;
};

struct PoseGraphResult {
  int iterations = 0;
  double initial_cost = 0.0;
  double final_cost = 0.0;
  bool converged = false;
  /// Ceres found no usable solution: the problem's poses are left as they were given.
  bool failed = false;
};

/// The cost of one edge over two 7-double pose blocks (automatic derivatives); the caller owns it.
ceres::CostFunction* make_relative_pose_cost(const SE3& T_i_j, double sigma_translation,
                                             double sigma_rotation);
/// The residual of one edge, r(T_i, T_j) as above, with unit sigmas.
Vector6d pose_graph_residual(const SE3& T_i_j, const SE3& T_i, const SE3& T_j);

/// Optimises the poses that are not fixed, in place. Problems without a fixed pose get the
/// first one fixed (the graph has a gauge freedom).
PoseGraphResult optimize_pose_graph(PoseGraphProblem& problem, const PoseGraphOptions& options);

}  // namespace mcslam::optim
