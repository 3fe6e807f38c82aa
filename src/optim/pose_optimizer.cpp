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

namespace {

/// The residual blocks of a frame's problem, made once for all rounds. (std::deque: cost
/// functions cannot be moved, and its elements never are.)
class PoseCosts {
 public:
  PoseCosts(const PinholeCamera& camera, const PoseProblem& problem,
            const PoseOptimizerOptions& options)
      : problem_(problem),
        point_costs_(problem.points.size()),
        delta_rgbd_(std::sqrt(options.chi2_rgbd)),
        delta_mono_(std::sqrt(options.chi2_mono)),
        delta_line_(std::sqrt(options.chi2_line)),
        delta_plane_(std::sqrt(options.chi2_plane)),
        delta_constraint_(std::sqrt(options.chi2_constraint)) {
    for (std::size_t i = 0; i < problem.points.size(); ++i) {
      const auto& obs = problem.points[i];
      if (obs.measurement.has_depth())
        point_costs_[i] = &rgbd_.emplace_back(camera, obs.measurement, obs.p_w);
      else
        point_costs_[i] = &mono_.emplace_back(camera, obs.measurement, obs.p_w);
    }
    for (const auto& obs : problem.lines)
      lines_.emplace_back(camera, obs.measurement, obs.start_w, obs.end_w);
    for (const auto& obs : problem.planes) planes_.emplace_back(obs.measurement, obs.plane_w);
    for (const auto& m : problem.constrained_points) constrained_points_.emplace_back(m);
    for (const auto& m : problem.constrained_lines) constrained_lines_.emplace_back(m);
  }

  /// The terms of a round started at T_start: the inliers of `result`, under the Huber loss in
  /// the robust rounds. A point behind the camera at T_start becomes an outlier of `result` (its
  /// residual cannot be evaluated there, which would stop the solve before its first step; it is
  /// never a reason to keep the start pose). `landmarks`: how many terms are of landmarks.
  std::vector<PoseTerm> terms(PoseOptimizationResult& result, bool robust, const SE3& T_start,
                              int& landmarks) const {
    const auto huber = [robust](double delta) { return robust ? delta : 0.0; };
    std::vector<PoseTerm> out;
    landmarks = 0;
    for (std::size_t i = 0; i < problem_.points.size(); ++i) {
      if (!result.inlier[i]) continue;
      const auto& obs = problem_.points[i];
      if (!((T_start * obs.p_w).z() > kMinPointDepth)) {
        result.inlier[i] = false;
        ++result.behind_camera;
        continue;
      }
      out.push_back(
          {point_costs_[i], huber(obs.measurement.has_depth() ? delta_rgbd_ : delta_mono_)});
    }
    for (std::size_t i = 0; i < problem_.lines.size(); ++i)
      if (result.line_inlier[i]) out.push_back({&lines_[i], huber(delta_line_)});
    for (std::size_t i = 0; i < problem_.planes.size(); ++i)
      if (result.plane_inlier[i]) out.push_back({&planes_[i], huber(delta_plane_)});
    landmarks = static_cast<int>(out.size());
    for (std::size_t i = 0; i < problem_.constrained_points.size(); ++i)
      if (result.constrained_point_inlier[i])
        out.push_back({&constrained_points_[i], huber(delta_constraint_)});
    for (std::size_t i = 0; i < problem_.constrained_lines.size(); ++i)
      if (result.constrained_line_inlier[i])
        out.push_back({&constrained_lines_[i], huber(delta_constraint_)});
    return out;
  }

 private:
  const PoseProblem& problem_;
  std::deque<PoseOnlyReprojectionError<3>> rgbd_;
  std::deque<PoseOnlyReprojectionError<2>> mono_;
  std::vector<const ceres::CostFunction*> point_costs_;
  std::deque<PoseOnlyLineError> lines_;
  std::deque<PoseOnlyPlaneError> planes_;
  std::deque<PoseOnlyConstrainedPointError> constrained_points_;
  std::deque<PoseOnlyConstrainedLineError> constrained_lines_;
  double delta_rgbd_, delta_mono_, delta_line_, delta_plane_, delta_constraint_;
};

/// Every observation's inlier flag and the counts at T_c_w, earlier outliers included: its
/// chi-square against its threshold.
void classify(const PinholeCamera& camera, const PoseProblem& problem, const SE3& T_c_w,
              const PoseOptimizerOptions& options, PoseOptimizationResult& result) {
  result.num_inliers = 0;
  for (std::size_t i = 0; i < problem.points.size(); ++i) {
    const auto& m = problem.points[i].measurement;
    const double chi2 = reprojection_chi2(camera, m, T_c_w * problem.points[i].p_w);
    result.inlier[i] = chi2 <= (m.has_depth() ? options.chi2_rgbd : options.chi2_mono);
    result.num_inliers += result.inlier[i] ? 1 : 0;
  }
  result.num_line_inliers = 0;
  for (std::size_t i = 0; i < problem.lines.size(); ++i) {
    const auto& obs = problem.lines[i];
    // line_chi2 is in pixels^2; the test needs it whitened like the residual.
    const double chi2 = line_chi2(camera, obs.measurement, T_c_w * obs.start_w, T_c_w * obs.end_w) *
                        obs.measurement.information;
    result.line_inlier[i] = chi2 <= options.chi2_line;
    result.num_line_inliers += result.line_inlier[i] ? 1 : 0;
  }
  result.num_plane_inliers = 0;
  for (std::size_t i = 0; i < problem.planes.size(); ++i) {
    const auto& obs = problem.planes[i];
    result.plane_inlier[i] = plane_chi2(obs.measurement, T_c_w, obs.plane_w) <= options.chi2_plane;
    result.num_plane_inliers += result.plane_inlier[i] ? 1 : 0;
  }
  result.num_constrained_point_inliers = 0;
  for (std::size_t i = 0; i < problem.constrained_points.size(); ++i) {
    result.constrained_point_inlier[i] =
        constrained_point_chi2(T_c_w, problem.constrained_points[i]) <= options.chi2_constraint;
    result.num_constrained_point_inliers += result.constrained_point_inlier[i] ? 1 : 0;
  }
  result.num_constrained_line_inliers = 0;
  for (std::size_t i = 0; i < problem.constrained_lines.size(); ++i) {
    result.constrained_line_inlier[i] =
        constrained_line_chi2(T_c_w, problem.constrained_lines[i]) <= options.chi2_constraint;
    result.num_constrained_line_inliers += result.constrained_line_inlier[i] ? 1 : 0;
  }
}

}  // namespace

PoseOptimizationResult optimize_pose(const PinholeCamera& camera, const SE3& initial_T_c_w,
                                     const PoseProblem& problem,
                                     const PoseOptimizerOptions& options) {
  PoseOptimizationResult result;
  result.T_c_w = initial_T_c_w;
  result.inlier.assign(problem.points.size(), true);
  result.line_inlier.assign(problem.lines.size(), true);
  result.plane_inlier.assign(problem.planes.size(), true);
  result.constrained_point_inlier.assign(problem.constrained_points.size(), true);
  result.constrained_line_inlier.assign(problem.constrained_lines.size(), true);
  // Constraint terms alone could never fix the pose (see the check before each solve), so they do
  // not count here either.
  if (problem.points.empty() && problem.lines.empty() && problem.planes.empty()) return result;

  double pose[kPoseSize];
  pose_to_block(initial_T_c_w, pose);
  const PoseCosts costs(camera, problem, options);
  PoseSolverOptions solver_options;
  solver_options.max_iterations = options.iterations_per_round;
  for (int round = 0; round < options.rounds; ++round) {
    const SE3 T_start = block_to_pose(pose);
    int landmarks = 0;
    const std::vector<PoseTerm> terms =
        costs.terms(result, round < options.robust_rounds, T_start, landmarks);
    // Every kind of landmark gives at least two independent equations, so three observations of
    // any mix are the least that can fix the six degrees of freedom. The constraint terms are not
    // counted: however many there are, they leave the position along their plane and the rotation
    // about its normal free.
    if (landmarks < 3) break;
    const PoseSolverSummary solved = solve_pose(terms, pose, solver_options);
    if (!solved.usable) {
      pose_to_block(T_start, pose);
      result.failed = true;
      break;
    }
    result.information = solved.information;
    classify(camera, problem, block_to_pose(pose), options, result);
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
