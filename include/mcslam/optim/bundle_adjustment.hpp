#pragma once
// Bundle adjustment over keyframe poses and world points (local BA of the mapper). The problem
// is plain data copied out of the map, so the map stays unlocked while Ceres runs.

#include <atomic>
#include <optional>
#include <string>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/optim/reprojection.hpp"

namespace mcslam::optim {

struct BundleAdjustmentProblem {
  struct Observation {
    int pose = 0;   // index into poses
    int point = 0;  // index into points
    PointMeasurement measurement;
  };
  std::vector<SE3> poses;  // T_c_w
  std::vector<bool> pose_fixed;
  std::vector<Eigen::Vector3d> points;
  std::vector<Observation> observations;
};

struct BundleAdjustmentOptions {
  /// Iterations with the Huber loss, then, after dropping outliers, without it.
  int robust_iterations = 5;
  int refine_iterations = 10;
  double chi2_rgbd = 7.815;
  double chi2_mono = 5.991;
  int num_threads = 1;
  std::optional<std::string> check() const;
};

struct BundleAdjustmentResult {
  std::vector<bool> inlier;  // per observation, after optimisation
  bool aborted = false;
  int iterations = 0;
  double initial_cost = 0.0;
  double final_cost = 0.0;
};

/// Optimises poses (except fixed ones) and points in place. `abort`, when given and set by
/// another thread, stops the solver at the end of its current iteration.
BundleAdjustmentResult bundle_adjust(const PinholeCamera& camera, BundleAdjustmentProblem& problem,
                                     const BundleAdjustmentOptions& options,
                                     const std::atomic<bool>* abort = nullptr);

}  // namespace mcslam::optim
