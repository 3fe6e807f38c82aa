#include "mcslam/optim/bundle_adjustment.hpp"

#include <cmath>
#include <deque>

#include "mcslam/optim/bundle_solver.hpp"
#include "mcslam/optim/se3_manifold.hpp"

namespace mcslam::optim {

std::optional<std::string> BundleAdjustmentOptions::check() const {
  if (robust_iterations < 1) return "mapper.ba.robust_iterations must be at least 1";
  if (refine_iterations < 0) return "mapper.ba.refine_iterations must not be negative";
  if (!(chi2_rgbd > 0.0) || !(chi2_mono > 0.0) || !(chi2_line > 0.0) || !(chi2_plane > 0.0))
    return "mapper.ba chi-square thresholds must be positive";
  return std::nullopt;
}

namespace {

/// T_c_w of pose k in the solver's array.
SE3 pose_at(const std::vector<double>& poses, int k) {
  return block_to_pose(&poses[static_cast<std::size_t>(k) * kPoseSize]);
}

/// The residual blocks of a problem, made once for both stages, and the landmark layout the
/// solver sees: points first, then segments, then planes. (std::deque: cost functions cannot be
/// moved, and its elements never are.)
class BundleCosts {
 public:
  BundleCosts(const PinholeCamera& camera, const BundleAdjustmentProblem& problem,
              const BundleAdjustmentOptions& options)
      : problem_(problem),
        point_costs_(problem.observations.size()),
        first_segment_(static_cast<int>(problem.points.size())),
        first_plane_(first_segment_ + static_cast<int>(problem.lines.size())),
        delta_rgbd_(std::sqrt(options.chi2_rgbd)),
        delta_mono_(std::sqrt(options.chi2_mono)),
        delta_line_(std::sqrt(options.chi2_line)),
        delta_plane_(std::sqrt(options.chi2_plane)) {
    for (std::size_t k = 0; k < problem.observations.size(); ++k) {
      const auto& m = problem.observations[k].measurement;
      point_costs_[k] =
          m.has_depth() ? static_cast<const ceres::CostFunction*>(&rgbd_.emplace_back(camera, m))
                        : &mono_.emplace_back(camera, m);
    }
    for (const auto& obs : problem.line_observations) lines_.emplace_back(camera, obs.measurement);
    for (const auto& obs : problem.plane_observations) planes_.emplace_back(obs.measurement);
  }

  /// The terms of the observations still inliers in `result`, under the Huber loss in the robust
  /// stage and plain in the refinement.
  std::vector<BundleTerm> terms(const BundleAdjustmentResult& result, bool robust) const {
    const auto huber = [robust](double delta) { return robust ? delta : 0.0; };
    std::vector<BundleTerm> out;
    for (std::size_t k = 0; k < problem_.observations.size(); ++k) {
      if (!result.inlier[k]) continue;
      const auto& obs = problem_.observations[k];
      out.push_back({point_costs_[k], obs.pose, obs.point,
                     huber(obs.measurement.has_depth() ? delta_rgbd_ : delta_mono_)});
    }
    for (std::size_t k = 0; k < problem_.line_observations.size(); ++k) {
      if (!result.line_inlier[k]) continue;
      const auto& obs = problem_.line_observations[k];
      out.push_back({&lines_[k], obs.pose, first_segment_ + obs.line, huber(delta_line_)});
    }
    for (std::size_t k = 0; k < problem_.plane_observations.size(); ++k) {
      if (!result.plane_inlier[k]) continue;
      const auto& obs = problem_.plane_observations[k];
      out.push_back({&planes_[k], obs.pose, first_plane_ + obs.plane, huber(delta_plane_)});
    }
    return out;
  }

 private:
  const BundleAdjustmentProblem& problem_;
  std::deque<ReprojectionError<3>> rgbd_;
  std::deque<ReprojectionError<2>> mono_;
  std::vector<const ceres::CostFunction*> point_costs_;
  std::deque<LineSegmentError> lines_;
  std::deque<PlaneError> planes_;
  int first_segment_, first_plane_;
  double delta_rgbd_, delta_mono_, delta_line_, delta_plane_;
};

/// Point observations whose point is behind its camera at the start: outliers from the start (a
/// residual that cannot be evaluated at the start point stops the solver before its first step).
void drop_behind_camera(const BundleAdjustmentProblem& problem, const std::vector<double>& poses,
                        BundleAdjustmentResult& result) {
  for (std::size_t k = 0; k < problem.observations.size(); ++k) {
    const auto& obs = problem.observations[k];
    if (!((pose_at(poses, obs.pose) * problem.points[static_cast<std::size_t>(obs.point)]).z() >
          kMinPointDepth)) {
      result.inlier[k] = false;
      ++result.behind_camera;
    }
  }
}

/// Every observation's inlier flag at the current estimate: its chi-square against its threshold
/// (a point behind its camera has an infinite one).
void classify(const PinholeCamera& camera, const BundleAdjustmentProblem& problem,
              const std::vector<double>& poses, const BundleAdjustmentOptions& options,
              BundleAdjustmentResult& result) {
  for (std::size_t k = 0; k < problem.observations.size(); ++k) {
    const auto& obs = problem.observations[k];
    const double chi2 = reprojection_chi2(
        camera, obs.measurement,
        pose_at(poses, obs.pose) * problem.points[static_cast<std::size_t>(obs.point)]);
    result.inlier[k] =
        chi2 <= (obs.measurement.has_depth() ? options.chi2_rgbd : options.chi2_mono);
  }
  for (std::size_t k = 0; k < problem.line_observations.size(); ++k) {
    const auto& obs = problem.line_observations[k];
    const SE3 T_c_w = pose_at(poses, obs.pose);
    const auto& line = problem.lines[static_cast<std::size_t>(obs.line)];
    // line_chi2 is in pixels^2; whitened here like the residual.
    result.line_inlier[k] =
        line_chi2(camera, obs.measurement, T_c_w * line.start, T_c_w * line.end) *
            obs.measurement.information <=
        options.chi2_line;
  }
  for (std::size_t k = 0; k < problem.plane_observations.size(); ++k) {
    const auto& obs = problem.plane_observations[k];
    result.plane_inlier[k] =
        plane_chi2(obs.measurement, pose_at(poses, obs.pose),
                   problem.planes[static_cast<std::size_t>(obs.plane)]) <= options.chi2_plane;
  }
}

}  // namespace

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
  drop_behind_camera(problem, poses, result);
  const std::vector<Eigen::Vector3d> points_before = problem.points;
  const std::vector<BundleAdjustmentProblem::Line> lines_before = problem.lines;
  const std::vector<Eigen::Vector4d> planes_before = problem.planes;
  // Each line as one 6-vector (start | end): one landmark block, eliminated by the Schur solver
  // (LineSegmentError). Written back into problem.lines after every usable solve.
  std::vector<Eigen::Matrix<double, 6, 1>> segments(problem.lines.size());
  for (std::size_t i = 0; i < problem.lines.size(); ++i)
    segments[i] << problem.lines[i].start, problem.lines[i].end;
  const BundleCosts costs(camera, problem, options);
  const PlaneManifold plane_manifold;
  const SegmentManifold segment_manifold;
  for (int stage = 0; stage < 2; ++stage) {
    const bool robust = stage == 0;
    const int iterations = robust ? options.robust_iterations : options.refine_iterations;
    if (iterations == 0 || result.aborted) break;
    // A line's endpoints can slide along the line with (almost) no change of residual (7). The
    // robust stage leaves them free to slide (its damped steps keep the normal equations
    // regular); the refinement moves them only across the line (SegmentManifold).
    // With that freedom the refinement ran to its limit of iterations on freiburg1_rpy (a
    // median of 10 in Ceres's count); without it, a median of 3. Pinning them in the robust
    // stage too was measured worse on the synthetic crowds (the undetected person 0.0113 ->
    // 0.0177 m; see docs/crowd.md).
    std::vector<BundleLandmark> landmarks;
    for (Eigen::Vector3d& point : problem.points) landmarks.push_back({point.data(), 3, nullptr});
    for (auto& segment : segments)
      landmarks.push_back({segment.data(), 6, robust ? nullptr : &segment_manifold});
    for (Eigen::Vector4d& plane : problem.planes) {
      // The manifold keeps |n| = 1 only if it starts there.
      plane.head<3>().normalize();
      landmarks.push_back({plane.data(), 4, &plane_manifold});
    }
    BundleSolverOptions solver_options;
    solver_options.max_iterations = iterations;
    solver_options.abort = abort;
    const BundleSolverSummary summary = solve_bundle(costs.terms(result, robust), poses.data(),
                                                     problem.pose_fixed, landmarks, solver_options);
    if (!summary.usable) {
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
    result.iterations += summary.iterations;
    result.aborted = summary.aborted;
    // Outliers: large error or behind the camera. They stay out of the refinement stage.
    classify(camera, problem, poses, options, result);
  }
  for (std::size_t i = 0; i < problem.poses.size(); ++i)
    problem.poses[i] = block_to_pose(&poses[i * kPoseSize]);
  return result;
}

}  // namespace mcslam::optim
