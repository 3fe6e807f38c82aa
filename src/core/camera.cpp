#include "mcslam/core/camera.hpp"

#include <cmath>

namespace mcslam {

std::optional<std::string> PinholeCamera::check() const {
  auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(fx) || !positive(fy)) return "focal lengths fx, fy must be positive";
  if (!std::isfinite(cx) || !std::isfinite(cy)) return "principal point cx, cy must be finite";
  if (width <= 0 || height <= 0) return "image width and height must be positive";
  if (cx < 0 || cy < 0 || cx > width || cy > height)
    return "principal point lies outside the image";
  if (!positive(depth_factor)) return "depth factor must be positive";
  if (!positive(bf)) return "virtual baseline bf must be positive";
  if (!std::isfinite(readout_time) || std::abs(readout_time) > 0.1)
    return "rolling-shutter readout_time must be in [-0.1, 0.1] s";
  for (double d : distortion)
    if (!std::isfinite(d)) return "distortion coefficients must be finite";
  return std::nullopt;
}

bool PinholeCamera::has_distortion() const {
  for (double d : distortion)
    if (d != 0.0) return true;
  return false;
}

Eigen::Matrix<double, 2, 3> PinholeCamera::project_jacobian(const Eigen::Vector3d& p_c) const {
  const double inv_z = 1.0 / p_c.z();
  const double inv_z2 = inv_z * inv_z;
  Eigen::Matrix<double, 2, 3> J;
  J << fx * inv_z, 0.0, -fx * p_c.x() * inv_z2, 0.0, fy * inv_z, -fy * p_c.y() * inv_z2;
  return J;
}

}  // namespace mcslam
