#pragma once
// What one keypoint, line segment or plane measures, for the pose optimiser and bundle
// adjustment.

#include <algorithm>
#include <cmath>
#include <optional>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/features/frame_features.hpp"
#include "mcslam/features/lines.hpp"
#include "mcslam/optim/line_residual.hpp"
#include "mcslam/optim/plane_residual.hpp"
#include "mcslam/optim/reprojection.hpp"
#include "mcslam/slam/options.hpp"

namespace mcslam::slam {

/// u, v weighted by the keypoint's pyramid level, and the depth (when the keypoint has one and
/// depth_weight > 0) as `depth_term`, weighted by depth_weight relative to them.
inline optim::PointMeasurement measurement_of(
    const features::PointFeature& f, const features::ScalePyramid& pyramid, double depth_weight,
    optim::DepthTerm depth_term = optim::DepthTerm::kRightU) {
  optim::PointMeasurement m;
  m.uv = f.keypoint.uv.cast<double>();
  m.with_depth = f.has_depth() && depth_weight > 0.0;
  m.depth_term = depth_term;
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

/// The tracker's segment-matching thresholds, the distance scaled by distance_factor (wider
/// windows when the pose prediction is poor).
inline features::LineMatchCriteria line_match_criteria(const TrackerOptions& o,
                                                       double distance_factor = 1.0) {
  features::LineMatchCriteria c;
  c.max_descriptor_distance = o.line_max_descriptor_distance;
  c.max_angle_deg = o.line_max_angle_deg;
  c.max_distance = o.line_max_distance * distance_factor;
  c.min_overlap = o.line_min_overlap;
  return c;
}

/// A 3D segment (world) projected with T_c_w; nullopt when an endpoint is behind the camera or
/// the segment lies entirely outside the image.
inline std::optional<features::PredictedLine> project_segment(const PinholeCamera& camera,
                                                              const SE3& T_c_w,
                                                              const Eigen::Vector3d& start_w,
                                                              const Eigen::Vector3d& end_w) {
  const Eigen::Vector3d s = T_c_w * start_w;
  const Eigen::Vector3d e = T_c_w * end_w;
  constexpr double kMinZ = 0.05;
  if (s.z() < kMinZ || e.z() < kMinZ) return std::nullopt;
  features::PredictedLine line;
  line.start = camera.project(s);
  line.end = camera.project(e);
  if (!camera.in_image(line.start) && !camera.in_image(line.end) &&
      !camera.in_image(0.5 * (line.start + line.end)))
    return std::nullopt;
  return line;
}

/// How well two planes (same frame) agree for matching: angle / plane_match_angle +
/// distance / plane_match_distance, in [0, 2]; nullopt beyond either threshold.
inline std::optional<double> plane_match_score(const TrackerOptions& o, const Eigen::Vector3d& n_a,
                                               double d_a, const Eigen::Vector3d& n_b, double d_b) {
  const double max_angle = o.plane_match_angle_deg * M_PI / 180.0;
  const double angle = std::acos(std::clamp(n_a.dot(n_b), -1.0, 1.0));
  const double distance = std::abs(d_a - d_b);
  if (angle > max_angle || distance > o.plane_match_distance) return std::nullopt;
  return angle / max_angle + distance / o.plane_match_distance;
}

}  // namespace mcslam::slam
