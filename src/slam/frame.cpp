#include "mcslam/slam/frame.hpp"

#include <cmath>

namespace mcslam::slam {

FrameBuilder::FrameBuilder(const PinholeCamera& camera, const features::OrbOptions& orb,
                           double min_depth, double max_depth)
    : camera_(camera),
      extractor_(orb),
      pyramid_(std::make_shared<features::ScalePyramid>(orb.num_levels, orb.scale_factor)),
      min_depth_(min_depth),
      max_depth_(max_depth) {}

Frame FrameBuilder::build(std::uint64_t id, double timestamp, const cv::Mat& gray,
                          const cv::Mat& depth) const {
  auto result = std::make_shared<features::FrameFeatures>();
  features::OrbFeatures orb = extractor_.extract(gray);
  result->points.resize(orb.keypoints.size());
  for (std::size_t i = 0; i < orb.keypoints.size(); ++i) {
    features::PointFeature& p = result->points[i];
    p.keypoint = orb.keypoints[i];
    p.descriptor = orb.descriptors[i];
    const int u = static_cast<int>(std::lround(p.keypoint.uv.x()));
    const int v = static_cast<int>(std::lround(p.keypoint.uv.y()));
    if (u < 0 || v < 0 || u >= depth.cols || v >= depth.rows) continue;
    const float d = depth.at<float>(v, u);
    if (std::isfinite(d) && d >= min_depth_ && d <= max_depth_) {
      p.depth = d;
      p.u_right = static_cast<float>(camera_.right_u(p.keypoint.uv.x(), d));
    }
  }
  result->grid = features::KeypointGrid(orb.keypoints, camera_.width, camera_.height);
  result->pyramid = pyramid_;
  Frame frame;
  frame.id = id;
  frame.timestamp = timestamp;
  frame.features = std::move(result);
  return frame;
}

}  // namespace mcslam::slam
