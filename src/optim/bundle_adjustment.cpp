#include "mcslam/optim/bundle_adjustment.hpp"

#include <ceres/iteration_callback.h>
#include <ceres/loss_function.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <cmath>

#include "mcslam/optim/se3_manifold.hpp"

namespace mcslam::optim {
namespace {

class AbortCallback final : public ceres::IterationCallback {
 public:
  explicit AbortCallback(const std::atomic<bool>* flag) : flag_(flag) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    if (flag_ != nullptr && flag_->load(std::memory_order_relaxed)) {
      aborted = true;
      return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    }
    return ceres::SOLVER_CONTINUE;
  }
  bool aborted = false;

 private:
  const std::atomic<bool>* flag_;
};

}  // namespace

std::optional<std::string> BundleAdjustmentOptions::check() const {
  if (robust_iterations < 1) return "local_ba.robust_iterations must be at least 1";
  if (refine_iterations < 0) return "local_ba.refine_iterations must not be negative";
  if (!(chi2_rgbd > 0.0) || !(chi2_mono > 0.0))
    return "local_ba chi-square thresholds must be positive";
  if (num_threads < 1) return "local_ba.num_threads must be at least 1";
  return std::nullopt;
}

BundleAdjustmentResult bundle_adjust(const PinholeCamera& camera, BundleAdjustmentProblem& problem,
                                     const BundleAdjustmentOptions& options,
                                     const std::atomic<bool>* abort) {
  BundleAdjustmentResult result;
  result.inlier.assign(problem.observations.size(), true);
  if (problem.observations.empty()) return result;

  std::vector<double> poses(problem.poses.size() * kPoseSize);
  for (std::size_t i = 0; i < problem.poses.size(); ++i)
    pose_to_block(problem.poses[i], &poses[i * kPoseSize]);
  SE3Manifold manifold;
  ceres::HuberLoss huber_rgbd(std::sqrt(options.chi2_rgbd));
  ceres::HuberLoss huber_mono(std::sqrt(options.chi2_mono));
  AbortCallback callback(abort);

  const auto chi2_of = [&](std::size_t k) {
    const auto& obs = problem.observations[k];
    const SE3 T_c_w = block_to_pose(&poses[static_cast<std::size_t>(obs.pose) * kPoseSize]);
    return reprojection_chi2(camera, obs.measurement,
                             T_c_w * problem.points[static_cast<std::size_t>(obs.point)]);
  };
  const auto threshold_of = [&](std::size_t k) {
    return problem.observations[k].measurement.has_depth() ? options.chi2_rgbd : options.chi2_mono;
  };

  for (int stage = 0; stage < 2; ++stage) {
    const bool robust = stage == 0;
    const int iterations = robust ? options.robust_iterations : options.refine_iterations;
    if (iterations == 0 || result.aborted) break;
    ceres::Problem::Options problem_options;
    problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem ceres_problem(problem_options);
    for (std::size_t k = 0; k < problem.observations.size(); ++k) {
      if (!result.inlier[k]) continue;
      const auto& obs = problem.observations[k];
      double* pose = &poses[static_cast<std::size_t>(obs.pose) * kPoseSize];
      double* point = problem.points[static_cast<std::size_t>(obs.point)].data();
      if (obs.measurement.has_depth()) {
        ceres_problem.AddResidualBlock(new ReprojectionError<3>(camera, obs.measurement),
                                       robust ? &huber_rgbd : nullptr, pose, point);
      } else {
        ceres_problem.AddResidualBlock(new ReprojectionError<2>(camera, obs.measurement),
                                       robust ? &huber_mono : nullptr, pose, point);
      }
    }
    for (std::size_t i = 0; i < problem.poses.size(); ++i) {
      double* pose = &poses[i * kPoseSize];
      if (!ceres_problem.HasParameterBlock(pose)) continue;
      ceres_problem.SetManifold(pose, &manifold);
      if (problem.pose_fixed[i]) ceres_problem.SetParameterBlockConstant(pose);
    }
    ceres::Solver::Options solver_options;
    solver_options.linear_solver_type =
        ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE) ? ceres::SPARSE_SCHUR
                                                                              : ceres::DENSE_SCHUR;
    solver_options.max_num_iterations = iterations;
    solver_options.logging_type = ceres::SILENT;
    solver_options.num_threads = options.num_threads;
    solver_options.callbacks.push_back(&callback);
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options, &ceres_problem, &summary);
    if (stage == 0) result.initial_cost = summary.initial_cost;
    result.final_cost = summary.final_cost;
    result.iterations += static_cast<int>(summary.iterations.size());
    result.aborted = callback.aborted;

    // Outliers: large error or behind the camera. They stay out of the refinement stage.
    for (std::size_t k = 0; k < problem.observations.size(); ++k)
      result.inlier[k] = chi2_of(k) <= threshold_of(k);
  }
  for (std::size_t i = 0; i < problem.poses.size(); ++i)
    problem.poses[i] = block_to_pose(&poses[i * kPoseSize]);
  return result;
}

}  // namespace mcslam::optim
