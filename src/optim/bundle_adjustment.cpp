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
  if (!(chi2_rgbd > 0.0) || !(chi2_mono > 0.0) || !(chi2_line > 0.0) || !(chi2_plane > 0.0))
    return "local_ba chi-square thresholds must be positive";
  if (num_threads < 1) return "local_ba.num_threads must be at least 1";
  return std::nullopt;
}

BundleAdjustmentResult bundle_adjust(const PinholeCamera& camera, BundleAdjustmentProblem& problem,
                                     const BundleAdjustmentOptions& options,
                                     const std::atomic<bool>* abort) {
  BundleAdjustmentResult result;
  result.inlier.assign(problem.observations.size(), true);
  result.line_inlier.assign(problem.line_observations.size(), true);
  result.plane_inlier.assign(problem.plane_observations.size(), true);
  if (problem.observations.empty() && problem.line_observations.empty() &&
      problem.plane_observations.empty())
    return result;

  std::vector<double> poses(problem.poses.size() * kPoseSize);
  for (std::size_t i = 0; i < problem.poses.size(); ++i)
    pose_to_block(problem.poses[i], &poses[i * kPoseSize]);
  SE3Manifold manifold;
  PlaneManifold plane_manifold;
  SegmentManifold segment_manifold;
  ceres::HuberLoss huber_rgbd(std::sqrt(options.chi2_rgbd));
  ceres::HuberLoss huber_mono(std::sqrt(options.chi2_mono));
  ceres::HuberLoss huber_line(std::sqrt(options.chi2_line));
  ceres::HuberLoss huber_plane(std::sqrt(options.chi2_plane));
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
  const auto line_chi2_of = [&](std::size_t k) {
    const auto& obs = problem.line_observations[k];
    const SE3 T_c_w = block_to_pose(&poses[static_cast<std::size_t>(obs.pose) * kPoseSize]);
    const auto& line = problem.lines[static_cast<std::size_t>(obs.line)];
    // line_chi2 is in pixels^2; whitened here like the residual.
    return line_chi2(camera, obs.measurement, T_c_w * line.start, T_c_w * line.end) *
           obs.measurement.information;
  };
  const auto plane_chi2_of = [&](std::size_t k) {
    const auto& obs = problem.plane_observations[k];
    const SE3 T_c_w = block_to_pose(&poses[static_cast<std::size_t>(obs.pose) * kPoseSize]);
    const Eigen::Vector4d& plane = problem.planes[static_cast<std::size_t>(obs.plane)];
    const Eigen::Vector3d n_c = T_c_w.rotation() * plane.head<3>();
    return plane_chi2(obs.measurement, n_c, plane.w() - n_c.dot(T_c_w.translation()));
  };

  // A residual that cannot be evaluated at the start point stops Ceres before its first step:
  // an observation whose point starts behind its camera is an outlier from the start.
  for (std::size_t k = 0; k < problem.observations.size(); ++k) {
    const auto& obs = problem.observations[k];
    const SE3 T_c_w = block_to_pose(&poses[static_cast<std::size_t>(obs.pose) * kPoseSize]);
    if (!((T_c_w * problem.points[static_cast<std::size_t>(obs.point)]).z() > kMinPointDepth)) {
      result.inlier[k] = false;
      ++result.behind_camera;
    }
  }
  const std::vector<Eigen::Vector3d> points_before = problem.points;
  const std::vector<BundleAdjustmentProblem::Line> lines_before = problem.lines;
  const std::vector<Eigen::Vector4d> planes_before = problem.planes;
  // Each line as one 6-vector (start | end): one landmark block, eliminated by the Schur solver
  // (LineSegmentError). Written back into problem.lines after every usable solve.
  std::vector<Eigen::Matrix<double, 6, 1>> segments(problem.lines.size());
  for (std::size_t i = 0; i < problem.lines.size(); ++i)
    segments[i] << problem.lines[i].start, problem.lines[i].end;
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
    // A line's endpoints can slide along the line with (almost) no change of residual (7). The
    // robust stage leaves them free to slide (its damped steps keep the normal equations
    // regular); the refinement moves them only across the line (SegmentManifold, set below).
    // With that freedom the refinement ran to its limit of iterations on freiburg1_rpy (a
    // median of 10 in Ceres's count); without it, a median of 3. Pinning them in the robust
    // stage too was measured worse on the synthetic crowds (the undetected person 0.0113 ->
    // 0.0177 m; see docs/crowd.md).
    for (std::size_t k = 0; k < problem.line_observations.size(); ++k) {
      if (!result.line_inlier[k]) continue;
      const auto& obs = problem.line_observations[k];
      double* pose = &poses[static_cast<std::size_t>(obs.pose) * kPoseSize];
      double* segment = segments[static_cast<std::size_t>(obs.line)].data();
      ceres_problem.AddResidualBlock(new LineSegmentError(camera, obs.measurement),
                                     robust ? &huber_line : nullptr, pose, segment);
    }
    for (std::size_t k = 0; k < problem.plane_observations.size(); ++k) {
      if (!result.plane_inlier[k]) continue;
      const auto& obs = problem.plane_observations[k];
      double* pose = &poses[static_cast<std::size_t>(obs.pose) * kPoseSize];
      double* plane = problem.planes[static_cast<std::size_t>(obs.plane)].data();
      ceres_problem.AddResidualBlock(new PlaneError(obs.measurement),
                                     robust ? &huber_plane : nullptr, pose, plane);
    }
    for (Eigen::Vector4d& plane : problem.planes) {
      if (!ceres_problem.HasParameterBlock(plane.data())) continue;
      // The manifold keeps |n| = 1 only if it starts there.
      plane.head<3>().normalize();
      ceres_problem.SetManifold(plane.data(), &plane_manifold);
    }
    for (auto& segment : segments)
      if (!robust && ceres_problem.HasParameterBlock(segment.data()))
        ceres_problem.SetManifold(segment.data(), &segment_manifold);
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
    if (!summary.IsSolutionUsable()) {
      problem.points = points_before;
      problem.lines = lines_before;
      problem.planes = planes_before;
      result.failed = true;
      return result;
    }
    for (std::size_t i = 0; i < problem.lines.size(); ++i) {
      problem.lines[i].start = segments[i].head<3>();
      problem.lines[i].end = segments[i].tail<3>();
    }
    if (stage == 0) result.initial_cost = summary.initial_cost;
    result.final_cost = summary.final_cost;
    result.iterations += static_cast<int>(summary.iterations.size());
    result.aborted = callback.aborted;

    // Outliers: large error or behind the camera. They stay out of the refinement stage.
    for (std::size_t k = 0; k < problem.observations.size(); ++k)
      result.inlier[k] = chi2_of(k) <= threshold_of(k);
    for (std::size_t k = 0; k < problem.line_observations.size(); ++k)
      result.line_inlier[k] = line_chi2_of(k) <= options.chi2_line;
    for (std::size_t k = 0; k < problem.plane_observations.size(); ++k)
      result.plane_inlier[k] = plane_chi2_of(k) <= options.chi2_plane;
  }
  for (std::size_t i = 0; i < problem.poses.size(); ++i)
    problem.poses[i] = block_to_pose(&poses[i * kPoseSize]);
  return result;
}

}  // namespace mcslam::optim
