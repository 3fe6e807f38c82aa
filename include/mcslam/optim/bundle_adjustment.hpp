#pragma once
// Bundle adjustment over keyframe poses and world points (local BA of the mapper). The problem
// is plain data copied out of the map, so the map stays unlocked while the solver
// (bundle_solver.hpp) runs.

#include <atomic>
#include <optional>
#include <string>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/optim/line_residual.hpp"
#include "mcslam/optim/plane_residual.hpp"
#include "mcslam/optim/reprojection.hpp"

namespace mcslam::optim {

struct BundleAdjustmentProblem {
  struct Observation {
    int pose = 0;   // index into poses
    int point = 0;  // index into points
    PointMeasurement measurement;
  };
  struct LineObservation {
    int pose = 0;
    int line = 0;  // index into lines
    LineMeasurement measurement;
  };
  struct PlaneObservation {
    int pose = 0;
    int plane = 0;  // index into planes
    PlaneMeasurement measurement;
  };
  /// A 3D line by its two endpoints (world).
  struct Line {
    Eigen::Vector3d start = Eigen::Vector3d::Zero();
    Eigen::Vector3d end = Eigen::Vector3d::Zero();
  };
  std::vector<SE3> poses;  // T_c_w
  std::vector<bool> pose_fixed;
  std::vector<Eigen::Vector3d> points;
  std::vector<Observation> observations;
  std::vector<Line> lines;
  std::vector<LineObservation> line_observations;
  std::vector<Eigen::Vector4d> planes;  // [n, d] world, |n| = 1
  std::vector<PlaneObservation> plane_observations;
};

struct BundleAdjustmentOptions {
  /// Iterations with the Huber loss, then, after dropping outliers, without it.
  int robust_iterations = 5;
  int refine_iterations = 10;
  double chi2_rgbd = 7.815;
  double chi2_mono = 5.991;
  double chi2_line = 5.991;
  double chi2_plane = 7.815;
  std::optional<std::string> check() const;
};

struct BundleAdjustmentResult {
  std::vector<bool> inlier;  // per point observation, after optimisation
  std::vector<bool> line_inlier;
  std::vector<bool> plane_inlier;
  bool aborted = false;
  /// The solver found no usable solution (the cost could not be evaluated at the start): the
  /// problem's poses and landmarks are left as they were given, and the caller must not apply
  /// them.
  bool failed = false;
  /// Point observations left out from the start: the point was behind the camera (or within
  /// kMinPointDepth of its centre) at the initial estimate. They are outliers.
  int behind_camera = 0;
  int iterations = 0;
  double initial_cost = 0.0;
  double final_cost = 0.0;
};

/// Optimises poses (except fixed ones), points, lines and planes in place (residuals (6)-(8),
/// Huber loss, then outliers dropped and refined without it). `abort`, when given and set by
/// another thread, stops the solver at the end of its current iteration.
BundleAdjustmentResult bundle_adjust(const PinholeCamera& camera, BundleAdjustmentProblem& problem,
                                     const BundleAdjustmentOptions& options,
                                     const std::atomic<bool>* abort = nullptr);

}  // namespace mcslam::optim
