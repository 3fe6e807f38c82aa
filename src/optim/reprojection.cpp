#include "mcslam/optim/reprojection.hpp"

#include "mcslam/core/se3.hpp"

namespace mcslam::optim {

Eigen::Vector3d transform_point(const double* pose, const Eigen::Vector3d& p) {
  const Eigen::Vector3d v(pose[0], pose[1], pose[2]);
  const double w = pose[3];
  const Eigen::Vector3d vxp = v.cross(p);
  return p + 2.0 * w * vxp + 2.0 * v.cross(vxp) + Eigen::Vector3d(pose[4], pose[5], pose[6]);
}

void transform_point_jacobians(const double* pose, const Eigen::Vector3d& p,
                               Eigen::Matrix<double, 3, 7>* d_pose, Eigen::Matrix3d* d_point) {
  const Eigen::Vector3d v(pose[0], pose[1], pose[2]);
  const double w = pose[3];
  if (d_pose != nullptr) {
    // R p = p + 2w (v x p) + 2 v x (v x p), and v x (v x p) = v (v.p) - p (v.v).
    d_pose->block<3, 3>(0, 0) =
        -2.0 * w * skew(p) + 2.0 * (v.dot(p) * Eigen::Matrix3d::Identity() + v * p.transpose() -
                                    2.0 * p * v.transpose());
    d_pose->col(3) = 2.0 * v.cross(p);
    d_pose->block<3, 3>(0, 4).setIdentity();
  }
  if (d_point != nullptr) {
    // d/dp: I + 2w [v]x + 2 [v]x [v]x.
    const Eigen::Matrix3d V = skew(v);
    *d_point = Eigen::Matrix3d::Identity() + 2.0 * w * V + 2.0 * V * V;
  }
}

template <int kDim>
ReprojectionError<kDim>::ReprojectionError(const PinholeCamera& camera, const PointMeasurement& m)
    : fx_(camera.fx),
      fy_(camera.fy),
      cx_(camera.cx),
      cy_(camera.cy),
      bf_(camera.bf),
      disparity_(m.depth_term == DepthTerm::kDisparity),
      sqrt_information_(std::sqrt(m.information)),
      sqrt_right_information_(std::sqrt(m.right_information)) {
  observed_[0] = m.uv.x();
  observed_[1] = m.uv.y();
  if constexpr (kDim == 3) observed_[2] = disparity_ ? m.disparity() : m.u_right;
}

template <int kDim>
bool ReprojectionError<kDim>::Evaluate(double const* const* parameters, double* residuals,
                                       double** jacobians) const {
  const double* pose = parameters[0];
  const Eigen::Vector3d p_w(parameters[1][0], parameters[1][1], parameters[1][2]);
  const Eigen::Vector3d p_c = transform_point(pose, p_w);
  const double z = p_c.z();
  if (z <= kMinPointDepth) return false;  // behind the camera: Ceres rejects the step
  const double inv_z = 1.0 / z;
  const double u = fx_ * p_c.x() * inv_z + cx_;
  const double v = fy_ * p_c.y() * inv_z + cy_;
  Eigen::Map<Eigen::Matrix<double, kDim, 1>> r(residuals);
  r[0] = sqrt_information_ * (u - observed_[0]);
  r[1] = sqrt_information_ * (v - observed_[1]);
  if constexpr (kDim == 3)
    r[2] = sqrt_right_information_ * ((disparity_ ? bf_ * inv_z : u - bf_ * inv_z) - observed_[2]);
  if (jacobians == nullptr || (jacobians[0] == nullptr && jacobians[1] == nullptr)) return true;

  Eigen::Matrix<double, kDim, 3> d_pc;
  d_pc.row(0) << fx_ * inv_z, 0.0, -fx_ * p_c.x() * inv_z * inv_z;
  d_pc.row(1) << 0.0, fy_ * inv_z, -fy_ * p_c.y() * inv_z * inv_z;
  if constexpr (kDim == 3) {
    // d(bf / z) = -bf / z^2 dz; u_r = u - bf / z adds u's row.
    if (disparity_) {
      d_pc.row(2) << 0.0, 0.0, -bf_ * inv_z * inv_z;
    } else {
      d_pc.row(2) = d_pc.row(0);
      d_pc(2, 2) += bf_ * inv_z * inv_z;
    }
    d_pc.row(2) *= sqrt_right_information_;
  }
  d_pc.template topRows<2>() *= sqrt_information_;
  Eigen::Matrix<double, 3, 7> d_pose;
  Eigen::Matrix3d d_point;
  transform_point_jacobians(pose, p_w, jacobians[0] ? &d_pose : nullptr,
                            jacobians[1] ? &d_point : nullptr);
  if (jacobians[0] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, kDim, 7, Eigen::RowMajor>> J(jacobians[0]);
    J = d_pc * d_pose;
  }
  if (jacobians[1] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, kDim, 3, Eigen::RowMajor>> J(jacobians[1]);
    J = d_pc * d_point;
  }
  return true;
}

template <int kDim>
PoseOnlyReprojectionError<kDim>::PoseOnlyReprojectionError(const PinholeCamera& camera,
                                                           const PointMeasurement& m,
                                                           const Eigen::Vector3d& p_w)
    : full_(camera, m), p_w_(p_w) {}

template <int kDim>
bool PoseOnlyReprojectionError<kDim>::Evaluate(double const* const* parameters, double* residuals,
                                               double** jacobians) const {
  const double* params[2] = {parameters[0], p_w_.data()};
  double* jac[2] = {jacobians ? jacobians[0] : nullptr, nullptr};
  return full_.Evaluate(params, residuals, jacobians ? jac : nullptr);
}

double depth_row_error(const PinholeCamera& camera, const PointMeasurement& m,
                       const Eigen::Vector3d& p_c) {
  if (m.depth_term == DepthTerm::kDisparity) return camera.bf / p_c.z() - m.disparity();
  return camera.right_u(camera.project(p_c).x(), p_c.z()) - m.u_right;
}

double reprojection_chi2(const PinholeCamera& camera, const PointMeasurement& m,
                         const Eigen::Vector3d& p_c) {
  if (p_c.z() <= kMinPointDepth) return std::numeric_limits<double>::infinity();
  const Eigen::Vector2d uv = camera.project(p_c);
  double chi2 = (uv - m.uv).squaredNorm() * m.information;
  if (m.has_depth()) {
    const double e = depth_row_error(camera, m, p_c);
    chi2 += e * e * m.right_information;
  }
  return chi2;
}

template class ReprojectionError<2>;
template class ReprojectionError<3>;
template class PoseOnlyReprojectionError<2>;
template class PoseOnlyReprojectionError<3>;

}  // namespace mcslam::optim
