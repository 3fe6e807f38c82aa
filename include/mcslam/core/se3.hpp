#pragma once
// Rigid transforms. Naming: T_a_b maps points from frame b to frame a (p_a = T_a_b * p_b).
// Tangent vectors are ordered xi = [rho (translation); phi (rotation)], and perturbations are
// applied on the left: T' = exp(xi) * T.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace mcslam {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

/// [v]x, the cross-product matrix: skew(v) * w == v.cross(w).
inline Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

/// SO(3) exponential map of a rotation vector.
Eigen::Quaterniond so3_exp(const Eigen::Vector3d& phi);
/// SO(3) logarithm: the rotation vector (angle in [0, pi]) of a unit quaternion.
Eigen::Vector3d so3_log(const Eigen::Quaterniond& q);
/// Left Jacobian of SO(3) and its inverse.
Eigen::Matrix3d so3_left_jacobian(const Eigen::Vector3d& phi);
Eigen::Matrix3d so3_left_jacobian_inverse(const Eigen::Vector3d& phi);

class SE3 {
 public:
  SE3() : q_(Eigen::Quaterniond::Identity()), t_(Eigen::Vector3d::Zero()) {}
  /// The quaternion is normalised here.
  SE3(const Eigen::Quaterniond& q, const Eigen::Vector3d& t) : q_(q.normalized()), t_(t) {}
  SE3(const Eigen::Matrix3d& R, const Eigen::Vector3d& t)
      : q_(Eigen::Quaterniond(R).normalized()), t_(t) {}

  static SE3 identity() { return SE3(); }
  /// A pose from a quaternion that is already unit to rounding (one read back from a file that
  /// an SE3 was written to): kept bit for bit, not renormalised, so that a saved pose reads back
  /// exactly. Renormalising a unit quaternion can change its last bits.
  static SE3 from_unit_quaternion(const Eigen::Quaterniond& q, const Eigen::Vector3d& t) {
    SE3 T;
    T.q_ = q;
    T.t_ = t;
    return T;
  }
  /// exp([rho; phi]) with the SE(3) left Jacobian coupling rho into the translation.
  static SE3 exp(const Vector6d& xi);
  /// From a 4x4 homogeneous matrix whose 3x3 block is a rotation (not re-orthonormalised).
  static SE3 from_matrix(const Eigen::Matrix4d& T);

  Vector6d log() const;
  SE3 inverse() const {
    const Eigen::Quaterniond qi = q_.conjugate();
    return SE3(qi, -(qi * t_));
  }

  SE3 operator*(const SE3& other) const { return SE3(q_ * other.q_, q_ * other.t_ + t_); }
  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return q_ * p + t_; }

  const Eigen::Quaterniond& quaternion() const { return q_; }
  Eigen::Matrix3d rotation() const { return q_.toRotationMatrix(); }
  const Eigen::Vector3d& translation() const { return t_; }
  Eigen::Matrix4d matrix() const;
  /// 6x6 adjoint for the [rho; phi] ordering: exp(Ad * xi) = T * exp(xi) * T^-1.
  Matrix6d adjoint() const;

  void set_translation(const Eigen::Vector3d& t) { t_ = t; }
  void set_quaternion(const Eigen::Quaterniond& q) { q_ = q.normalized(); }

 private:
  Eigen::Quaterniond q_;
  Eigen::Vector3d t_;
};

/// Rotation angle (rad) of a relative rotation, in [0, pi].
double rotation_angle(const Eigen::Quaterniond& q);

}  // namespace mcslam
