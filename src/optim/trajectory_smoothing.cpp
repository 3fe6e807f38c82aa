#include "mcslam/optim/trajectory_smoothing.hpp"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <vector>

#include "mcslam/core/error.hpp"

namespace mcslam::optim {
namespace {

/// Below this noise (metres per axis) smoothing changes nothing measurable; it also keeps the
/// measurement weight finite on exact data.
constexpr double kMinNoise = 1e-4;
/// Median absolute deviation to standard deviation (Gaussian).
constexpr double kMadToSigma = 1.4826;
/// Reweighting stops when no weight changes by more than this: the solution then moves by a
/// thousandth of the distance that earned a pose its weight, far below the noise.
constexpr double kWeightChange = 1e-3;

struct Segment {
  std::size_t begin = 0;
  std::size_t end = 0;  // one past the last pose
  std::size_t size() const { return end - begin; }
};

std::vector<Segment> split_segments(const Trajectory& trajectory, double max_gap,
                                    const std::vector<std::size_t>& breaks) {
  std::vector<Segment> segments;
  Segment current;
  for (std::size_t i = 1; i <= trajectory.size(); ++i) {
    const bool cut = i == trajectory.size() ||
                     !(trajectory[i].timestamp > trajectory[i - 1].timestamp) ||
                     trajectory[i].timestamp - trajectory[i - 1].timestamp > max_gap ||
                     std::binary_search(breaks.begin(), breaks.end(), i);
    if (!cut) continue;
    current.end = i;
    segments.push_back(current);
    current.begin = i;
  }
  return segments;
}

/// The second-difference operator of a segment: row k (frame begin + k + 1) is the change of
/// velocity dv = (p_next - p) / dt_after - (p - p_prev) / dt_before.
struct SecondDifferences {
  Eigen::SparseMatrix<double> D;
  Eigen::VectorXd mean_dt;  // (dt_before + dt_after) / 2 per row
  Eigen::VectorXd gain2;    // sum of the squared coefficients per row
};

SecondDifferences second_differences(const Trajectory& trajectory, const Segment& s) {
  const int n = static_cast<int>(s.size());
  SecondDifferences out;
  out.D.resize(n - 2, n);
  out.mean_dt.resize(n - 2);
  out.gain2.resize(n - 2);
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<std::size_t>(3 * (n - 2)));
  for (int k = 0; k + 2 < n; ++k) {
    const std::size_t i = s.begin + static_cast<std::size_t>(k) + 1;
    const double before = 1.0 / (trajectory[i].timestamp - trajectory[i - 1].timestamp);
    const double after = 1.0 / (trajectory[i + 1].timestamp - trajectory[i].timestamp);
    triplets.emplace_back(k, k, before);
    triplets.emplace_back(k, k + 1, -(before + after));
    triplets.emplace_back(k, k + 2, after);
    out.mean_dt[k] = 0.5 * (1.0 / before + 1.0 / after);
    out.gain2[k] = before * before + (before + after) * (before + after) + after * after;
  }
  out.D.setFromTriplets(triplets.begin(), triplets.end());
  return out;
}

Eigen::MatrixX3d positions(const Trajectory& trajectory, const Segment& s) {
  Eigen::MatrixX3d Y(static_cast<Eigen::Index>(s.size()), 3);
  for (std::size_t k = 0; k < s.size(); ++k)
    Y.row(static_cast<Eigen::Index>(k)) = trajectory[s.begin + k].T_w_c.translation().transpose();
  return Y;
}

double median(std::vector<double> values) {
  const auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

/// The positions' noise per axis from the second differences of all segments. A second
/// difference of white noise sigma is dv with variance sigma^2 * gain2; the motion adds
/// q * mean_dt, removed here with its median.
std::optional<double> estimate_noise(const std::vector<SecondDifferences>& ops,
                                     const std::vector<Eigen::MatrixX3d>& Y, double q) {
  std::vector<double> normalised;
  std::vector<double> motion;
  for (std::size_t s = 0; s < ops.size(); ++s) {
    const Eigen::MatrixX3d dv = ops[s].D * Y[s];
    for (Eigen::Index k = 0; k < dv.rows(); ++k) {
      const double scale = 1.0 / std::sqrt(ops[s].gain2[k]);
      for (int a = 0; a < 3; ++a) normalised.push_back(std::abs(dv(k, a)) * scale);
      motion.push_back(q * ops[s].mean_dt[k] / ops[s].gain2[k]);
    }
  }
  if (motion.size() < static_cast<std::size_t>(kMinSecondDifferences)) return std::nullopt;
  const double spread = kMadToSigma * median(normalised);
  const double variance = spread * spread - median(motion);
  return std::sqrt(std::max(variance, kMinNoise * kMinNoise));
}

/// Iteratively reweighted solves of one segment; returns the smoothed positions and counts the
/// poses still beyond the outlier distance.
Eigen::MatrixX3d smooth_segment(const SecondDifferences& op, const Eigen::MatrixX3d& Y,
                                double sigma, const TrajectorySmoothingOptions& options,
                                int& downweighted) {
  const Eigen::Index n = Y.rows();
  Eigen::VectorXd prior(op.mean_dt.size());
  for (Eigen::Index k = 0; k < prior.size(); ++k)
    prior[k] = 1.0 / (options.acceleration_density * op.mean_dt[k]);
  const Eigen::SparseMatrix<double> motion =
      Eigen::SparseMatrix<double>(op.D.transpose()) * prior.asDiagonal() * op.D;
  const double inv_var = 1.0 / (sigma * sigma);
  const double limit = options.outlier_sigmas * sigma;
  Eigen::VectorXd weights = Eigen::VectorXd::Ones(n);
  Eigen::MatrixX3d P = Y;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>>
      solver;
  for (int round = 0; round < options.iterations; ++round) {
    Eigen::SparseMatrix<double> H = motion;
    for (Eigen::Index i = 0; i < n; ++i) H.coeffRef(i, i) += weights[i] * inv_var;
    solver.compute(H);
    if (solver.info() != Eigen::Success) return Y;
    const Eigen::MatrixX3d rhs = (weights * inv_var).asDiagonal() * Y;
    P = solver.solve(rhs);
    if (solver.info() != Eigen::Success || !P.allFinite()) return Y;
    bool changed = false;
    for (Eigen::Index i = 0; i < n; ++i) {
      const double r = (P.row(i) - Y.row(i)).norm();
      const double w = r <= limit ? 1.0 : limit / r;
      changed = changed || std::abs(w - weights[i]) > kWeightChange;
      weights[i] = w;
    }
    if (!changed) break;
  }
  for (Eigen::Index i = 0; i < n; ++i)
    if ((P.row(i) - Y.row(i)).norm() > limit) ++downweighted;
  return P;
}

}  // namespace

std::optional<std::string> TrajectorySmoothingOptions::check() const {
  if (!std::isfinite(acceleration_density) || acceleration_density <= 0.0)
    return "trajectory.acceleration_density must be positive";
  if (!std::isfinite(outlier_sigmas) || outlier_sigmas <= 0.0)
    return "trajectory.outlier_sigmas must be positive";
  if (!std::isfinite(max_gap) || max_gap <= 0.0) return "trajectory.max_gap must be positive";
  if (iterations < 1) return "trajectory.iterations must be at least 1";
  return std::nullopt;
}

Trajectory smooth_trajectory(const Trajectory& trajectory,
                             const TrajectorySmoothingOptions& options,
                             TrajectorySmoothingReport* report,
                             const std::vector<std::size_t>& breaks) {
  if (auto problem = options.check()) throw InputError(*problem);
  TrajectorySmoothingReport local;
  TrajectorySmoothingReport& out = report ? *report : local;
  out = TrajectorySmoothingReport{};
  if (!options.enabled) return trajectory;

  std::vector<Segment> segments;
  for (const Segment& s : split_segments(trajectory, options.max_gap, breaks))
    if (s.size() >= 3) segments.push_back(s);
  std::vector<SecondDifferences> ops;
  std::vector<Eigen::MatrixX3d> Y;
  for (const Segment& s : segments) {
    ops.push_back(second_differences(trajectory, s));
    Y.push_back(positions(trajectory, s));
  }
  const std::optional<double> sigma = estimate_noise(ops, Y, options.acceleration_density);
  if (!sigma) return trajectory;

  Trajectory result = trajectory;
  double change2 = 0.0;
  for (std::size_t s = 0; s < segments.size(); ++s) {
    const Eigen::MatrixX3d P = smooth_segment(ops[s], Y[s], *sigma, options, out.downweighted);
    for (std::size_t k = 0; k < segments[s].size(); ++k) {
      StampedPose& pose = result[segments[s].begin + k];
      const Eigen::Vector3d p = P.row(static_cast<Eigen::Index>(k)).transpose();
      change2 += (p - pose.T_w_c.translation()).squaredNorm();
      pose.T_w_c = SE3::from_unit_quaternion(pose.T_w_c.quaternion(), p);
    }
  }
  out.applied = true;
  out.position_noise = *sigma;
  out.segments = static_cast<int>(segments.size());
  out.rms_change = trajectory.empty() ? 0.0 : std::sqrt(change2 / trajectory.size());
  return result;
}

}  // namespace mcslam::optim
