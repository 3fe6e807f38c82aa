#pragma once
// Bonn RGB-D Dynamic dataset ground truth. Its groundtruth.txt gives the pose of the
// motion-capture marker body, not of the camera. The camera pose is
//   T_cam = T_ros * T_gt * T_ros * T_m
// with
//   T_ros = [-1 0 0 0; 0 0 1 0; 0 1 0 0; 0 0 0 1]
//   T_m   = [1.0157 0.1828 -0.2389 0.0113; 0.0009 -0.8431 -0.6413 -0.0098;
//            -0.3009 0.6147 -0.8085 0.0111; 0 0 0 1].
// T_ros is a proper rotation (det +1, 180 deg about (0, 1, 1)) and its own inverse.
// T_m's 3x3 block is a rotation scaled by ~1.0593 (all its row norms are 1.0593). We project it
// onto the nearest rotation (SVD, det +1) and keep its translation, so every converted pose is a
// rigid transform.

#include <Eigen/Core>

#include "mcslam/core/se3.hpp"
#include "mcslam/core/trajectory.hpp"

namespace mcslam::eval {

/// The nearest rotation to M in the Frobenius norm: U diag(1, 1, det(U V^T)) V^T from M = U S V^T.
Eigen::Matrix3d nearest_rotation(const Eigen::Matrix3d& M);

/// T_ros above.
Eigen::Matrix4d bonn_T_ros();
/// T_m exactly as published (scaled rotation block).
Eigen::Matrix4d bonn_T_m_raw();
/// T_m with its 3x3 block replaced by nearest_rotation() of it; translation unchanged.
Eigen::Matrix4d bonn_T_m();

/// Camera pose from one marker pose: T_ros * T_gt * T_ros * bonn_T_m(), computed with 4x4 matrices.
SE3 bonn_marker_to_camera(const SE3& T_gt);
/// Per-pose conversion of a whole ground-truth trajectory; timestamps are kept.
Trajectory bonn_marker_to_camera(const Trajectory& marker_gt);

}  // namespace mcslam::eval
