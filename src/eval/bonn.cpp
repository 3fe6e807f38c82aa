#include "mcslam/eval/bonn.hpp"

#include <Eigen/SVD>

namespace mcslam::eval {

Eigen::Matrix3d nearest_rotation(const Eigen::Matrix3d& M) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d& U = svd.matrixU();
  const Eigen::Matrix3d& V = svd.matrixV();
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  if ((U * V.transpose()).determinant() < 0.0) S(2, 2) = -1.0;
  return U * S * V.transpose();
}

Eigen::Matrix4d bonn_T_ros() {
  Eigen::Matrix4d T;
  T << -1, 0, 0, 0,  //
      0, 0, 1, 0,    //
      0, 1, 0, 0,    //
      0, 0, 0, 1;
  return T;
}

Eigen::Matrix4d bonn_T_m_raw() {
  Eigen::Matrix4d T;
  T << 1.0157, 0.1828, -0.2389, 0.0113,   //
      0.0009, -0.8431, -0.6413, -0.0098,  //
      -0.3009, 0.6147, -0.8085, 0.0111,   //
      0, 0, 0, 1;
  return T;
}

Eigen::Matrix4d bonn_T_m() {
  Eigen::Matrix4d T = bonn_T_m_raw();
  T.block<3, 3>(0, 0) = nearest_rotation(Eigen::Matrix3d(T.block<3, 3>(0, 0)));
  return T;
}

SE3 bonn_marker_to_camera(const SE3& T_gt) {
  // Computed once: both factors are constant.
  static const Eigen::Matrix4d kRos = bonn_T_ros();
  static const Eigen::Matrix4d kRosM = bonn_T_ros() * bonn_T_m();
  const Eigen::Matrix4d T = kRos * T_gt.matrix() * kRosM;
  return SE3::from_matrix(T);
}

Trajectory bonn_marker_to_camera(const Trajectory& marker_gt) {
  Trajectory out;
  out.reserve(marker_gt.size());
  for (const StampedPose& p : marker_gt)
    out.push_back({p.timestamp, bonn_marker_to_camera(p.T_w_c)});
  return out;
}

}  // namespace mcslam::eval
