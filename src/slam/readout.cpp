#include "mcslam/slam/readout.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

namespace mcslam::slam {

std::optional<std::string> ReadoutOptions::check() const {
  if (!(min_angular_velocity >= 0.0) || !std::isfinite(min_angular_velocity))
    return "readout.min_angular_velocity must be finite and >= 0";
  if (min_points < 7) return "readout.min_points must be at least 7 (6 pose parameters and r)";
  if (min_frames < 2) return "readout.min_frames must be at least 2";
  if (!(max_std > 0.0) || !std::isfinite(max_std)) return "readout.max_std must be positive";
  if (!(min_significance >= 0.0) || !std::isfinite(min_significance))
    return "readout.min_significance must be finite and >= 0";
  if (!(huber > 0.0) || !std::isfinite(huber)) return "readout.huber must be positive";
  if (!(max_readout > 0.0 && max_readout <= 0.1)) return "readout.max_readout must be in (0, 0.1]";
  if (!(anchor_age > 0.0) || !std::isfinite(anchor_age))
    return "readout.anchor_age must be positive";
  if (!(calibration_seconds >= 0.0) || !std::isfinite(calibration_seconds))
    return "readout.calibration_seconds must be finite and >= 0";
  return std::nullopt;
}

ReadoutEstimator::ReadoutEstimator(const PinholeCamera& camera, const ReadoutOptions& options)
    : camera_(camera), options_(options), in_use_(camera.readout_time) {}

namespace {
Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}
}  // namespace

Eigen::Matrix<double, 2, 7> readout_jacobian(const PinholeCamera& camera, const SE3& T_b_a,
                                             const Eigen::Vector3d& p_a, double s_a,
                                             const CameraTwist& motion_a, double v,
                                             const CameraTwist& motion) {
  const Eigen::Vector3d q = T_b_a * p_a;
  const Eigen::Matrix<double, 2, 3> J = camera.project_jacobian(q);
  const double s = (v - 0.5 * camera.height) / camera.height;
  Eigen::Matrix<double, 2, 7> out;
  out.leftCols<3>() = -J;              // q + t
  out.middleCols<3>(3) = J * skew(q);  // q + theta x q = q - [q]x theta
  const Eigen::Vector3d moved_a = motion_a.omega.cross(p_a) + motion_a.nu;
  out.col(6) = -s * J * (motion.omega.cross(q) + motion.nu)  // the keypoint moves
               + s_a * J * (T_b_a.rotation() * moved_a);     // and the anchor's point
  return out;
}

ReadoutEquation ReadoutEstimator::pair_equation(const ReadoutFrame& frame,
                                                const CameraTwist& motion,
                                                const AnchorFrame& anchor, double huber_at) const {
  // Residual of a point paired with its anchor: e(xi, r) = x(r) - pi(exp(xi) T_b_a p_a(r)), x(r)
  // the keypoint compensated with readout r at the true motion, p_a(r) the anchor's point
  // likewise. Both were compensated with the angular velocity and readout then in use; to first
  // order in the small motion during the readout e is linear in r: e = c + j r + J_xi xi. The
  // row v is that of the compensated keypoint, within a few pixels of the raw row (a relative
  // error of s below 1 %).
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> B = Eigen::Matrix<double, 6, 1>::Zero();
  Eigen::Matrix<double, 6, 1> g_xi = Eigen::Matrix<double, 6, 1>::Zero();
  double C = 0.0, g_r = 0.0;
  int used = 0;
  const double H = camera_.height;
  const SE3 T_b_a = frame.T_c_w * anchor.T_c_w.inverse();
  const Eigen::Matrix3d R_b_a = T_b_a.rotation();
  for (const ReadoutPoint& p : frame.points) {
    const auto it = anchor.points.find(p.landmark);
    if (it == anchor.points.end()) continue;
    const AnchorPoint& a = it->second;
    const Eigen::Vector3d q = T_b_a * a.p_c;
    if (!(q.z() > 0.0)) continue;
    const Eigen::Matrix<double, 2, 7> Jr =
        readout_jacobian(camera_, T_b_a, a.p_c, a.s, anchor.motion, p.uv.y(), motion);
    const Eigen::Matrix<double, 2, 6> J_xi = Jr.leftCols<6>();
    const Eigen::Vector2d j = Jr.col(6);
    const Eigen::Matrix<double, 2, 3> J = camera_.project_jacobian(q);
    const double s = (p.uv.y() - 0.5 * H) / H;
    const Eigen::Vector2d c =
        p.uv - camera_.project(q) + s * J * frame.omega_used.cross(q) * frame.readout_used -
        a.s * J * (R_b_a * anchor.omega_used.cross(a.p_c)) * anchor.readout_used;
    // Both keypoints' noise: 1 / (sigma_a^2 + sigma_b^2).
    const double information = 1.0 / (1.0 / p.information + 1.0 / a.information);
    // Huber weight on the whitened error at the readout the weights are taken at.
    const double err = std::sqrt(information) * (c + j * huber_at).norm();
    const double w = information * (err <= options_.huber ? 1.0 : options_.huber / err);
    A += w * J_xi.transpose() * J_xi;
    B += w * J_xi.transpose() * j;
    g_xi += w * J_xi.transpose() * c;
    C += w * j.squaredNorm();
    g_r += w * j.dot(c);
    ++used;
  }
  ReadoutEquation eq;
  eq.points = used;
  if (used < options_.min_points) return eq;
  const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(A);
  if (ldlt.info() != Eigen::Success) return eq;
  eq.h = C - B.dot(ldlt.solve(B));
  eq.g = g_r - B.dot(ldlt.solve(g_xi));
  if (!(eq.h > 0.0) || !std::isfinite(eq.g)) eq = ReadoutEquation{0.0, 0.0, used};
  return eq;
}

ReadoutEquation ReadoutEstimator::equation(const ReadoutFrame& frame, const CameraTwist& motion,
                                           double huber_at) const {
  // Anchors a third, two thirds and all of anchor_age old (the nearest held frames): pairs
  // whose motions differ (a turn and its return) tell most.
  ReadoutEquation sum;
  const AnchorFrame* last = nullptr;
  for (int k = 1; k <= 3; ++k) {
    const double age = options_.anchor_age * k / 3.0;
    const AnchorFrame* best = nullptr;
    for (const AnchorFrame& a : history_)
      if (!best || std::abs(frame.timestamp - a.timestamp - age) <
                       std::abs(frame.timestamp - best->timestamp - age))
        best = &a;
    if (!best || best == last || !(frame.timestamp > best->timestamp)) continue;
    last = best;
    const ReadoutEquation eq = pair_equation(frame, motion, *best, huber_at);
    if (!(eq.h > 0.0)) continue;
    sum.h += eq.h;
    sum.g += eq.g;
    sum.points += eq.points;
  }
  return sum;
}

void ReadoutEstimator::add(ReadoutFrame frame) {
  // Motion over the step from the previous frame (the angular velocity as
  // Tracker::angular_velocity()).
  CameraTwist back;
  bool have_back = false;
  if (last_T_c_w_) {
    const double dt = frame.timestamp - last_timestamp_;
    // Consecutive frames only: a gap of more than a few frames (a lost or dropped stretch) makes
    // the difference of poses no velocity at either end.
    if (dt > 1e-4 && dt < 0.2) {
      const SE3 step = frame.T_c_w * last_T_c_w_->inverse();
      back.omega = so3_log(step.quaternion()) / dt;
      back.nu = step.translation() / dt;
      have_back = true;
    }
  }
  // The held frame's motion at its capture time: the mean of the steps before and after it (a
  // central difference).
  if (pending_ && have_back) {
    CameraTwist central;
    central.omega = 0.5 * (pending_back_.omega + back.omega);
    central.nu = 0.5 * (pending_back_.nu + back.nu);
    accumulate(*pending_, central);
  }
  last_T_c_w_ = frame.T_c_w;
  last_timestamp_ = frame.timestamp;
  if (have_back) {
    pending_back_ = back;
    pending_ = std::move(frame);
  } else {
    pending_.reset();
  }
}

void ReadoutEstimator::accumulate(const ReadoutFrame& frame, const CameraTwist& motion) {
  const double at = frames_ > 0 ? estimate_ : frame.readout_used;
  const ReadoutEquation eq = motion.omega.norm() < options_.min_angular_velocity
                                 ? ReadoutEquation{}
                                 : equation(frame, motion, at);
  // This frame becomes an anchor for the next anchor_age seconds.
  const double H = camera_.height;
  AnchorFrame held;
  held.timestamp = frame.timestamp;
  held.T_c_w = frame.T_c_w;
  held.motion = motion;
  held.omega_used = frame.omega_used;
  held.readout_used = frame.readout_used;
  for (const ReadoutPoint& p : frame.points)
    held.points[p.landmark] = {camera_.unproject(p.uv, p.depth), (p.uv.y() - 0.5 * H) / H,
                               p.information};
  history_.push_back(std::move(held));
  while (!history_.empty() &&
         frame.timestamp - history_.front().timestamp > options_.anchor_age * 1.1)
    history_.pop_front();
  if (!(eq.h > 0.0)) return;
  const double r = -eq.g / eq.h;
  if (std::abs(r) - options_.max_readout > 3.0 / std::sqrt(eq.h)) {
    ++rejected_;
    return;
  }
  sum_h_ += eq.h;
  sum_g_ += eq.g;
  sum_hrr_ += eq.h * r * r;
  ++frames_;
  ++epoch_frames_;
  last_frame_timestamp_ = frame.timestamp;
  update();
}

void ReadoutEstimator::update() {
  // The estimate of the current epoch (its frames only).
  const double estimate = -sum_g_ / sum_h_;
  // The formal variance 1 / sum h assumes the keypoint noise of the pyramid levels and
  // independent frames; the frames' own estimates scatter more (map errors, the velocity's
  // error), so their weighted scatter scales it when larger.
  const double formal = 1.0 / sum_h_;
  double scaled = formal;
  if (epoch_frames_ > 1) {
    const double scatter = std::max(0.0, sum_hrr_ - estimate * estimate * sum_h_);
    scaled = scatter / (epoch_frames_ - 1) / sum_h_;
  }
  const double std = std::sqrt(std::max(formal, scaled));
  const bool good = epoch_frames_ >= options_.min_frames && std < options_.max_std;
  if (good || !confident_) {
    estimate_ = estimate;
    std_ = std;
  }
  if (!good) return;
  if (!confident_) {
    confident_at_ = last_frame_timestamp_;
    frames_when_confident_ = frames_;
  }
  confident_ = true;
  in_use_ = std::abs(estimate_) >= options_.min_significance * std_ ? estimate_ : 0.0;
  // The equations are linearised around the compensation in use and the tracked poses, both
  // off by the readout's error until it is known: each epoch starts afresh from frames
  // compensated with the last epoch's estimate (iterating the linearisation). Epochs double in
  // length (min_frames, 2 min_frames, ...) so that the later ones average over longer stretches.
  if (epoch_frames_ >= options_.min_frames << std::min(epoch_, 16)) {
    ++epoch_;
    epoch_frames_ = 0;
    sum_h_ = sum_g_ = sum_hrr_ = 0.0;
  }
}

ReadoutReport ReadoutEstimator::report() const {
  ReadoutReport r;
  r.automatic = true;
  r.readout_time = in_use_;
  r.estimate = estimate_;
  r.std = std_;
  r.frames_used = frames_;
  r.epochs = epoch_;
  r.frames_rejected = rejected_;
  r.confident = confident_;
  r.confident_at = confident_at_;
  r.frames_used_when_confident = frames_when_confident_;
  return r;
}

}  // namespace mcslam::slam
