#pragma once
// What one keypoint, line segment or plane measures, for the pose optimiser and bundle
// adjustment.

#include <cmath>

#include "mcslam/features/frame_features.hpp"
#include "mcslam/optim/line_residual.hpp"
#include "mcslam/optim/plane_residual.hpp"
#include "mcslam/optim/reprojection.hpp"

namespace mcslam::slam {

/// u, v weighted by the keypoint's pyramid level, and u_right (when the keypoint has a depth
/// and depth_weight > 0) weighted by depth_weight relative to them.
inline optim::PointMeasurement measurement_of(const features::PointFeature& f,
                                              const features::ScalePyramid& pyramid,
                                              double depth_weight) {
  optim::PointMeasurement m;
  m.uv = f.keypoint.uv.cast<double>();
  m.with_depth = f.has_depth() && depth_weight > 0.0;
  m.u_right = f.u_right;
  m.information = pyramid.inv_sigma2[static_cast<std::size_t>(f.keypoint.level)];
  m.right_information = m.information * depth_weight;
  return m;
}

/// The segment's normalised line, weighted by 1 / sigma^2 (sigma in pixels).
inline optim::LineMeasurement line_measurement_of(const features::LineFeature& f, double sigma) {
  optim::LineMeasurement m;
  m.coefficients = f.coefficients();
  m.information = 1.0 / (sigma * sigma);
  return m;
}

/// The plane in the camera frame, its angles weighted by 1 / sigma_angle^2 and its distance by
/// 1 / sigma_distance^2.
inline optim::PlaneMeasurement plane_measurement_of(const features::PlaneFeature& f,
                                                    double sigma_angle_deg, double sigma_distance) {
  optim::PlaneMeasurement m;
  m.normal = f.normal;
  m.d = f.d;
  const double sigma_angle = sigma_angle_deg * M_PI / 180.0;
  m.angle_information = 1.0 / (sigma_angle * sigma_angle);
  m.distance_information = 1.0 / (sigma_distance * sigma_distance);
  return m;
}

}  // namespace mcslam::slam
