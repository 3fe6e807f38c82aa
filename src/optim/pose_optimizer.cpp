#include "mcslam/optim/pose_optimizer.hpp"

#include <cmath>
#include <deque>

#include "mcslam/optim/pose_solver.hpp"
#include "mcslam/optim/se3_manifold.hpp"

namespace mcslam::optim {

std::optional<std::string> PoseOptimizerOptions::check() const {
  if (rounds < 1) return "pose_optimizer.rounds must be at least 1";
  if (iterations_per_round < 1) return "pose_optimizer.iterations_per_round must be at least 1";
  if (robust_rounds < 0) return "pose_optimizer.robust_rounds must not be negative";
  if (!(chi2_rgbd > 0.0) || !(chi2_mono > 0.0) || !(chi2_line > 0.0) || !(chi2_plane > 0.0) ||
      !(chi2_constraint > 0.0))
    return "pose_optimizer chi-square thresholds must be positive";
  return std::nullopt;
}

PoseOptimizationResult optimize_pose(const PinholeCamera& camera, const SE3& initial_T_c_w,
                                     const PoseProblem& problem,
                                     const PoseOptimizerOptions& options) {
  const auto& points = problem.points;
  const auto& lines = problem.lines;
  const auto& planes = problem.planes;
  const auto& constrained_points = problem.constrained_points;
  const auto& constrained_lines = problem.constrained_lines;
  PoseOptimizationResult result;
  result.T_c_w = initial_T_c_w;
  result.inlier.assign(points.size(), true);
  result.line_inlier.assign(lines.size(), true);
  result.plane_inlier.assign(planes.size(), true);
  result.constrained_point_inlier.assign(constrained_points.size(), true);
  result.constrained_line_inlier.assign(constrained_lines.size(), true);
  // Constraint terms alone could never fix the pose (see the check before each solve), so they do
  // not count here either.
  if (points.empty() && lines.empty() && planes.empty()) return result;

  double pose[kPoseSize];
  pose_to_block(initial_T_c_w, pose);
  // The residual blocks are made once; each round solves with the inliers of the round before.
  // (std::deque: cost functions cannot be moved, and its elements never are.)
  std::deque<PoseOnlyReprojectionError<3>> rgbd_terms;
  std::deque<PoseOnlyReprojectionError<2>> mono_terms;
  std::vector<const ceres::CostFunction*> point_terms(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto& obs = points[i];
    if (obs.measurement.has_depth())
      point_terms[i] = &rgbd_terms.emplace_back(camera, obs.measurement, obs.p_w);
    else
      point_terms[i] = &mono_terms.emplace_back(camera, obs.measurement, obs.p_w);
  }
  std::deque<PoseOnlyLineError> line_terms;
  for (const auto& obs : lines)
    line_terms.emplace_back(camera, obs.measurement, obs.start_w, obs.end_w);
  std::deque<PoseOnlyPlaneError> plane_terms;
  for (const auto& obs : planes) plane_terms.emplace_back(obs.measurement, obs.plane_w);
  std::deque<PoseOnlyConstrainedPointError> constrained_point_terms;
  for (const auto& m : constrained_points) constrained_point_terms.emplace_back(m);
  std::deque<PoseOnlyConstrainedLineError> constrained_line_terms;
  for (const auto& m : constrained_lines) constrained_line_terms.emplace_back(m);

  PoseSolverOptions solver_options;
  solver_options.max_iterations = options.iterations_per_round;
  const double delta_rgbd = std::sqrt(options.chi2_rgbd);
  const double delta_mono = std::sqrt(options.chi2_mono);
  const double delta_line = std::sqrt(options.chi2_line);
  const double delta_plane = std::sqrt(options.chi2_plane);
  const double delta_constraint = std::sqrt(options.chi2_constraint);
  std::vector<PoseTerm> terms;
  terms.reserve(points.size() + lines.size() + planes.size() + constrained_points.size() +
                constrained_lines.size());

  for (int round = 0; round < options.rounds; ++round) {
    const bool robust = round < options.robust_rounds;
    const auto huber = [robust](double delta) { return robust ? delta : 0.0; };
    terms.clear();
    int active = 0;
    const SE3 T_start = block_to_pose(pose);
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (!result.inlier[i]) continue;
      const auto& obs = points[i];
      // A residual that cannot be evaluated at the start point would stop the solve before its
      // first step: such a point is an outlier of this round, never a reason to keep the start
      // pose.
      if (!((T_start * obs.p_w).z() > kMinPointDepth)) {
        result.inlier[i] = false;
        ++result.behind_camera;
        continue;
      }
      terms.push_back(
          {point_terms[i], huber(obs.measurement.has_depth() ? delta_rgbd : delta_mono)});
      ++active;
    }
    for (std::size_t i = 0; i < lines.size(); ++i) {
      if (!result.line_inlier[i]) continue;
      terms.push_back({&line_terms[i], huber(delta_line)});
      ++active;
    }
    for (std::size_t i = 0; i < planes.size(); ++i) {
      if (!result.plane_inlier[i]) continue;
      terms.push_back({&plane_terms[i], huber(delta_plane)});
      ++active;
    }
    for (std::size_t i = 0; i < constrained_points.size(); ++i)
      if (result.constrained_point_inlier[i])
        terms.push_back({&constrained_point_terms[i], huber(delta_constraint)});
    for (std::size_t i = 0; i < constrained_lines.size(); ++i)
      if (result.constrained_line_inlier[i])
        terms.push_back({&constrained_line_terms[i], huber(delta_constraint)});
    // Every kind of landmark gives at least two independent equations, so three observations of
    // any mix are the least that can fix the six degrees of freedom. The constraint terms are not
    // counted: however many there are, they leave the position along their plane and the rotation
    // about its normal free.
    if (active < 3) break;
    if (!solve_pose(terms, pose, solver_options).usable) {
      pose_to_block(T_start, pose);
      result.failed = true;
      break;
    }

    // Reclassify every observation, including earlier outliers, at the new pose.
    const SE3 T_c_w = block_to_pose(pose);
    result.num_inliers = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      const auto& m = points[i].measurement;
      const double chi2 = reprojection_chi2(camera, m, T_c_w * points[i].p_w);
      result.inlier[i] = chi2 <= (m.has_depth() ? options.chi2_rgbd : options.chi2_mono);
      result.num_inliers += result.inlier[i] ? 1 : 0;
    }
    result.num_line_inliers = 0;
    for (std::size_t i = 0; i < lines.size(); ++i) {
      const auto& obs = lines[i];
      // line_chi2 is in pixels^2; the test needs it whitened like the residual.
      const double chi2 =
          line_chi2(camera, obs.measurement, T_c_w * obs.start_w, T_c_w * obs.end_w) *
          obs.measurement.information;
      result.line_inlier[i] = chi2 <= options.chi2_line;
      result.num_line_inliers += result.line_inlier[i] ? 1 : 0;
    }
    result.num_plane_inliers = 0;
    for (std::size_t i = 0; i < planes.size(); ++i) {
      const auto& obs = planes[i];
      const Eigen::Vector3d n_c = T_c_w.rotation() * obs.plane_w.head<3>();
      const double d_c = obs.plane_w.w() - n_c.dot(T_c_w.translation());
      result.plane_inlier[i] = plane_chi2(obs.measurement, n_c, d_c) <= options.chi2_plane;
      result.num_plane_inliers += result.plane_inlier[i] ? 1 : 0;
    }
    result.num_constrained_point_inliers = 0;
    for (std::size_t i = 0; i < constrained_points.size(); ++i) {
      result.constrained_point_inlier[i] =
          constrained_point_chi2(T_c_w, constrained_points[i]) <= options.chi2_constraint;
      result.num_constrained_point_inliers += result.constrained_point_inlier[i] ? 1 : 0;
    }
    result.num_constrained_line_inliers = 0;
    for (std::size_t i = 0; i < constrained_lines.size(); ++i) {
      result.constrained_line_inlier[i] =
          constrained_line_chi2(T_c_w, constrained_lines[i]) <= options.chi2_constraint;
      result.num_constrained_line_inliers += result.constrained_line_inlier[i] ? 1 : 0;
    }
    // Too few inliers of all kinds together to go on rejecting outliers. Constraint inliers are
    // evidence for the classification too (the landmark minimum is enforced above).
    if (result.num_inliers + result.num_line_inliers + result.num_plane_inliers +
            result.num_constrained_point_inliers + result.num_constrained_line_inliers <
        10)
      break;
  }
  result.T_c_w = block_to_pose(pose);
  return result;
}

PoseOptimizationResult optimize_pose(const PinholeCamera& camera, const SE3& initial_T_c_w,
                                     const std::vector<PoseObservation>& observations,
                                     const PoseOptimizerOptions& options) {
  PoseProblem problem;
  problem.points = observations;
  return optimize_pose(camera, initial_T_c_w, problem, options);
}

}  // namespace mcslam::optim
