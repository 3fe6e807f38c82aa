#pragma once
// A frame ready for tracking: its immutable features, built from an undistorted RGB-D pair.

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>

#include "mcslam/core/camera.hpp"
#include "mcslam/features/frame_features.hpp"
#include "mcslam/features/orb.hpp"

namespace mcslam::slam {

struct Frame {
  std::uint64_t id = 0;
  double timestamp = 0.0;
  std::shared_ptr<const features::FrameFeatures> features;
};

/// Builds the per-keypoint depth and virtual right coordinate. `gray` is CV_8UC1 and `depth` is
/// CV_32FC1 in metres (0 = missing), both undistorted and of the camera's size.
class FrameBuilder {
 public:
  FrameBuilder(const PinholeCamera& camera, const features::OrbOptions& orb, double min_depth,
               double max_depth);
  Frame build(std::uint64_t id, double timestamp, const cv::Mat& gray, const cv::Mat& depth) const;
  const std::shared_ptr<const features::ScalePyramid>& pyramid() const { return pyramid_; }

 private:
  PinholeCamera camera_;
  features::OrbExtractor extractor_;
  std::shared_ptr<const features::ScalePyramid> pyramid_;
  double min_depth_;
  double max_depth_;
};

}  // namespace mcslam::slam
