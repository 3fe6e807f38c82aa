#pragma once
// The camera's angular velocity in one frame, from the frame's own rolling-shutter distortion.
//
// A rolling-shutter camera exposes its rows one after the other over the readout time: row v is
// seen tau(v) = (v - H / 2) / H * readout after the middle row. The frame's keypoints are moved
// to the middle row's time before tracking (FrameBuilder), with the angular velocity the last
// frames predict (omega0). A handheld camera's angular velocity changes faster than that
// prediction follows (on freiburg1_rpy it errs by 0.5 rad/s RMS against the ground truth): the
// rows of the image are then turned against each other by the error times tau, the pose solved
// from them takes a share of it, and the share changes from frame to frame.
//
// The error shows in the frame itself: with the pose solved, an error d of the angular velocity
// moves each keypoint by d_uv/d_d = dpi/dX [X]x tau (X: the keypoint's bearing at the middle
// row's time), an image-wide shear whose size grows with the row's distance from the middle,
// which no pose reproduces. Hundreds of keypoints over the image's rows fix d to a few
// hundredths of a rad/s. The correction is estimated by linear least squares over the pose's
// inlier points with a prior on d (the prediction's error), then the keypoints are moved by it
// and the pose solved again.

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/optim/pose_optimizer.hpp"

namespace mcslam::optim {

/// A row's exposure time relative to the middle row's (s).
double row_time(const PinholeCamera& camera, double v, double readout_time);

/// Where a keypoint at `uv` (already moved to the middle row's time with an angular velocity
/// omega0; seen at row time `tau`) would be with omega0 + d instead:
/// pi(exp(-d tau) unproject(uv)). With `jacobian`, d uv / d d at d (2x3).
Eigen::Vector2d shutter_corrected_uv(const PinholeCamera& camera, const Eigen::Vector2d& uv,
                                     double tau, const Eigen::Vector3d& d,
                                     Eigen::Matrix<double, 2, 3>* jacobian = nullptr);

struct AngularVelocityCorrection {
  Eigen::Vector3d d = Eigen::Vector3d::Zero();  ///< rad/s, camera frame
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  int points = 0;  ///< inlier points used
  /// d^T S d / s0^2: the correction's chi-square against zero (3 dof), S its information after
  /// the pose's elimination and s0^2 the residuals' a posteriori variance factor (their mean
  /// squared whitened residual per degree of freedom: the keypoints' real noise against the
  /// 1 px at their level the weights assume).
  double chi2 = 0.0;
};

/// The correction d of the angular velocity that best explains the residuals of the pose T_c_w
/// at the inlier points of `problem` (u, v only), with a prior d ~ N(0, prior_sigma^2 I).
AngularVelocityCorrection estimate_angular_velocity_correction(
    const PinholeCamera& camera, const PoseProblem& problem, const std::vector<bool>& inlier,
    const SE3& T_c_w, double readout_time, double prior_sigma);

/// Moves every point measurement of `problem` by the correction d (u, v and the virtual right
/// coordinate together).
void apply_angular_velocity_correction(const PinholeCamera& camera, double readout_time,
                                       const Eigen::Vector3d& d, PoseProblem& problem);

}  // namespace mcslam::optim
