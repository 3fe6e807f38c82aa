#include "mcslam/optim/pose_filter.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

namespace mcslam::optim {

std::optional<std::string> PoseFilterOptions::check() const {
  const auto positive = [](double x) { return std::isfinite(x) && x > 0.0; };
  if (!positive(acceleration_density))
    return "pose_filter.acceleration_density must be a positive number (m^2/s^3)";
  if (!positive(angular_acceleration_density))
    return "pose_filter.angular_acceleration_density must be a positive number (rad^2/s^3)";
  if (!positive(measurement_noise_scale))
    return "pose_filter.measurement_noise_scale must be a positive number";
  if (!positive(downweight_chi2)) return "pose_filter.downweight_chi2 must be a positive number";
  if (!positive(gate_chi2)) return "pose_filter.gate_chi2 must be a positive number";
  if (held_frames < 0 || held_frames > 30)
    return "pose_filter.held_frames must be a number of frames from 0 to 30";
  if (!positive(max_gap)) return "pose_filter.max_gap must be a positive number of seconds";
  if (!(std::isfinite(adaptive_memory) && adaptive_memory >= 0.0))
    return "pose_filter.adaptive_memory must be a number of seconds >= 0 (0: fixed densities)";
  if (!(std::isfinite(max_liveliness) && max_liveliness >= 1.0))
    return "pose_filter.max_liveliness must be a number >= 1";
  if (!(std::isfinite(noise_window) && noise_window >= 0.0))
    return "pose_filter.noise_window must be a number of seconds >= 0 (0: the optimiser's "
           "covariance as it is)";
  if (lag < 0 || lag > 300) return "pose_filter.lag must be a number of frames from 0 to 300";
  if (lag > 0 && !enabled) return "pose_filter.lag needs pose_filter.enabled: true";
  return std::nullopt;
}

namespace {

using Matrix3d = Eigen::Matrix3d;
using Vector3d = Eigen::Vector3d;
using Matrix12x6d = Eigen::Matrix<double, 12, 6>;

constexpr int kC = PoseFilterState::kC, kV = PoseFilterState::kV, kTheta = PoseFilterState::kTheta,
              kW = PoseFilterState::kW;

Matrix3d rotation_exp(const Vector3d& phi) { return so3_exp(phi).toRotationMatrix(); }

Vector3d rotation_log(const Matrix3d& R) { return so3_log(Eigen::Quaterniond(R)); }

SE3 pose_of(const Matrix3d& R_c_w, const Vector3d& c) { return SE3(R_c_w, -(R_c_w * c)); }

/// The measurement's information on y = [dc; dtheta] from the solver's xi = [rho; phi]: to first
/// order a left step exp(xi) moves the centre by -R^T rho and turns by phi.
Matrix6d information_on_centre(const Matrix6d& H_xi, const Matrix3d& R_c_w) {
  Matrix6d M = Matrix6d::Zero();
  M.block<3, 3>(0, 0) = -R_c_w;
  M.block<3, 3>(3, 3).setIdentity();
  Matrix6d H = M.transpose() * H_xi * M;
  return 0.5 * (H + H.transpose());
}

/// Rows of the measured blocks (centre, rotation) of the 12-state.
Matrix12x6d measured_columns(const Matrix12d& P) {
  Matrix12x6d PC;
  PC.leftCols<3>() = P.middleCols<3>(kC);
  PC.rightCols<3>() = P.middleCols<3>(kTheta);
  return PC;
}

}  // namespace

const char* to_string(FilterOutcome outcome) {
  switch (outcome) {
    case FilterOutcome::kOff:
      return "off";
    case FilterOutcome::kFused:
      return "fused";
    case FilterOutcome::kDownweighted:
      return "downweighted";
    case FilterOutcome::kHeld:
      return "held";
    case FilterOutcome::kRestarted:
      return "restarted";
  }
  return "unknown";
}

SE3 PoseFilterState::T_c_w() const { return pose_of(R, c); }

PoseFilterState PoseFilterState::plus(const Vector12d& d) const {
  PoseFilterState x = *this;
  x.c += d.segment<3>(kC);
  x.v += d.segment<3>(kV);
  x.R = rotation_exp(d.segment<3>(kTheta)) * x.R;
  x.w += d.segment<3>(kW);
  return x;
}

Vector12d PoseFilterState::minus(const PoseFilterState& b) const {
  Vector12d d;
  d.segment<3>(kC) = c - b.c;
  d.segment<3>(kV) = v - b.v;
  d.segment<3>(kTheta) = rotation_log(R * b.R.transpose());
  d.segment<3>(kW) = w - b.w;
  return d;
}

void PoseFilterState::move_world(const SE3& W) {
  const Matrix3d R_W = W.rotation();
  c = W * c;
  v = R_W * v;
  R = R * R_W.transpose();
  Matrix12d J = Matrix12d::Identity();
  J.block<3, 3>(kC, kC) = R_W;
  J.block<3, 3>(kV, kV) = R_W;
  P = J * P * J.transpose();
}

PoseFilter::PoseFilter(const PoseFilterOptions& options)
    : options_(options), noise_(options.noise_window) {}

double PoseFilter::measurement_variance_factor() const {
  const double s2 = options_.measurement_noise_scale * options_.measurement_noise_scale;
  if (!(options_.noise_window > 0.0)) return s2;
  return s2 * std::max(1.0, noise_.variance_factor());
}

Matrix6d PoseFilter::measurement_covariance(const Matrix6d& information,
                                            const Matrix3d& R_c_w) const {
  // A direction the measurement leaves free: 1 m, 1 rad.
  Matrix6d H = information_on_centre(information, R_c_w) / measurement_variance_factor();
  H += Matrix6d::Identity();
  return H.inverse();
}

void PoseFilter::restart(double timestamp, const SE3& T_c_w, const Matrix6d& information,
                         bool keep_velocities) {
  const Matrix12d before = x_.P;
  if (!keep_velocities) {
    x_.v.setZero();
    x_.w.setZero();
    liveliness_ = 1.0;
    mean_nis_ = 6.0;
    has_velocity_ = false;
  }
  started_ = true;
  held_ = 0;
  map_moved_.reset();
  timestamp_ = timestamp;
  x_.R = T_c_w.rotation();
  x_.c = -(x_.R.transpose() * T_c_w.translation());
  // The pose as uncertain as its measurement says; the velocities unknown at a handheld camera's
  // scale (1 m/s, 2 rad/s).
  const Matrix6d cov = measurement_covariance(information, x_.R);
  x_.P.setZero();
  x_.P.block<3, 3>(kC, kC) = cov.block<3, 3>(0, 0);
  x_.P.block<3, 3>(kC, kTheta) = cov.block<3, 3>(0, 3);
  x_.P.block<3, 3>(kTheta, kC) = cov.block<3, 3>(3, 0);
  x_.P.block<3, 3>(kTheta, kTheta) = cov.block<3, 3>(3, 3);
  if (keep_velocities) {
    x_.P.block<3, 3>(kV, kV) = before.block<3, 3>(kV, kV);
    x_.P.block<3, 3>(kW, kW) = before.block<3, 3>(kW, kW);
  } else {
    x_.P.block<3, 3>(kV, kV) = Matrix3d::Identity() * 1.0;
    x_.P.block<3, 3>(kW, kW) = Matrix3d::Identity() * 4.0;
  }
}

void PoseFilter::adapt(double dt, double nis) {
  if (!(options_.adaptive_memory > 0.0) || !std::isfinite(nis)) return;
  // Covariance matching: the innovations' recent mean against the 6 the model expects. A camera
  // livelier than the densities gives larger innovations, and the densities follow (never below
  // the settings', so that a calm camera keeps them); one bad frame counts at most 4 times 6.
  // The multiplier moves by (mean / 6)^(dt / memory): by the ratio over one memory's time, as
  // fast as the mean itself can tell, so that a few frames off the motion, which hold the slow
  // mean above 6 for about that time, lift it by about that ratio once. With the frames' noise
  // measured (noise_window), the handheld sequences' innovations stay below 6 and the multiplier
  // at 1 (freiburg1_rpy's at most 1.8); the render at 2.4 m/s^2 lifts it (90th percentile 7.5).
  const double keep = std::exp(-dt / options_.adaptive_memory);
  mean_nis_ = keep * mean_nis_ + (1.0 - keep) * std::min(nis, 24.0);
  liveliness_ = std::clamp(liveliness_ * std::pow(mean_nis_ / 6.0, dt / options_.adaptive_memory),
                           1.0, options_.max_liveliness);
}

Matrix12d PoseFilter::predict(double dt) {
  const Matrix3d A = rotation_exp(x_.w * dt);
  x_.R = A * x_.R;
  x_.c += x_.v * dt;
  Matrix12d F = Matrix12d::Identity();
  F.block<3, 3>(kC, kV) = Matrix3d::Identity() * dt;
  F.block<3, 3>(kTheta, kTheta) = A;
  F.block<3, 3>(kTheta, kW) = Matrix3d::Identity() * dt;
  Matrix12d Q = Matrix12d::Zero();
  const double dt2 = dt * dt, dt3 = dt2 * dt;
  const auto add = [&](int pos, int vel, double q) {
    Q.block<3, 3>(pos, pos) = Matrix3d::Identity() * (q * dt3 / 3.0);
    Q.block<3, 3>(pos, vel) = Matrix3d::Identity() * (q * dt2 / 2.0);
    Q.block<3, 3>(vel, pos) = Matrix3d::Identity() * (q * dt2 / 2.0);
    Q.block<3, 3>(vel, vel) = Matrix3d::Identity() * (q * dt);
  };
  add(kC, kV, options_.acceleration_density * liveliness_);
  add(kTheta, kW, options_.angular_acceleration_density * liveliness_);
  x_.P = F * x_.P * F.transpose() + Q;
  return F;
}

bool PoseFilter::noise_known() const {
  return !(options_.noise_window > 0.0) || noise_.values() >= PoseNoiseEstimate::kMinValues;
}

PoseFilterUpdate PoseFilter::restarted_at(double timestamp, const SE3& T_c_w, double nis) {
  PoseFilterUpdate out;
  out.T_c_w = T_c_w;
  out.nis = nis;
  out.outcome = FilterOutcome::kRestarted;
  out.step = PoseFilterStep{timestamp, true, x_, Matrix12d::Identity(), x_};
  return out;
}

Vector6d PoseFilter::innovation(const SE3& T_c_w) const {
  const Matrix3d R = T_c_w.rotation();
  Vector6d z;
  z.head<3>() = -(R.transpose() * T_c_w.translation()) - x_.c;
  z.tail<3>() = rotation_log(R * x_.R.transpose());
  return z;
}

bool PoseFilter::holds(const SE3& T_c_w, double nis, const Matrix6d& S_inv, bool& map_jump) {
  // A frame the map's move since the frame before explains (a loop correction) is a jump.
  map_jump = false;
  if (map_moved_) {
    const Vector6d z_before = innovation(T_c_w * *map_moved_);
    map_jump = z_before.dot(S_inv * z_before) <= options_.gate_chi2;
    map_moved_.reset();
  }
  // Until the frames' noise is measured their covariance is the optimiser's, which can
  // understate it many times over (noise_window): the gate then tells nothing.
  if (!std::isfinite(nis) || map_jump || !noise_known() || held_ >= options_.held_frames)
    return false;
  ++held_;
  return true;
}

PoseFilterUpdate PoseFilter::update(double timestamp, const SE3& T_c_w,
                                    const Matrix6d& information) {
  if (!options_.enabled) {
    PoseFilterUpdate out;
    out.T_c_w = T_c_w;
    return out;
  }
  const double dt = timestamp - timestamp_;
  const std::optional<Measurement> previous = last_measurement_;
  last_measurement_ = Measurement{timestamp, T_c_w, information};
  // Whether this measurement continues the last one (no start, no gap, time moves on).
  const bool continues = started_ && dt > 0.0 && dt <= options_.max_gap;
  const Matrix3d R_m = T_c_w.rotation();
  const Vector3d c_m = -(R_m.transpose() * T_c_w.translation());
  const bool noise_was_known = noise_known();
  if (options_.noise_window > 0.0) {
    if (!continues) noise_.break_sequence();
    noise_.add(timestamp, R_m, c_m, information_on_centre(information, R_m));
  }
  if (!continues || !information.allFinite()) {
    restart(timestamp, T_c_w, information.allFinite() ? information : Matrix6d::Zero(), false);
    return restarted_at(timestamp, T_c_w, 0.0);
  }
  // Until the frames' noise is measured the state's covariance holds their covariance as the
  // optimiser gives it, which can understate it many times over (freiburg1_rpy: 85): the
  // velocities the first frames gave count for that much more than they are worth, and taken
  // at their word once the measurements count for what they are, they carry the pose away from
  // the frames for several frames. When the noise is first known, the covariance is scaled by
  // the factor found, as if the first frames had counted at their measured noise.
  if (!noise_was_known && noise_known()) x_.P *= std::max(1.0, noise_.variance_factor());
  PoseFilterStep step;
  step.timestamp = timestamp;
  step.F = predict(dt);
  step.predicted = x_;

  const Vector6d z = innovation(T_c_w);
  Matrix6d H = information_on_centre(information, x_.R) / measurement_variance_factor();
  // S^-1 = (C P C^T + H^-1)^-1 = H (I + C P C^T H)^-1: no inverse of H, which may be singular.
  const Matrix12x6d PC = measured_columns(x_.P);
  Matrix6d CPC;
  CPC.topRows<3>() = PC.middleRows<3>(kC);
  CPC.bottomRows<3>() = PC.middleRows<3>(kTheta);
  Matrix6d S_inv = H * (Matrix6d::Identity() + CPC * H).partialPivLu().inverse();
  const double nis = z.dot(S_inv * z);
  adapt(dt, nis);
  if (!std::isfinite(nis) || nis > options_.gate_chi2) {
    bool map_jump = false;
    if (holds(T_c_w, nis, S_inv, map_jump)) {
      // The prediction stands for this frame.
      timestamp_ = timestamp;
      step.filtered = x_;
      PoseFilterUpdate out;
      out.T_c_w = x_.T_c_w();
      out.nis = nis;
      out.outcome = FilterOutcome::kHeld;
      out.step = std::move(step);
      return out;
    }
    // A jump the map's move explains keeps the velocities (the camera did not stop);
    // velocities_between says when they failed.
    const bool velocities_failed = !map_jump && (held_ > 0 || !noise_known());
    restart(timestamp, T_c_w, information, true);
    if (velocities_failed && previous) velocities_between(*previous, T_c_w, information, timestamp);
    return restarted_at(timestamp, T_c_w, std::isfinite(nis) ? nis : 0.0);
  }
  held_ = 0;
  map_moved_.reset();
  if (nis > options_.downweight_chi2) {
    // Huber: the measurement counts as a frame at the threshold would.
    H *= std::sqrt(options_.downweight_chi2 / nis);
    S_inv = H * (Matrix6d::Identity() + CPC * H).partialPivLu().inverse();
  }
  const Matrix12x6d K = PC * S_inv;
  x_ = x_.plus(K * z);
  has_velocity_ = true;
  Matrix12d IKC = Matrix12d::Identity();
  IKC.middleCols<3>(kC) -= K.leftCols<3>();
  IKC.middleCols<3>(kTheta) -= K.rightCols<3>();
  x_.P = IKC * x_.P;
  x_.P = 0.5 * (x_.P + x_.P.transpose()).eval();
  timestamp_ = timestamp;
  step.filtered = x_;
  PoseFilterUpdate out;
  out.T_c_w = x_.T_c_w();
  out.nis = nis;
  out.outcome =
      nis > options_.downweight_chi2 ? FilterOutcome::kDownweighted : FilterOutcome::kFused;
  out.step = std::move(step);
  return out;
}

void PoseFilter::velocities_between(const Measurement& before, const SE3& T_c_w,
                                    const Matrix6d& information, double timestamp) {
  // A frame beyond the gate after a held one (each the other's confirmation: the camera jumped
  // or moved otherwise than the velocities said, beyond the model), or beyond it while its noise
  // is not yet known (the velocities then come from frames that counted for more than they were
  // worth): the velocities kept from before are what failed. Kept, they predict the next frame
  // off again, which is held, and the pose alternates between prediction and measurement. The
  // frame before and this one tell the velocities since: y = [c; theta], u = (y_m - y_b) / dt,
  // Cov(u) = (C_b + C_m) / dt^2, Cov(y_m, u) = C_m / dt.
  const double dt = timestamp - before.timestamp;
  if (!(dt > 0.0)) return;
  const Matrix3d R_b = before.T_c_w.rotation(), R_m = T_c_w.rotation();
  const Vector3d c_b = -(R_b.transpose() * before.T_c_w.translation());
  const Vector3d c_m = -(R_m.transpose() * T_c_w.translation());
  const Matrix6d C_b = measurement_covariance(
      before.information.allFinite() ? before.information : Matrix6d::Zero(), R_b);
  const Matrix6d C_m = measurement_covariance(information, R_m);
  x_.v = (c_m - c_b) / dt;
  x_.w = rotation_log(R_m * R_b.transpose()) / dt;
  const Matrix6d C_u = (C_b + C_m) / (dt * dt);
  const Matrix6d C_yu = C_m / dt;
  const int y[2] = {kC, kTheta}, u[2] = {kV, kW};
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j) {
      x_.P.block<3, 3>(u[i], u[j]) = C_u.block<3, 3>(3 * i, 3 * j);
      x_.P.block<3, 3>(y[i], u[j]) = C_yu.block<3, 3>(3 * i, 3 * j);
      x_.P.block<3, 3>(u[j], y[i]) = C_yu.block<3, 3>(3 * i, 3 * j).transpose();
    }
  has_velocity_ = true;
}

void PoseFilter::move_world(const SE3& W) {
  if (last_measurement_) last_measurement_->T_c_w = last_measurement_->T_c_w * W.inverse();
  noise_.move_world(W);
  if (started_ && options_.follow_map) x_.move_world(W);
  if (started_ && !options_.follow_map) map_moved_ = map_moved_ ? W * *map_moved_ : W;
}

}  // namespace mcslam::optim
