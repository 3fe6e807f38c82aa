#pragma once
// What one keypoint measures, for the pose optimiser and bundle adjustment.

#include "mcslam/features/frame_features.hpp"
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

}  // namespace mcslam::slam
