#pragma once
// Residual (6) of the paper for RGB-D keypoints: the reprojection error of a world point in the
// image, extended by a third row for the keypoint's depth (DepthTerm): the virtual right-camera
// coordinate u_r = u - bf / z (ORB-SLAM2's form) or the disparity bf / z alone. Residuals are
// whitened by 1 / sigma of the keypoint's pyramid level. Analytic Jacobians with respect to the
// pose block (7, see se3_manifold.hpp) and the point.

#include <ceres/sized_cost_function.h>

#include "mcslam/core/camera.hpp"

namespace mcslam::optim {

/// Depth (m) at or below which a point is behind the camera: its residual cannot be evaluated
/// (Evaluate returns false, which rejects a trial step but fails a solve at its start point, so
/// the optimisers leave such observations out) and its chi-square is infinite.
inline constexpr double kMinPointDepth = 1e-6;

/// How a keypoint's depth enters the third row of its residual.
enum class DepthTerm {
  /// The virtual right-camera coordinate u_r = u - bf / z, as a stereo camera's second image
  /// would give it (ORB-SLAM2's RGB-D form). For an RGB-D camera u_r is computed from u, so its
  /// error is u's error plus the depth's: a solve that moves a point along its ray can shift u
  /// and u_r together, and the depth holds the point no better than u does, whatever its weight.
  kRightU,
  /// The disparity bf / z alone (pixels): what the depth camera measured, independent of where
  /// the colour keypoint lies. Bundle adjustment uses it (docs/design.md, "Depth in bundle
  /// adjustment").
  kDisparity,
};

/// What one keypoint says about a world point.
struct PointMeasurement {
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();
  /// Virtual right-camera u, u - bf / z of the measured depth z; used only when with_depth.
  double u_right = 0.0;
  bool with_depth = false;  // false: a 2D (u, v) residual
  DepthTerm depth_term = DepthTerm::kRightU;
  double information = 1.0;  // 1 / sigma^2 of the keypoint's level, for u and v
  /// 1 / sigma^2 of the depth row (u_right or the disparity, pixels). Callers scale the level's
  /// information by a depth weight: the depth at a keypoint carries the sensor's noise, its
  /// registration to the colour image and the time between the two images.
  double right_information = 1.0;
  bool has_depth() const { return with_depth; }
  /// The measured disparity bf / z (pixels).
  double disparity() const { return uv.x() - u_right; }
};

/// p_c = R(q) p_w + t, written for unit quaternions so that its ambient derivative is exact.
Eigen::Vector3d transform_point(const double* pose, const Eigen::Vector3d& p_w);
/// d p_c / d pose (3x7) and d p_c / d p_w (3x3).
void transform_point_jacobians(const double* pose, const Eigen::Vector3d& p_w,
                               Eigen::Matrix<double, 3, 7>* d_pose, Eigen::Matrix3d* d_point);

/// Residual of kDim = 3 (u, v, u_r) or 2 (u, v) for a pose and a point.
template <int kDim>
class ReprojectionError final : public ceres::SizedCostFunction<kDim, 7, 3> {
 public:
  ReprojectionError(const PinholeCamera& camera, const PointMeasurement& m);
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  double fx_, fy_, cx_, cy_, bf_;
  bool disparity_;
  /// u, v and, with depth, u_right or the disparity (depth_term).
  Eigen::Matrix<double, kDim, 1> observed_;
  double sqrt_information_;
  double sqrt_right_information_;
};

/// The same residual with the point held fixed (pose-only optimisation).
template <int kDim>
class PoseOnlyReprojectionError final : public ceres::SizedCostFunction<kDim, 7> {
 public:
  PoseOnlyReprojectionError(const PinholeCamera& camera, const PointMeasurement& m,
                            const Eigen::Vector3d& p_w);
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  ReprojectionError<kDim> full_;
  Eigen::Vector3d p_w_;
};

/// The depth row's unwhitened error (prediction minus measurement, pixels) for a camera point in
/// front of the camera: u_r or the disparity, as m.depth_term says.
double depth_row_error(const PinholeCamera& camera, const PointMeasurement& m,
                       const Eigen::Vector3d& p_c);

/// The unwhitened squared error of a measurement for a camera point (for chi-square tests).
double reprojection_chi2(const PinholeCamera& camera, const PointMeasurement& m,
                         const Eigen::Vector3d& p_c);

extern template class ReprojectionError<2>;
extern template class ReprojectionError<3>;
extern template class PoseOnlyReprojectionError<2>;
extern template class PoseOnlyReprojectionError<3>;

}  // namespace mcslam::optim
