#include "mcslam/optim/pose_solver.hpp"

#include <algorithm>
#include <cmath>

#include "mcslam/core/se3.hpp"
#include "mcslam/optim/se3_manifold.hpp"
#include "optim/huber.hpp"
#include "optim/trust_region.hpp"

namespace mcslam::optim {
namespace {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Matrix76 = Eigen::Matrix<double, 7, 6, Eigen::RowMajor>;

/// The cost at a pose and the Gauss-Newton system of its tangent: H = J^T W J and g = J^T W r
/// with the Huber weights W.
struct Linearisation {
  double cost = 0.0;
  Matrix6d H = Matrix6d::Zero();
  Vector6d g = Vector6d::Zero();
};

/// Adds one residual block of kDim rows (its pose Jacobian J7, 7 columns, row-major) to the
/// system with the Huber weight w: the tangent Jacobian is J7 * plus.
template <int kDim>
bool accumulate(const double* residual, const double* jacobian, const Matrix76& plus, double w,
                Linearisation& out) {
  const Eigen::Map<const Eigen::Matrix<double, kDim, 1>> r(residual);
  const Eigen::Map<const Eigen::Matrix<double, kDim, 7, Eigen::RowMajor>> J7(jacobian);
  const Eigen::Matrix<double, kDim, 6> J = J7 * plus;
  if (!J.allFinite()) return false;
  out.H.noalias() += w * (J.transpose() * J);
  out.g.noalias() += w * (J.transpose() * r);
  return true;
}

/// The cost at `pose` and, with `normal` set, its system; false when a term cannot be evaluated
/// there (or gives a non-finite value).
bool evaluate(const std::vector<PoseTerm>& terms, const double* pose, bool normal,
              Linearisation& out) {
  out = Linearisation{};
  Matrix76 plus;
  if (normal) SE3Manifold().PlusJacobian(pose, plus.data());
  double residual[kMaxPoseResidual];
  double jacobian[kMaxPoseResidual * 7];
  double* jacobians[1] = {jacobian};
  const double* parameters[1] = {pose};
  for (const PoseTerm& term : terms) {
    const int dim = term.cost->num_residuals();
    if (!term.cost->Evaluate(parameters, residual, normal ? jacobians : nullptr)) return false;
    double s = 0.0;
    for (int k = 0; k < dim; ++k) s += residual[k] * residual[k];
    if (!std::isfinite(s)) return false;
    const HuberTerm loss = huber(s, term.huber_delta);
    out.cost += 0.5 * loss.rho;
    if (!normal) continue;
    const double w = loss.weight;
    bool finite = false;
    switch (dim) {
      case 1:
        finite = accumulate<1>(residual, jacobian, plus, w, out);
        break;
      case 2:
        finite = accumulate<2>(residual, jacobian, plus, w, out);
        break;
      case 3:
        finite = accumulate<3>(residual, jacobian, plus, w, out);
        break;
      case 4:
        finite = accumulate<4>(residual, jacobian, plus, w, out);
        break;
      default:
        break;
    }
    if (!finite) return false;
  }
  return std::isfinite(out.cost);
}

}  // namespace

PoseSolverSummary solve_pose(const std::vector<PoseTerm>& terms, double* pose,
                             const PoseSolverOptions& options) {
  PoseSolverSummary summary;
  for (const PoseTerm& term : terms) {
    if (term.cost == nullptr) return summary;
    const auto& blocks = term.cost->parameter_block_sizes();
    if (blocks.size() != 1 || blocks[0] != kPoseSize || term.cost->num_residuals() < 1 ||
        term.cost->num_residuals() > kMaxPoseResidual)
      return summary;
  }
  Linearisation at;
  if (!evaluate(terms, pose, true, at)) return summary;
  summary.usable = true;
  summary.initial_cost = summary.final_cost = at.cost;

  TrustRegion region(options.initial_radius);
  const SE3Manifold manifold;
  double candidate[kPoseSize];
  Linearisation trial;
  while (summary.iterations < options.max_iterations) {
    if (at.g.cwiseAbs().maxCoeff() <= options.gradient_tolerance) break;
    ++summary.iterations;
    // The step of the damped system, and the decrease the linear model predicts for it.
    Matrix6d damped = at.H;
    for (int i = 0; i < 6; ++i) damped(i, i) += region.damping(at.H(i, i));
    const Vector6d step = -damped.ldlt().solve(at.g);
    const double model_decrease = -(at.g.dot(step) + 0.5 * step.dot(at.H * step));
    const bool valid = step.allFinite() && model_decrease > 0.0;
    bool taken = false;
    if (valid) {
      manifold.Plus(pose, step.data(), candidate);
      const Eigen::Map<const Eigen::Matrix<double, kPoseSize, 1>> x(pose), y(candidate);
      if ((y - x).norm() <= options.parameter_tolerance * (x.norm() + options.parameter_tolerance))
        break;
      if (evaluate(terms, candidate, false, trial)) {
        const double change = at.cost - trial.cost;
        if (std::abs(change) <= options.function_tolerance * at.cost) {
          if (change > 0.0) {
            std::copy(candidate, candidate + kPoseSize, pose);
            summary.final_cost = trial.cost;
            ++summary.successful;
          }
          break;
        }
        const double relative_decrease = change / model_decrease;
        if (relative_decrease > TrustRegion::kMinRelativeDecrease) {
          std::copy(candidate, candidate + kPoseSize, pose);
          summary.final_cost = trial.cost;
          ++summary.successful;
          // The step is taken; a system that cannot be formed there (a Jacobian that is not
          // finite) stops the iterations at it.
          if (!evaluate(terms, pose, true, at)) break;
          region.accept(relative_decrease);
          taken = true;
        }
      }
    }
    if (!taken && !region.reject()) break;
  }
  summary.information = at.H;
  return summary;
}

}  // namespace mcslam::optim
