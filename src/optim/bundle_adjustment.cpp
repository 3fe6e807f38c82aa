#include "mcslam/optim/bundle_adjustment.hpp"

#include <cmath>
#include <deque>

#include "mcslam/optim/bundle_solver.hpp"
#include "mcslam/optim/se3_manifold.hpp"

namespace mcslam::optim {

std::optional<std::string> BundleAdjustmentOptions::check() const {
  if (robust_iterations < 1) return "local_ba.robust_iterations must be at least 1";
  if (refine_iterations < 0) return "local_ba.refine_iterations must not be negative";
  if (!(chi2_rgbd > 0.0) || !(chi2_mono > 0.0) || !(chi2_line > 0.0) || !(chi2_plane > 0.0))
    return "local_ba chi-square thresholds must be positive";
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
  const PlaneManifold plane_manifold;
  const SegmentManifold segment_manifold;

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
  // Landmark blocks: points first, then segments, then planes. Ownership of the residual blocks
  // stays here (std::deque: cost functions cannot be moved, and its elements never are).
  const std::size_t first_segment = problem.points.size();
  const std::size_t first_plane = first_segment + segments.size();
  std::deque<ReprojectionError<3>> rgbd_terms;
  std::deque<ReprojectionError<2>> mono_terms;
  std::vector<const ceres::CostFunction*> point_terms(problem.observations.size());
  for (std::size_t k = 0; k < problem.observations.size(); ++k) {
    const auto& m = problem.observations[k].measurement;
    point_terms[k] =
        m.has_depth() ? static_cast<const ceres::CostFunction*>(&rgbd_terms.emplace_back(camera, m))
                      : &mono_terms.emplace_back(camera, m);
  }
  std::deque<LineSegmentError> line_terms;
  for (const auto& obs : problem.line_observations)
    line_terms.emplace_back(camera, obs.measurement);
  std::deque<PlaneError> plane_terms;
  for (const auto& obs : problem.plane_observations) plane_terms.emplace_back(obs.measurement);
  const double delta_rgbd = std::sqrt(options.chi2_rgbd);
  const double delta_mono = std::sqrt(options.chi2_mono);
  const double delta_line = std::sqrt(options.chi2_line);
  const double delta_plane = std::sqrt(options.chi2_plane);
  std::vector<BundleTerm> terms;
  std::vector<BundleLandmark> landmarks;
  for (int stage = 0; stage < 2; ++stage) {
    const bool robust = stage == 0;
    const int iterations = robust ? options.robust_iterations : options.refine_iterations;
    if (iterations == 0 || result.aborted) break;
    const auto huber = [robust](double delta) { return robust ? delta : 0.0; };
    terms.clear();
    for (std::size_t k = 0; k < problem.observations.size(); ++k) {
      if (!result.inlier[k]) continue;
      const auto& obs = problem.observations[k];
      terms.push_back({point_terms[k], obs.pose, obs.point,
                       huber(obs.measurement.has_depth() ? delta_rgbd : delta_mono)});
    }
    // A line's endpoints can slide along the line with (almost) no change of residual (7). The
    // robust stage leaves them free to slide (its damped steps keep the normal equations
    // regular); the refinement moves them only across the line (SegmentManifold, below).
    // With that freedom the refinement ran to its limit of iterations on freiburg1_rpy (a
    // median of 10 in Ceres's count); without it, a median of 3. Pinning them in the robust
    // stage too was measured worse on the synthetic crowds (the undetected person 0.0113 ->
    // 0.0177 m; see docs/crowd.md).
    for (std::size_t k = 0; k < problem.line_observations.size(); ++k) {
      if (!result.line_inlier[k]) continue;
      const auto& obs = problem.line_observations[k];
      terms.push_back({&line_terms[k], obs.pose, static_cast<int>(first_segment) + obs.line,
                       huber(delta_line)});
    }
    for (std::size_t k = 0; k < problem.plane_observations.size(); ++k) {
      if (!result.plane_inlier[k]) continue;
      const auto& obs = problem.plane_observations[k];
      terms.push_back({&plane_terms[k], obs.pose, static_cast<int>(first_plane) + obs.plane,
                       huber(delta_plane)});
    }
    landmarks.clear();
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
    const BundleSolverSummary summary =
        solve_bundle(terms, poses.data(), problem.pose_fixed, landmarks, solver_options);
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
