#include "mcslam/optim/pose_optimizer.hpp"

#include <ceres/loss_function.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <cmath>
#include <memory>

#include "mcslam/optim/se3_manifold.hpp"

namespace mcslam::optim {

std::optional<std::string> PoseOptimizerOptions::check() const {
  if (rounds < 1) return "pose_optimizer.rounds must be at least 1";
  if (iterations_per_round < 1) return "pose_optimizer.iterations_per_round must be at least 1";
  if (robust_rounds < 0) return "pose_optimizer.robust_rounds must not be negative";
  if (!(chi2_rgbd > 0.0) || !(chi2_mono > 0.0))
    return "pose_optimizer chi-square thresholds must be positive";
  return std::nullopt;
}

PoseOptimizationResult optimize_pose(const PinholeCamera& camera, const SE3& initial_T_c_w,
                                     const std::vector<PoseObservation>& observations,
                                     const PoseOptimizerOptions& options) {
  PoseOptimizationResult result;
  result.T_c_w = initial_T_c_w;
  result.inlier.assign(observations.size(), true);
  if (observations.empty()) return result;

  double pose[kPoseSize];
  pose_to_block(initial_T_c_w, pose);
  SE3Manifold manifold;
  ceres::HuberLoss huber_rgbd(std::sqrt(options.chi2_rgbd));
  ceres::HuberLoss huber_mono(std::sqrt(options.chi2_mono));

  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::DENSE_QR;
  solver_options.max_num_iterations = options.iterations_per_round;
  solver_options.logging_type = ceres::SILENT;
  solver_options.minimizer_progress_to_stdout = false;
  solver_options.num_threads = 1;

  for (int round = 0; round < options.rounds; ++round) {
    const bool robust = round < options.robust_rounds;
    ceres::Problem::Options problem_options;
    problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(problem_options);
    problem.AddParameterBlock(pose, kPoseSize, &manifold);
    int active = 0;
    for (std::size_t i = 0; i < observations.size(); ++i) {
      if (!result.inlier[i]) continue;
      const auto& obs = observations[i];
      if (obs.measurement.has_depth()) {
        problem.AddResidualBlock(new PoseOnlyReprojectionError<3>(camera, obs.measurement, obs.p_w),
                                 robust ? &huber_rgbd : nullptr, pose);
      } else {
        problem.AddResidualBlock(new PoseOnlyReprojectionError<2>(camera, obs.measurement, obs.p_w),
                                 robust ? &huber_mono : nullptr, pose);
      }
      ++active;
    }
    if (active < 3) break;
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options, &problem, &summary);

    // Reclassify every observation, including earlier outliers, at the new pose.
    const SE3 T_c_w = block_to_pose(pose);
    result.num_inliers = 0;
    for (std::size_t i = 0; i < observations.size(); ++i) {
      const auto& m = observations[i].measurement;
      const double chi2 = reprojection_chi2(camera, m, T_c_w * observations[i].p_w);
      result.inlier[i] = chi2 <= (m.has_depth() ? options.chi2_rgbd : options.chi2_mono);
      result.num_inliers += result.inlier[i] ? 1 : 0;
    }
    if (result.num_inliers < 10) break;
  }
  result.T_c_w = block_to_pose(pose);
  return result;
}

}  // namespace mcslam::optim
