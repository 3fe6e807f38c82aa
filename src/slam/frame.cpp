#include "mcslam/slam/frame.hpp"

#include <cmath>

namespace mcslam::slam {
namespace {
/// Relative depth difference above which two depth lookups are taken to straddle an edge.
constexpr double kDepthConsistency = 0.03;
}  // namespace

FrameBuilder::FrameBuilder(const PinholeCamera& camera, const features::OrbOptions& orb,
                           double min_depth, double max_depth)
    : camera_(camera),
      extractor_(orb),
      pyramid_(std::make_shared<features::ScalePyramid>(orb.num_levels, orb.scale_factor)),
      min_depth_(min_depth),
      max_depth_(max_depth) {}

std::optional<float> FrameBuilder::depth_at(const cv::Mat& depth, double u, double v) const {
  const int x = static_cast<int>(std::lround(u));
  const int y = static_cast<int>(std::lround(v));
  if (x < 0 || y < 0 || x >= depth.cols || y >= depth.rows) return std::nullopt;
  const float d = depth.at<float>(y, x);
  if (!std::isfinite(d) || d < min_depth_ || d > max_depth_) return std::nullopt;
  return d;
}

Frame FrameBuilder::build(std::uint64_t id, double timestamp, const cv::Mat& gray,
                          const cv::Mat& depth, const FrameMotion& motion) const {
  const bool compensate = motion.T_rgb_depth.has_value();
  const SE3 T_rgb_d = compensate ? *motion.T_rgb_depth : SE3();
  const bool rolling = motion.readout_time > 0.0 && motion.angular_velocity.norm() > 0.0;
  const double half_height = 0.5 * camera_.height;
  const SE3 T_d_rgb = T_rgb_d.inverse();
  auto result = std::make_shared<features::FrameFeatures>();
  features::OrbFeatures orb = extractor_.extract(gray);
  result->points.resize(orb.keypoints.size());
  for (std::size_t i = 0; i < orb.keypoints.size(); ++i) {
    features::PointFeature& p = result->points[i];
    p.keypoint = orb.keypoints[i];
    p.descriptor = orb.descriptors[i];
    const Eigen::Vector2d uv = p.keypoint.uv.cast<double>();
    std::optional<float> d = depth_at(depth, uv.x(), uv.y());
    if (d && compensate) {
      // Where the depth camera saw this point, and its depth there moved to the colour time.
      const Eigen::Vector3d p_depth = T_d_rgb * camera_.unproject(uv, *d);
      std::optional<float> d_seen;
      if (p_depth.z() > 0.0) {
        const Eigen::Vector2d uv_depth = camera_.project(p_depth);
        d_seen = depth_at(depth, uv_depth.x(), uv_depth.y());
        if (d_seen && std::abs(*d_seen - p_depth.z()) > kDepthConsistency * p_depth.z())
          d_seen.reset();  // a depth discontinuity between the two looks
        if (d_seen) {
          const Eigen::Vector3d p_rgb = T_rgb_d * camera_.unproject(uv_depth, *d_seen);
          d_seen = static_cast<float>(p_rgb.z());
        }
      }
      d = d_seen;
    }
    if (rolling) {
      // Row v was exposed (v - H/2) / H * readout after the middle row: rotate its bearing back.
      const double tau = (uv.y() - half_height) / camera_.height * motion.readout_time;
      const Eigen::Matrix3d R_t_tau = so3_exp(motion.angular_velocity * tau).toRotationMatrix();
      const Eigen::Vector3d bearing = camera_.unproject(uv, d ? *d : 1.0);
      const Eigen::Vector3d at_middle = R_t_tau.transpose() * bearing;
      if (at_middle.z() > 0.0) {
        p.keypoint.uv = camera_.project(at_middle).cast<float>();
        if (d) d = static_cast<float>(at_middle.z());
      }
    }
    if (d) {
      p.depth = *d;
      p.u_right = static_cast<float>(camera_.right_u(p.keypoint.uv.x(), *d));
    }
  }
  if (rolling) {
    for (std::size_t i = 0; i < orb.keypoints.size(); ++i)
      orb.keypoints[i] = result->points[i].keypoint;
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
