#include "mcslam/optim/rolling_shutter.hpp"

#include <Eigen/Cholesky>
#include <algorithm>

namespace mcslam::optim {

double row_time(const PinholeCamera& camera, double v, double readout_time) {
  return (v - 0.5 * camera.height) / camera.height * readout_time;
}

Eigen::Vector2d shutter_corrected_uv(const PinholeCamera& camera, const Eigen::Vector2d& uv,
                                     double tau, const Eigen::Vector3d& d,
                                     Eigen::Matrix<double, 2, 3>* jacobian) {
  const Eigen::Vector3d bearing = camera.unproject(uv, 1.0);
  const Eigen::Vector3d moved = so3_exp(-tau * d).toRotationMatrix() * bearing;
  if (jacobian) {
    // exp(-tau (d + e)) b ~ exp(-tau e) exp(-tau d) b = moved + tau moved x e to first order in
    // e (exact at d = 0; at a frame's angles, |tau d| < 1e-2 rad, to 1 % otherwise).
    *jacobian = camera.project_jacobian(moved) * (tau * skew(moved));
  }
  return camera.project(moved);
}

AngularVelocityCorrection estimate_angular_velocity_correction(
    const PinholeCamera& camera, const PoseProblem& problem, const std::vector<bool>& inlier,
    const SE3& T_c_w, double readout_time, double prior_sigma) {
  // Jointly with the pose's own correction (tangent xi, T' = exp(xi) T): a turn of the angular
  // velocity shears the image much as part of a turn of the pose moves it, so the two are
  // estimated together and the pose is eliminated (Schur complement). Rows: u, v and, with
  // depth, the virtual right coordinate u_r = u - bf / z, which moves with u under d, or the
  // disparity bf / z, which d leaves as it is (DepthTerm).
  using Matrix9d = Eigen::Matrix<double, 9, 9>;
  using Vector9d = Eigen::Matrix<double, 9, 1>;
  AngularVelocityCorrection out;
  Matrix9d H = Matrix9d::Zero();
  Vector9d g = Vector9d::Zero();
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  double squares = 0.0;
  int rows = 0;
  for (std::size_t i = 0; i < problem.points.size(); ++i) {
    if (i >= inlier.size() || !inlier[i]) continue;
    const PoseObservation& obs = problem.points[i];
    const PointMeasurement& m = obs.measurement;
    const Eigen::Vector3d p_c = T_c_w * obs.p_w;
    if (!(p_c.z() > kMinPointDepth)) continue;
    const double tau = row_time(camera, m.uv.y(), readout_time);
    Eigen::Matrix<double, 2, 3> J_d;
    const Eigen::Vector2d uv = shutter_corrected_uv(camera, m.uv, tau, zero, &J_d);
    Eigen::Matrix<double, 3, 6> dp;  // d p_c / d xi
    dp << Eigen::Matrix3d::Identity(), -skew(p_c);
    const Eigen::Matrix<double, 2, 3> J_pi = camera.project_jacobian(p_c);
    // e = prediction - measurement(d): its Jacobians on [xi, d].
    Eigen::Matrix<double, 3, 9> J = Eigen::Matrix<double, 3, 9>::Zero();
    Eigen::Vector3d e = Eigen::Vector3d::Zero();
    Eigen::Vector3d w(m.information, m.information, 0.0);
    J.block<2, 6>(0, 0) = J_pi * dp;
    J.block<2, 3>(0, 6) = -J_d;
    e.head<2>() = camera.project(p_c) - uv;
    if (m.with_depth) {
      const double bf_z2 = camera.bf / (p_c.z() * p_c.z());
      if (m.depth_term == DepthTerm::kDisparity) {
        J.block<1, 6>(2, 0) = Eigen::RowVector3d(0.0, 0.0, -bf_z2) * dp;
      } else {
        Eigen::RowVector3d d_ur = J_pi.row(0);
        d_ur.z() += bf_z2;
        J.block<1, 6>(2, 0) = d_ur * dp;
        J.block<1, 3>(2, 6) = -J_d.row(0);
      }
      e.z() = depth_row_error(camera, m, p_c);
      w.z() = m.right_information;
    }
    H.noalias() += J.transpose() * w.asDiagonal() * J;
    g.noalias() += J.transpose() * w.asDiagonal() * e;
    squares += e.dot(w.asDiagonal() * e);
    rows += m.with_depth ? 3 : 2;
    ++out.points;
  }
  H.block<3, 3>(6, 6) += Eigen::Matrix3d::Identity() / (prior_sigma * prior_sigma);
  // Minimise |e + J x|^2: H x = -g; the pose eliminated.
  const Eigen::Matrix<double, 6, 6> H_pp = H.topLeftCorner<6, 6>();
  const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> pose(H_pp);
  const Eigen::Matrix<double, 6, 3> H_pd = H.block<6, 3>(0, 6);
  const Eigen::Matrix3d S = H.block<3, 3>(6, 6) - H_pd.transpose() * pose.solve(H_pd);
  const Eigen::Vector3d b = g.tail<3>() - H_pd.transpose() * pose.solve(g.head<6>());
  out.information = S;
  out.d = -S.ldlt().solve(b);
  if (!out.d.allFinite()) {
    out.d.setZero();
    return out;
  }
  // The residuals after the joint fit (the shear taken out): min |e + J x|^2 = e^T e - g^T x*,
  // x* = H^-1 g over pose and correction.
  const double fitted = std::max(squares - g.dot(H.ldlt().solve(g)), 0.0);
  const double variance_factor = rows > 9 ? fitted / (rows - 9) : 1.0;
  out.chi2 = out.d.dot(S * out.d) / std::max(variance_factor, 1e-12);
  return out;
}

void apply_angular_velocity_correction(const PinholeCamera& camera, double readout_time,
                                       const Eigen::Vector3d& d, PoseProblem& problem) {
  for (PoseObservation& obs : problem.points) {
    PointMeasurement& m = obs.measurement;
    const double tau = row_time(camera, m.uv.y(), readout_time);
    const Eigen::Vector2d uv = shutter_corrected_uv(camera, m.uv, tau, d);
    // The depth is unchanged to first order (a turn of at most milliradians): u_r moves with u
    // and the disparity u - u_r stays.
    if (m.with_depth) m.u_right += uv.x() - m.uv.x();
    m.uv = uv;
  }
}

}  // namespace mcslam::optim
