#include "mcslam/optim/pose_graph.hpp"

#include <ceres/autodiff_cost_function.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <cmath>

#include "mcslam/core/error.hpp"
#include "mcslam/optim/se3_manifold.hpp"

namespace mcslam::optim {
namespace {

/// Pose blocks are [qx, qy, qz, qw, tx, ty, tz] of T_c_w (se3_manifold.hpp).
struct RelativePoseCost {
  RelativePoseCost(const SE3& T_i_j, double inv_sigma_t, double inv_sigma_r)
      : inv_sigma_t(inv_sigma_t), inv_sigma_r(inv_sigma_r) {
    const SE3 inv = T_i_j.inverse();
    q_inv = inv.quaternion();
    t_inv = inv.translation();
  }

  template <typename T>
  bool operator()(const T* pose_i, const T* pose_j, T* residual) const {
    using Quat = Eigen::Quaternion<T>;
    using Vec3 = Eigen::Matrix<T, 3, 1>;
    const Quat qi(pose_i[3], pose_i[0], pose_i[1], pose_i[2]);
    const Quat qj(pose_j[3], pose_j[0], pose_j[1], pose_j[2]);
    const Vec3 ti(pose_i[4], pose_i[5], pose_i[6]);
    const Vec3 tj(pose_j[4], pose_j[5], pose_j[6]);
    // T_i * T_j^-1 = (qi qj^-1, ti - qi qj^-1 tj)
    const Quat qj_inv = qj.conjugate();
    const Quat q_ij = qi * qj_inv;
    const Vec3 t_ij = ti - q_ij * tj;
    // E = measured^-1 * (T_i T_j^-1)
    const Quat q_m = q_inv.cast<T>();
    const Quat q_e = q_m * q_ij;
    const Vec3 t_e = q_m * t_ij + t_inv.cast<T>();
    const T sign = q_e.w() < T(0) ? T(-1) : T(1);
    for (int k = 0; k < 3; ++k) {
      residual[k] = t_e[k] * T(inv_sigma_t);
      residual[3 + k] = T(2) * sign * q_e.vec()[k] * T(inv_sigma_r);
    }
    return true;
  }

  Eigen::Quaterniond q_inv;
  Eigen::Vector3d t_inv;
  double inv_sigma_t;
  double inv_sigma_r;
};

}  // namespace

std::optional<std::string> PoseGraphOptions::check() const {
  if (iterations < 1) return "pose graph: iterations must be at least 1";
  if (!(sigma_translation > 0.0) || !(sigma_rotation > 0.0))
    return "pose graph: sigmas must be positive";
  if (num_threads < 1) return "pose graph: num_threads must be at least 1";
  return std::nullopt;
}

ceres::CostFunction* make_relative_pose_cost(const SE3& T_i_j, double sigma_translation,
                                             double sigma_rotation) {
  return new ceres::AutoDiffCostFunction<RelativePoseCost, 6, kPoseSize, kPoseSize>(
      new RelativePoseCost(T_i_j, 1.0 / sigma_translation, 1.0 / sigma_rotation));
}

Vector6d pose_graph_residual(const SE3& T_i_j, const SE3& T_i, const SE3& T_j) {
  const RelativePoseCost cost(T_i_j, 1.0, 1.0);
  double bi[kPoseSize], bj[kPoseSize];
  pose_to_block(T_i, bi);
  pose_to_block(T_j, bj);
  Vector6d r;
  cost(bi, bj, r.data());
  return r;
}

PoseGraphResult optimize_pose_graph(PoseGraphProblem& problem, const PoseGraphOptions& options) {
  if (auto e = options.check()) throw InputError(*e);
  PoseGraphResult result;
  const std::size_t n = problem.poses.size();
  if (n == 0 || problem.edges.empty()) return result;
  problem.fixed.resize(n, false);
  bool any_fixed = false;
  for (bool f : problem.fixed) any_fixed = any_fixed || f;
  if (!any_fixed) problem.fixed[0] = true;

  std::vector<double> blocks(n * kPoseSize);
  for (std::size_t k = 0; k < n; ++k) pose_to_block(problem.poses[k], &blocks[k * kPoseSize]);
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem ceres_problem(problem_options);
  SE3Manifold manifold;
  std::vector<bool> used(n, false);
  for (const PoseGraphEdge& e : problem.edges) {
    if (e.i < 0 || e.j < 0 || static_cast<std::size_t>(e.i) >= n ||
        static_cast<std::size_t>(e.j) >= n || e.i == e.j || !(e.weight > 0.0))
      continue;
    auto* cost = make_relative_pose_cost(e.T_i_j, options.sigma_translation * e.weight,
                                         options.sigma_rotation * e.weight);
    ceres_problem.AddResidualBlock(cost, nullptr,
                                   &blocks[static_cast<std::size_t>(e.i) * kPoseSize],
                                   &blocks[static_cast<std::size_t>(e.j) * kPoseSize]);
    used[static_cast<std::size_t>(e.i)] = used[static_cast<std::size_t>(e.j)] = true;
  }
  for (std::size_t k = 0; k < n; ++k) {
    if (!used[k]) continue;
    double* block = &blocks[k * kPoseSize];
    ceres_problem.SetManifold(block, &manifold);
    if (problem.fixed[k]) ceres_problem.SetParameterBlockConstant(block);
  }
  if (ceres_problem.NumResidualBlocks() == 0) return result;
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE)
                                  ? ceres::SPARSE_NORMAL_CHOLESKY
                                  : ceres::DENSE_NORMAL_CHOLESKY;
  solver.max_num_iterations = options.iterations;
  solver.num_threads = options.num_threads;
  solver.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &ceres_problem, &summary);
  result.iterations = static_cast<int>(summary.iterations.size());
  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;
  result.converged = summary.termination_type == ceres::CONVERGENCE;
  result.failed = !summary.IsSolutionUsable();
  if (result.failed) return result;
  for (std::size_t k = 0; k < n; ++k)
    if (used[k] && !problem.fixed[k]) problem.poses[k] = block_to_pose(&blocks[k * kPoseSize]);
  return result;
}

}  // namespace mcslam::optim
