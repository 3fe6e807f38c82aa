#include "mcslam/optim/bundle_solver.hpp"

#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>
#include <optional>
#include <unordered_map>

#include "mcslam/core/se3.hpp"
#include "mcslam/optim/se3_manifold.hpp"
#include "optim/huber.hpp"
#include "optim/trust_region.hpp"

namespace mcslam::optim {
namespace {

constexpr int kMaxResidual = 4;
constexpr int kMaxLandmark = 6;

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Matrix76 = Eigen::Matrix<double, 7, 6, Eigen::RowMajor>;
/// Landmark-sized blocks (tangent t <= 6), on the stack.
using MatrixL =
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxLandmark, kMaxLandmark>;
using VectorL = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxLandmark, 1>;
using MatrixPL = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxLandmark>;
using MatrixRL = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor,
                               kMaxResidual, kMaxLandmark>;

/// The problem's layout: free poses numbered 0..F-1 (fixed ones -1), each landmark's tangent size
/// and its terms.
struct Layout {
  std::vector<int> free_index;
  int free_poses = 0;
  std::vector<int> tangent;
  std::vector<std::vector<int>> terms_of;
};

/// Where the parameters are: the poses' array and each landmark's block.
struct State {
  const double* poses = nullptr;
  std::vector<const double*> landmarks;
};

/// The cost and the Gauss-Newton blocks (Huber-weighted) at a state.
struct System {
  double cost = 0.0;
  std::vector<Matrix6d> Hpp;  // per free pose
  std::vector<Vector6d> gp;
  std::vector<MatrixL> Hll;  // per landmark
  std::vector<VectorL> gl;
  std::vector<MatrixPL> W;  // per term whose pose is free: J_pose^T w J_landmark
};

/// Adds term k (residual of Dim rows, landmark of T tangent unknowns; Eigen::Dynamic: the sizes
/// given at run time) to the system: the tangent Jacobians are the ambient ones times the charts'
/// Jacobians (`pose_plus` nullptr: the pose is fixed; `landmark_plus` nullptr: Euclidean).
template <int Dim, int T>
bool accumulate(const double* residual, const double* jacobian_pose,
                const double* jacobian_landmark, const Matrix76* pose_plus,
                const MatrixL* landmark_plus, double w, std::size_t l, int free, std::size_t k,
                System& out, int dim = Dim, int ambient = T, int tangent = T) {
  constexpr int kRows = Dim == Eigen::Dynamic ? kMaxResidual : Dim;
  constexpr int kCols = T == Eigen::Dynamic ? kMaxLandmark : T;
  using Residual = Eigen::Matrix<double, Dim, 1, 0, kRows, 1>;
  using JacobianL = Eigen::Matrix<double, Dim, T, Eigen::RowMajor, kRows, kCols>;
  using Ambient = Eigen::Matrix<double, Dim, Eigen::Dynamic, Eigen::RowMajor, kRows, kMaxLandmark>;
  const Eigen::Map<const Residual> r(residual, dim);
  JacobianL Jl;
  if (landmark_plus != nullptr)
    Jl = Eigen::Map<const Ambient>(jacobian_landmark, dim, ambient) * *landmark_plus;
  else
    Jl = Eigen::Map<const JacobianL>(jacobian_landmark, dim, tangent);
  if (!Jl.allFinite()) return false;
  out.Hll[l].topLeftCorner(tangent, tangent).noalias() += w * (Jl.transpose() * Jl);
  out.gl[l].head(tangent).noalias() += w * (Jl.transpose() * r);
  if (free < 0) return true;
  using Jacobian7 = Eigen::Matrix<double, Dim, 7, Eigen::RowMajor, kRows, 7>;
  const Eigen::Matrix<double, Dim, 6, 0, kRows, 6> Jp =
      Eigen::Map<const Jacobian7>(jacobian_pose, dim, 7) * *pose_plus;
  if (!Jp.allFinite()) return false;
  out.Hpp[static_cast<std::size_t>(free)].noalias() += w * (Jp.transpose() * Jp);
  out.gp[static_cast<std::size_t>(free)].noalias() += w * (Jp.transpose() * r);
  out.W[k].noalias() = w * (Jp.transpose() * Jl);
  return true;
}

bool evaluate(const std::vector<BundleTerm>& terms, const std::vector<BundleLandmark>& landmarks,
              const Layout& layout, const State& state, bool normal, System& out) {
  out.cost = 0.0;
  std::vector<Matrix76> pose_plus;
  std::vector<MatrixL> landmark_plus;  // ambient x tangent, for landmarks with a manifold
  if (normal) {
    out.Hpp.assign(static_cast<std::size_t>(layout.free_poses), Matrix6d::Zero());
    out.gp.assign(static_cast<std::size_t>(layout.free_poses), Vector6d::Zero());
    out.Hll.resize(landmarks.size());
    out.gl.resize(landmarks.size());
    landmark_plus.resize(landmarks.size());
    for (std::size_t l = 0; l < landmarks.size(); ++l) {
      const int t = layout.tangent[l];
      out.Hll[l].setZero(t, t);
      out.gl[l].setZero(t);
      if (landmarks[l].manifold) {
        Eigen::Matrix<double, kMaxLandmark, kMaxLandmark, Eigen::RowMajor> J;
        landmarks[l].manifold->PlusJacobian(state.landmarks[l], J.data());
        // Row-major ambient x tangent, packed at the start of J's storage.
        landmark_plus[l] = Eigen::Map<
            const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
            J.data(), landmarks[l].ambient, t);
      }
    }
    pose_plus.resize(layout.free_index.size());
    for (std::size_t p = 0; p < layout.free_index.size(); ++p)
      if (layout.free_index[p] >= 0)
        SE3Manifold().PlusJacobian(state.poses + p * kPoseSize, pose_plus[p].data());
    out.W.resize(terms.size());
  }
  double residual[kMaxResidual];
  double jacobian_pose[kMaxResidual * kPoseSize];
  double jacobian_landmark[kMaxResidual * kMaxLandmark];
  for (std::size_t k = 0; k < terms.size(); ++k) {
    const BundleTerm& term = terms[k];
    const int dim = term.cost->num_residuals();
    const int free = layout.free_index[static_cast<std::size_t>(term.pose)];
    const double* parameters[2] = {state.poses + static_cast<std::size_t>(term.pose) * kPoseSize,
                                   state.landmarks[static_cast<std::size_t>(term.landmark)]};
    double* jacobians[2] = {free >= 0 ? jacobian_pose : nullptr, jacobian_landmark};
    if (!term.cost->Evaluate(parameters, residual, normal ? jacobians : nullptr)) return false;
    const Eigen::Map<const Eigen::VectorXd> r(residual, dim);
    const double s = r.squaredNorm();
    if (!std::isfinite(s)) return false;
    const HuberTerm loss = huber(s, term.huber_delta);
    out.cost += 0.5 * loss.rho;
    if (!normal) continue;
    const std::size_t l = static_cast<std::size_t>(term.landmark);
    const BundleLandmark& landmark = landmarks[l];
    const Matrix76* plus = free >= 0 ? &pose_plus[static_cast<std::size_t>(term.pose)] : nullptr;
    const MatrixL* landmark_chart = landmark.manifold ? &landmark_plus[l] : nullptr;
    // Points (3 unknowns, residuals of 3 or 2) in fixed sizes; the rest in bounded dynamic ones.
    bool finite = false;
    if (landmark.ambient == 3 && !landmark.manifold && dim == 3)
      finite = accumulate<3, 3>(residual, jacobian_pose, jacobian_landmark, plus, nullptr,
                                loss.weight, l, free, k, out);
    else if (landmark.ambient == 3 && !landmark.manifold && dim == 2)
      finite = accumulate<2, 3>(residual, jacobian_pose, jacobian_landmark, plus, nullptr,
                                loss.weight, l, free, k, out);
    else
      finite = accumulate<Eigen::Dynamic, Eigen::Dynamic>(
          residual, jacobian_pose, jacobian_landmark, plus, landmark_chart, loss.weight, l, free, k,
          out, dim, landmark.ambient, layout.tangent[l]);
    if (!finite) return false;
  }
  return std::isfinite(out.cost);
}

/// The damped system's diagonal (TrustRegion::damping).
template <typename Matrix>
void damp(Matrix& H, const TrustRegion& region) {
  for (Eigen::Index i = 0; i < H.rows(); ++i) H(i, i) += region.damping(H(i, i));
}

/// The poses' system after the landmarks' elimination, S dp = b, by 6x6 blocks of pose pairs
/// (upper triangle). Dense up to kDenseLimit free poses (a local window, where every keyframe
/// sees most others); beyond, sparse with a fill-reducing ordering (a whole map's adjustment,
/// where a keyframe sees its neighbours only: the dense factorisation would grow with the cube of
/// the map's size).
class ReducedSystem {
 public:
  static constexpr int kDenseLimit = 96;

  explicit ReducedSystem(int poses)
      : poses_(poses), dense_(poses <= kDenseLimit), b_(Eigen::VectorXd::Zero(6 * poses)) {
    if (dense_) S_ = Eigen::MatrixXd::Zero(6 * poses, 6 * poses);
  }

  /// S(row, col) += M for row <= col (in pose indices).
  void add(int row, int col, const Matrix6d& M) {
    if (dense_) {
      S_.block<6, 6>(6 * row, 6 * col) += M;
      return;
    }
    const auto [it, fresh] = blocks_.try_emplace(static_cast<long>(row) * poses_ + col);
    if (fresh) it->second.setZero();
    it->second += M;
  }
  /// The contribution M of the pair of terms (a on pose pa, c on pose pc) and of its mirror.
  void subtract_pair(int pa, int pc, bool same_term, const Matrix6d& M) {
    if (same_term)
      add(pa, pa, -M);
    else if (pa < pc)
      add(pa, pc, -M);
    else if (pa > pc)
      add(pc, pa, -M.transpose());
    else
      add(pa, pa, -(M + M.transpose()));
  }
  Eigen::VectorXd& rhs() { return b_; }

  bool solve(Eigen::VectorXd& dp) const {
    if (poses_ == 0) {  // every pose fixed: the landmarks alone move
      dp.resize(0);
      return true;
    }
    if (dense_) {
      const Eigen::LDLT<Eigen::MatrixXd, Eigen::Upper> ldlt(S_);
      if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return false;
      dp = ldlt.solve(b_);
      return dp.allFinite();
    }
    std::vector<Eigen::Triplet<double>> entries;
    entries.reserve(blocks_.size() * 36);
    for (const auto& [key, M] : blocks_) {
      const int row = static_cast<int>(key / poses_), col = static_cast<int>(key % poses_);
      for (int i = 0; i < 6; ++i)
        for (int j = row == col ? i : 0; j < 6; ++j)
          entries.emplace_back(6 * row + i, 6 * col + j, M(i, j));
    }
    Eigen::SparseMatrix<double> S(6 * poses_, 6 * poses_);
    S.setFromTriplets(entries.begin(), entries.end());
    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Upper> ldlt(S);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 0.0)) return false;
    dp = ldlt.solve(b_);
    return dp.allFinite();
  }

 private:
  int poses_;
  bool dense_;
  Eigen::MatrixXd S_;
  std::unordered_map<long, Matrix6d> blocks_;
  Eigen::VectorXd b_;
};

/// Folds landmark l (T tangent unknowns; Eigen::Dynamic: its size at run time) into the poses'
/// system S dp = b: S -= W C^-1 W^T over pairs of its terms, b += W C^-1 g_l.
template <int T>
void eliminate(const std::vector<BundleTerm>& terms, const Layout& layout, const System& sys,
               std::size_t l, const MatrixL& C_inverse, ReducedSystem& S) {
  constexpr int kCols = T == Eigen::Dynamic ? kMaxLandmark : T;
  using Square = Eigen::Matrix<double, T, T, 0, kCols, kCols>;
  using Coupling = Eigen::Matrix<double, 6, T, 0, 6, kCols>;
  const int t = layout.tangent[l];
  const Square C_inv = C_inverse.topLeftCorner(t, t);
  const Eigen::Matrix<double, T, 1, 0, kCols, 1> g = sys.gl[l].head(t);
  const std::vector<int>& own = layout.terms_of[l];
  for (std::size_t a = 0; a < own.size(); ++a) {
    const BundleTerm& ta = terms[static_cast<std::size_t>(own[a])];
    const int pa = layout.free_index[static_cast<std::size_t>(ta.pose)];
    if (pa < 0) continue;
    const Coupling Y = Coupling(sys.W[static_cast<std::size_t>(own[a])].leftCols(t)) * C_inv;
    S.rhs().segment<6>(6 * pa).noalias() += Y * g;
    for (std::size_t c = a; c < own.size(); ++c) {
      const BundleTerm& tc = terms[static_cast<std::size_t>(own[c])];
      const int pc = layout.free_index[static_cast<std::size_t>(tc.pose)];
      if (pc < 0) continue;
      S.subtract_pair(
          pa, pc, c == a,
          Y * Coupling(sys.W[static_cast<std::size_t>(own[c])].leftCols(t)).transpose());
    }
  }
}

/// The Levenberg-Marquardt step at `sys` (poses' tangent steps in dp, 6 per free pose, and each
/// landmark's in dl), the landmarks eliminated; false when a system is not positive definite.
bool step(const std::vector<BundleTerm>& terms, const Layout& layout, const System& sys,
          const TrustRegion& region, Eigen::VectorXd& dp, std::vector<VectorL>& dl) {
  ReducedSystem S(layout.free_poses);
  for (int p = 0; p < layout.free_poses; ++p) {
    Matrix6d A = sys.Hpp[static_cast<std::size_t>(p)];
    damp(A, region);
    S.add(p, p, A);
    S.rhs().segment<6>(6 * p) = -sys.gp[static_cast<std::size_t>(p)];
  }
  std::vector<MatrixL> C_inverse(sys.Hll.size());
  for (std::size_t l = 0; l < sys.Hll.size(); ++l) {
    if (layout.terms_of[l].empty()) continue;
    MatrixL C = sys.Hll[l];
    damp(C, region);
    const Eigen::LDLT<MatrixL> ldlt(C);
    if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return false;
    C_inverse[l] = ldlt.solve(MatrixL::Identity(C.rows(), C.cols()));
    // Points (3 unknowns) in fixed sizes.
    if (layout.tangent[l] == 3)
      eliminate<3>(terms, layout, sys, l, C_inverse[l], S);
    else
      eliminate<Eigen::Dynamic>(terms, layout, sys, l, C_inverse[l], S);
  }
  if (!S.solve(dp)) return false;
  dl.resize(sys.Hll.size());
  for (std::size_t l = 0; l < sys.Hll.size(); ++l) {
    const std::vector<int>& own = layout.terms_of[l];
    if (own.empty()) {
      dl[l].setZero(layout.tangent[l]);
      continue;
    }
    VectorL rhs = -sys.gl[l];
    for (int k : own) {
      const int p =
          layout.free_index[static_cast<std::size_t>(terms[static_cast<std::size_t>(k)].pose)];
      if (p >= 0)
        rhs.noalias() -= sys.W[static_cast<std::size_t>(k)].transpose() * dp.segment<6>(6 * p);
    }
    dl[l] = C_inverse[l] * rhs;
    if (!dl[l].allFinite()) return false;
  }
  return true;
}

/// The decrease the linear model predicts for a step: -(g . dx + dx^T H dx / 2), H undamped.
double model_decrease(const std::vector<BundleTerm>& terms, const Layout& layout, const System& sys,
                      const Eigen::VectorXd& dp, const std::vector<VectorL>& dl) {
  double linear = 0.0, quadratic = 0.0;
  for (int p = 0; p < layout.free_poses; ++p) {
    const auto d = dp.segment<6>(6 * p);
    linear += sys.gp[static_cast<std::size_t>(p)].dot(d);
    quadratic += d.dot(sys.Hpp[static_cast<std::size_t>(p)] * d);
  }
  for (std::size_t l = 0; l < sys.Hll.size(); ++l) {
    if (layout.terms_of[l].empty()) continue;
    linear += sys.gl[l].dot(dl[l]);
    quadratic += dl[l].dot(sys.Hll[l] * dl[l]);
    for (int k : layout.terms_of[l]) {
      const int p =
          layout.free_index[static_cast<std::size_t>(terms[static_cast<std::size_t>(k)].pose)];
      if (p >= 0)
        quadratic += 2.0 * dp.segment<6>(6 * p).dot(sys.W[static_cast<std::size_t>(k)] * dl[l]);
    }
  }
  return -(linear + 0.5 * quadratic);
}

bool valid_shape(const BundleTerm& term, const std::vector<BundleLandmark>& landmarks,
                 std::size_t num_poses) {
  if (term.cost == nullptr || term.pose < 0 || static_cast<std::size_t>(term.pose) >= num_poses ||
      term.landmark < 0 || static_cast<std::size_t>(term.landmark) >= landmarks.size())
    return false;
  const auto& blocks = term.cost->parameter_block_sizes();
  const BundleLandmark& l = landmarks[static_cast<std::size_t>(term.landmark)];
  return blocks.size() == 2 && blocks[0] == kPoseSize && blocks[1] == l.ambient &&
         term.cost->num_residuals() >= 1 && term.cost->num_residuals() <= kMaxResidual;
}

/// The layout of a problem, or nothing when a block or a term does not have the shape the solver
/// takes (see bundle_solver.hpp).
std::optional<Layout> make_layout(const std::vector<BundleTerm>& terms,
                                  const std::vector<bool>& pose_fixed,
                                  const std::vector<BundleLandmark>& landmarks) {
  Layout layout;
  layout.free_index.assign(pose_fixed.size(), -1);
  for (std::size_t p = 0; p < pose_fixed.size(); ++p)
    if (!pose_fixed[p]) layout.free_index[p] = layout.free_poses++;
  layout.tangent.resize(landmarks.size());
  layout.terms_of.resize(landmarks.size());
  for (std::size_t l = 0; l < landmarks.size(); ++l) {
    const BundleLandmark& lm = landmarks[l];
    if (lm.x == nullptr || lm.ambient < 1 || lm.ambient > kMaxLandmark) return std::nullopt;
    if (lm.manifold && (lm.manifold->AmbientSize() != lm.ambient ||
                        lm.manifold->TangentSize() < 1 || lm.manifold->TangentSize() > lm.ambient))
      return std::nullopt;
    layout.tangent[l] = lm.manifold ? lm.manifold->TangentSize() : lm.ambient;
  }
  for (std::size_t k = 0; k < terms.size(); ++k) {
    if (!valid_shape(terms[k], landmarks, pose_fixed.size())) return std::nullopt;
    layout.terms_of[static_cast<std::size_t>(terms[k].landmark)].push_back(static_cast<int>(k));
  }
  return layout;
}

/// The largest component of the gradient.
double largest_gradient(const System& sys) {
  double largest = 0.0;
  for (const Vector6d& g : sys.gp) largest = std::max(largest, g.cwiseAbs().maxCoeff());
  for (const VectorL& g : sys.gl)
    if (g.size() > 0) largest = std::max(largest, g.cwiseAbs().maxCoeff());
  return largest;
}

/// The parameters a step leads to: every pose (fixed ones copied) and every landmark, in buffers
/// of their own until the step is taken.
class Candidate {
 public:
  Candidate(const double* poses, std::size_t num_poses,
            const std::vector<BundleLandmark>& landmarks)
      : poses_(poses, poses + num_poses * kPoseSize), landmarks_(landmarks.size()) {
    state_.poses = poses_.data();
    for (std::size_t l = 0; l < landmarks.size(); ++l) {
      landmarks_[l].assign(landmarks[l].x, landmarks[l].x + landmarks[l].ambient);
      state_.landmarks.push_back(landmarks_[l].data());
    }
  }

  const State& state() const { return state_; }

  /// Moves to the step (dp, dl) from the current parameters; true when it moves them by no more
  /// than `tolerance` of their norm (Ceres's parameter tolerance: the iterations stop).
  bool step_from(const double* poses, const std::vector<BundleLandmark>& landmarks,
                 const Layout& layout, const Eigen::VectorXd& dp, const std::vector<VectorL>& dl,
                 double tolerance) {
    const SE3Manifold pose_manifold;
    double moved = 0.0, norm = 0.0;
    for (std::size_t p = 0; p < layout.free_index.size(); ++p) {
      const double* x = poses + p * kPoseSize;
      double* y = poses_.data() + p * kPoseSize;
      const int f = layout.free_index[p];
      if (f < 0) continue;  // copied at construction, never moved
      pose_manifold.Plus(x, dp.data() + 6 * f, y);
      for (int i = 0; i < kPoseSize; ++i) {
        moved += (y[i] - x[i]) * (y[i] - x[i]);
        norm += x[i] * x[i];
      }
    }
    for (std::size_t l = 0; l < landmarks.size(); ++l) {
      const BundleLandmark& lm = landmarks[l];
      double* y = landmarks_[l].data();
      if (lm.manifold)
        lm.manifold->Plus(lm.x, dl[l].data(), y);
      else
        for (int i = 0; i < lm.ambient; ++i) y[i] = lm.x[i] + dl[l][i];
      for (int i = 0; i < lm.ambient; ++i) {
        moved += (y[i] - lm.x[i]) * (y[i] - lm.x[i]);
        norm += lm.x[i] * lm.x[i];
      }
    }
    return std::sqrt(moved) <= tolerance * (std::sqrt(norm) + tolerance);
  }

  /// Takes the step: the current parameters become the candidate's.
  void copy_to(double* poses, const std::vector<BundleLandmark>& landmarks) const {
    std::copy(poses_.begin(), poses_.end(), poses);
    for (std::size_t l = 0; l < landmarks.size(); ++l)
      std::copy(landmarks_[l].begin(), landmarks_[l].end(), landmarks[l].x);
  }

 private:
  std::vector<double> poses_;
  std::vector<std::vector<double>> landmarks_;
  State state_;
};

}  // namespace

BundleSolverSummary solve_bundle(const std::vector<BundleTerm>& terms, double* poses,
                                 const std::vector<bool>& pose_fixed,
                                 const std::vector<BundleLandmark>& landmarks,
                                 const BundleSolverOptions& options) {
  BundleSolverSummary summary;
  const std::optional<Layout> layout = make_layout(terms, pose_fixed, landmarks);
  if (!layout) return summary;
  State current;
  current.poses = poses;
  for (const BundleLandmark& lm : landmarks) current.landmarks.push_back(lm.x);
  System sys;
  if (!evaluate(terms, landmarks, *layout, current, true, sys)) return summary;
  summary.usable = true;
  summary.initial_cost = summary.final_cost = sys.cost;
  const auto aborted = [&] {
    return options.abort != nullptr && options.abort->load(std::memory_order_relaxed);
  };
  if (aborted()) {
    summary.aborted = true;
    return summary;
  }

  Candidate candidate(poses, pose_fixed.size(), landmarks);
  TrustRegion region(options.initial_radius);
  Eigen::VectorXd dp;
  std::vector<VectorL> dl;
  System trial;
  while (summary.iterations < options.max_iterations) {
    if (largest_gradient(sys) <= options.gradient_tolerance) break;
    ++summary.iterations;
    bool taken = false;
    const bool solved = step(terms, *layout, sys, region, dp, dl);
    const double predicted = solved ? model_decrease(terms, *layout, sys, dp, dl) : 0.0;
    if (solved && predicted > 0.0) {
      if (candidate.step_from(poses, landmarks, *layout, dp, dl, options.parameter_tolerance))
        break;
      if (evaluate(terms, landmarks, *layout, candidate.state(), false, trial)) {
        const double change = sys.cost - trial.cost;
        const bool converged = std::abs(change) <= options.function_tolerance * sys.cost;
        const double relative_decrease = change / predicted;
        if ((converged && change > 0.0) ||
            (!converged && relative_decrease > TrustRegion::kMinRelativeDecrease)) {
          candidate.copy_to(poses, landmarks);
          ++summary.successful;
          summary.final_cost = trial.cost;
          // A system that cannot be formed at the step taken (a Jacobian that is not finite)
          // stops the iterations there.
          if (converged || !evaluate(terms, landmarks, *layout, current, true, sys)) break;
          region.accept(relative_decrease);
          taken = true;
        } else if (converged) {
          break;
        }
      }
    }
    if (aborted()) {
      summary.aborted = true;
      break;
    }
    if (!taken && !region.reject()) break;
  }
  return summary;
}

}  // namespace mcslam::optim
