#pragma once
// Levenberg-Marquardt for bundle adjustment: camera poses and landmarks (points, line segments,
// planes), each residual block tying one pose to one landmark, the landmarks eliminated by the
// Schur complement so that only the poses' system (6 unknowns a free pose) is factorised.
//
// The mapper's local bundle adjustment spent most of its time in Ceres's generic code: its
// landmark blocks differ in size (3, 6, 4) and its residuals too (3, 2), so no fixed-size Schur
// eliminator applies, and each block went through dynamically sized matrices and locked cells.
// This solver takes the same cost functions and manifolds and follows the same
// Levenberg-Marquardt as pose_solver.hpp (Ceres's damping, radius updates, Huber as its
// corrector, stopping rules), with the landmarks eliminated one at a time.

#include <ceres/cost_function.h>
#include <ceres/manifold.h>

#include <atomic>
#include <vector>

#include "mcslam/optim/levenberg_marquardt.hpp"

namespace mcslam::optim {

/// A landmark's parameter block: `x` points to `ambient` doubles; `manifold` (ambient size equal,
/// tangent at most 6), or nullptr for a Euclidean block (at most 6).
struct BundleLandmark {
  double* x = nullptr;
  int ambient = 0;
  const ceres::Manifold* manifold = nullptr;
};

/// One residual block: `cost` takes (pose block of 7, landmark block) and has at most 4
/// residuals; `huber_delta` as in PoseTerm (0: plain least squares).
struct BundleTerm {
  const ceres::CostFunction* cost = nullptr;
  int pose = 0;
  int landmark = 0;
  double huber_delta = 0.0;
};

struct BundleSolverOptions : LevenbergMarquardtOptions {
  /// When set by another thread, the solver stops after its current iteration (the parameters
  /// are then those of the last step taken).
  const std::atomic<bool>* abort = nullptr;
};

struct BundleSolverSummary {
  /// False when the cost cannot be evaluated at the start, or a block does not have the shape
  /// described above: the parameters are left as given.
  bool usable = false;
  bool aborted = false;
  int iterations = 0;
  int successful = 0;
  double initial_cost = 0.0;
  double final_cost = 0.0;
};

/// Minimises 0.5 * sum rho(|r|^2) over the poses (7 doubles each, se3_manifold.hpp, in `poses`)
/// that are not fixed and over the landmarks, in place.
BundleSolverSummary solve_bundle(const std::vector<BundleTerm>& terms, double* poses,
                                 const std::vector<bool>& pose_fixed,
                                 const std::vector<BundleLandmark>& landmarks,
                                 const BundleSolverOptions& options = {});

}  // namespace mcslam::optim
