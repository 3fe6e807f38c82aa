#pragma once
// The immutable observations of one RGB-D frame (ORB points, line segments, planes), shared by the
// frame and, when it becomes a keyframe, by the keyframe (std::shared_ptr<const FrameFeatures>).

#include <cmath>
#include <memory>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "mcslam/features/grid.hpp"
#include "mcslam/features/lines.hpp"
#include "mcslam/features/orb.hpp"
#include "mcslam/features/planes.hpp"

namespace mcslam::features {

/// Per-level scale of an ORB pyramid, derived from its options.
struct ScalePyramid {
  std::vector<double> scale;       // 1, s, s^2, ...
  std::vector<double> sigma2;      // scale^2: variance of a keypoint position at that level
  std::vector<double> inv_sigma2;  // 1 / sigma2
  double log_scale_factor = 0.0;

  ScalePyramid() = default;
  ScalePyramid(int levels, double factor) : log_scale_factor(std::log(factor)) {
    double s = 1.0;
    for (int i = 0; i < levels; ++i) {
      scale.push_back(s);
      sigma2.push_back(s * s);
      inv_sigma2.push_back(1.0 / (s * s));
      s *= factor;
    }
  }
  int levels() const { return static_cast<int>(scale.size()); }
  /// The level at which a point seen at `distance` is expected, given its maximum distance.
  int predict_level(double distance, double max_distance) const {
    const double ratio = max_distance / distance;
    int level = static_cast<int>(std::ceil(std::log(ratio) / log_scale_factor));
    if (level < 0) level = 0;
    if (level >= levels()) level = levels() - 1;
    return level;
  }
};

/// One ORB keypoint with its descriptor and depth. depth <= 0 means no valid depth; then
/// u_right < 0 as well.
struct PointFeature {
  Keypoint keypoint;
  OrbDescriptor descriptor;
  float depth = -1.0f;
  float u_right = -1.0f;
  /// The frame plane (index into FrameFeatures::planes) the point lies on, -1 for none: later
  /// stages use it to tell an object's features from those of the floor or wall behind it.
  int plane = -1;

  bool has_depth() const { return depth > 0.0f; }
};

struct FrameFeatures {
  std::vector<PointFeature> points;
  std::vector<LineFeature> lines;
  std::vector<PlaneFeature> planes;
  KeypointGrid grid;
  std::shared_ptr<const ScalePyramid> pyramid;
  /// The undistorted grey image the features came from (shared, not copied): object boxes are
  /// carried between frames by the optical flow of their features.
  cv::Mat image;

  /// The points' descriptors, in point order (for matching and bags of words).
  std::vector<OrbDescriptor> point_descriptors() const {
    std::vector<OrbDescriptor> out;
    out.reserve(points.size());
    for (const PointFeature& p : points) out.push_back(p.descriptor);
    return out;
  }
};

}  // namespace mcslam::features
