#pragma once
// Pinhole RGB-D camera. Images given to the SLAM pipeline are already undistorted, so
// projection here is the plain pinhole model; `distortion` describes the raw images.

#include <Eigen/Core>
#include <array>
#include <optional>
#include <string>

namespace mcslam {

struct PinholeCamera {
  double fx = 0.0;
  double fy = 0.0;
  double cx = 0.0;
  double cy = 0.0;
  int width = 0;
  int height = 0;
  /// Radial-tangential distortion of the raw images: k1, k2, p1, p2, k3.
  std::array<double, 5> distortion{0.0, 0.0, 0.0, 0.0, 0.0};
  /// Raw depth value per metre (TUM and Bonn: 5000).
  double depth_factor = 5000.0;
  /// Virtual stereo baseline times fx (ORB-SLAM2's Camera.bf), in pixel*metres. It turns a
  /// depth z into a virtual right-image coordinate u_r = u - bf / z.
  double bf = 40.0;
  /// Rolling shutter: time (s) between the exposure of the first and the last image row; 0 for a
  /// global shutter, negative when the rows are read bottom to top. Keypoints are corrected with
  /// the tracked angular velocity when it is not 0.
  double readout_time = 0.0;
  /// The readout time is unknown (setting `camera.readout_time: auto`): SLAM estimates it from
  /// the images while running (slam::ReadoutEstimator) and readout_time is ignored.
  bool readout_auto = false;

  /// An empty optional when the parameters are usable; otherwise what is wrong.
  std::optional<std::string> check() const;
  bool has_distortion() const;

  /// Pinhole projection of a point in the camera frame (z must be > 0).
  Eigen::Vector2d project(const Eigen::Vector3d& p_c) const {
    const double inv_z = 1.0 / p_c.z();
    return {fx * p_c.x() * inv_z + cx, fy * p_c.y() * inv_z + cy};
  }
  /// Jacobian of project() with respect to p_c (2x3).
  Eigen::Matrix<double, 2, 3> project_jacobian(const Eigen::Vector3d& p_c) const;
  /// Virtual right-camera u coordinate of a point at depth z seen at column u.
  double right_u(double u, double z) const { return u - bf / z; }
  /// Back-projection of pixel (u, v) at depth z (metres) into the camera frame.
  Eigen::Vector3d unproject(const Eigen::Vector2d& uv, double z) const {
    return {(uv.x() - cx) * z / fx, (uv.y() - cy) * z / fy, z};
  }
  bool in_image(const Eigen::Vector2d& uv, double border = 0.0) const {
    return uv.x() >= border && uv.y() >= border && uv.x() < width - border &&
           uv.y() < height - border;
  }
};

}  // namespace mcslam
