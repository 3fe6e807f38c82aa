#include "mcslam/slam/frame.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>

#include "mcslam/core/worker.hpp"

namespace mcslam::slam {
namespace {
/// Relative depth difference above which two depth lookups are taken to straddle an edge.
constexpr double kDepthConsistency = 0.03;

bool rolling(const FrameMotion& motion) {
  return motion.readout_time != 0.0 && motion.angular_velocity.norm() > 0.0;
}
}  // namespace

FrameBuilder::FrameBuilder(const PinholeCamera& camera, const SystemOptions& options)
    : camera_(camera),
      use_(options.use),
      min_depth_(options.tracker.min_depth),
      max_depth_(options.tracker.max_depth),
      on_plane_distance_(options.tracker.on_plane_distance),
      orb_(options.orb),
      pyramid_(std::make_shared<features::ScalePyramid>(options.orb.num_levels,
                                                        options.orb.scale_factor)) {
  if (use_.lines) {
    lines_ = std::make_unique<features::LineExtractor>(options.lines);
    line_worker_ = std::make_unique<Worker>("mcslam-lines");
  }
  if (use_.planes) {
    planes_ = std::make_unique<features::PlaneExtractor>(camera, options.planes);
    plane_worker_ = std::make_unique<Worker>("mcslam-planes");
  }
}

FrameBuilder::~FrameBuilder() = default;

std::optional<float> FrameBuilder::depth_at(const cv::Mat& depth, double u, double v) const {
  const int x = static_cast<int>(std::lround(u));
  const int y = static_cast<int>(std::lround(v));
  if (x < 0 || y < 0 || x >= depth.cols || y >= depth.rows) return std::nullopt;
  const float d = depth.at<float>(y, x);
  if (!std::isfinite(d) || d < min_depth_ || d > max_depth_) return std::nullopt;
  return d;
}

Eigen::Matrix3d FrameBuilder::rolling_shutter_rotation(const FrameMotion& motion, double v) const {
  // Row v was exposed (v - H/2) / H * readout after the middle row: rotate its bearing back.
  const double tau = (v - 0.5 * camera_.height) / camera_.height * motion.readout_time;
  return so3_exp(motion.angular_velocity * tau).toRotationMatrix().transpose();
}

namespace {

/// The pixels of `regions`: inside a box and not beyond its depth (a missing depth counts as
/// inside). Empty when there are no regions.
cv::Mat moving_mask(const std::vector<FrameMotion::MovingRegion>& regions, const cv::Mat& depth) {
  if (regions.empty() || depth.empty()) return {};
  cv::Mat mask = cv::Mat::zeros(depth.size(), CV_8UC1);
  const cv::Rect image(0, 0, depth.cols, depth.rows);
  for (const FrameMotion::MovingRegion& r : regions) {
    if (r.max_depth < 0.0f) continue;  // a static object's box: cleared below
    const cv::Rect box =
        image & cv::Rect(cv::Point(static_cast<int>(std::floor(r.box.x)),
                                   static_cast<int>(std::floor(r.box.y))),
                         cv::Point(static_cast<int>(std::ceil(r.box.x + r.box.width)),
                                   static_cast<int>(std::ceil(r.box.y + r.box.height))));
    for (int v = box.y; v < box.y + box.height; ++v) {
      const float* d = depth.ptr<float>(v);
      std::uint8_t* m = mask.ptr<std::uint8_t>(v);
      for (int u = box.x; u < box.x + box.width; ++u)
        if (r.max_depth <= 0.0f || !(d[u] > 0.0f) || d[u] <= r.max_depth) m[u] = 1;
    }
  }
  for (const FrameMotion::MovingRegion& r : regions)
    if (r.max_depth < 0.0f) mask(image & cv::Rect(r.box)).setTo(0);
  return mask;
}

}  // namespace

Frame FrameBuilder::build(std::uint64_t id, double timestamp, const cv::Mat& gray,
                          const cv::Mat& depth, const FrameMotion& motion,
                          StageTimes* times) const {
  // The mask only matters when ORB limits its features there (orb.moving_density > 0).
  const cv::Mat moving =
      needs_moving_mask() ? moving_mask(motion.moving_regions, depth) : cv::Mat();
  DetectedFeatures detected = detect(gray, depth, moving);
  if (times) {
    times->add("orb_extract", detected.orb_ms);
    times->add("extract_wait", detected.wait_ms);
    if (use_.lines) times->add_concurrent("line_extract", detected.line_ms);
    if (use_.planes) times->add_concurrent("plane_extract", detected.plane_ms);
  }
  return finish(id, timestamp, std::move(detected), gray, depth, motion, times);
}

DetectedFeatures FrameBuilder::detect(const cv::Mat& gray, const cv::Mat& depth,
                                      const cv::Mat& moving) const {
  DetectedFeatures out;
  out.size = gray.size();
  // Lines and planes are extracted on their workers while this thread extracts the points: the
  // three read the images only and write their own lists.
  if (line_worker_)
    line_worker_->post([&] {
      Stopwatch w;
      out.lines = lines_->extract(gray);
      for (auto& line : out.lines) lines_->fit_depth(camera_, depth, line);
      out.line_ms = w.elapsed_ms();
    });
  if (plane_worker_)
    plane_worker_->post([&] {
      Stopwatch w;
      // The frame uses the planes, not the pixels' labels.
      out.planes = planes_->extract(depth, features::PlaneExtractor::Labels::kNone).planes;
      out.plane_ms = w.elapsed_ms();
    });
  Stopwatch watch;
  // Both workers are waited for even when the points throw: their jobs refer to this frame.
  std::exception_ptr error;
  try {
    if (use_.points) out.orb = orb_.extract(gray, moving);
  } catch (...) {
    error = std::current_exception();
  }
  out.orb_ms = watch.elapsed_ms();
  watch.restart();
  for (Worker* worker : {line_worker_.get(), plane_worker_.get()}) {
    if (!worker) continue;
    try {
      worker->wait();
    } catch (...) {
      if (!error) error = std::current_exception();
    }
  }
  if (error) std::rethrow_exception(error);
  out.wait_ms = watch.elapsed_ms();
  return out;
}

Frame FrameBuilder::finish(std::uint64_t id, double timestamp, DetectedFeatures detected,
                           const cv::Mat& gray, const cv::Mat& depth, const FrameMotion& motion,
                           StageTimes* times) const {
  Stopwatch watch;
  auto result = std::make_shared<features::FrameFeatures>();
  result->pyramid = pyramid_;
  result->image = gray;
  if (use_.points) finish_points(std::move(detected.orb), depth, motion, *result);
  if (use_.lines) finish_lines(std::move(detected.lines), motion, *result);
  if (use_.planes) {
    finish_planes(std::move(detected.planes), motion, *result);
    assign_planes(*result);
  }
  if (times) times->add("feature_finish", watch.elapsed_ms());
  Frame frame;
  frame.id = id;
  frame.timestamp = timestamp;
  frame.features = std::move(result);
  frame.readout_time = motion.readout_time;
  return frame;
}

void FrameBuilder::finish_points(features::OrbFeatures orb, const cv::Mat& depth,
                                 const FrameMotion& motion, features::FrameFeatures& out) const {
  const bool compensate = motion.T_rgb_depth.has_value();
  const SE3 T_rgb_d = compensate ? *motion.T_rgb_depth : SE3();
  const SE3 T_d_rgb = T_rgb_d.inverse();
  const bool rolling_shutter = rolling(motion);
  out.points.resize(orb.keypoints.size());
  for (std::size_t i = 0; i < orb.keypoints.size(); ++i) {
    features::PointFeature& p = out.points[i];
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
    if (rolling_shutter) {
      const Eigen::Vector3d at_middle =
          rolling_shutter_rotation(motion, uv.y()) * camera_.unproject(uv, d ? *d : 1.0);
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
  if (rolling_shutter) {
    for (std::size_t i = 0; i < orb.keypoints.size(); ++i)
      orb.keypoints[i] = out.points[i].keypoint;
  }
  out.grid = features::KeypointGrid(orb.keypoints, camera_.width, camera_.height);
}

void FrameBuilder::finish_lines(std::vector<features::LineFeature> lines, const FrameMotion& motion,
                                features::FrameFeatures& out) const {
  out.lines = std::move(lines);
  const bool compensate = motion.T_rgb_depth.has_value();
  const bool rolling_shutter = rolling(motion);
  for (auto& line : out.lines) {
    // Fitted in detect(). The same depth range as points: beyond it the sensor's depth is not to be
    // trusted.
    if (line.has_depth && (std::min(line.start_c.z(), line.end_c.z()) < min_depth_ ||
                           std::max(line.start_c.z(), line.end_c.z()) > max_depth_))
      line.has_depth = false;
    if (line.has_depth && compensate) {
      // Fitted in the depth image: move the 3D segment to the colour capture time.
      line.start_c = *motion.T_rgb_depth * line.start_c;
      line.end_c = *motion.T_rgb_depth * line.end_c;
      if (line.start_c.z() <= 0.0 || line.end_c.z() <= 0.0) line.has_depth = false;
    }
    if (!rolling_shutter) continue;
    // Each endpoint moves with its own row's time, as keypoints do.
    for (int k = 0; k < 2; ++k) {
      Eigen::Vector2f& uv = k == 0 ? line.start : line.end;
      Eigen::Vector3d& p_c = k == 0 ? line.start_c : line.end_c;
      const Eigen::Matrix3d R = rolling_shutter_rotation(motion, uv.y());
      const Eigen::Vector3d bearing = R * camera_.unproject(uv.cast<double>(), 1.0);
      if (bearing.z() > 0.0) uv = camera_.project(bearing).cast<float>();
      if (line.has_depth) p_c = R * p_c;
    }
  }
}

void FrameBuilder::finish_planes(std::vector<features::PlaneFeature> planes,
                                 const FrameMotion& motion, features::FrameFeatures& out) const {
  out.planes = std::move(planes);
  if (motion.T_rgb_depth) {
    // n' = R n, d' = d - n' . t moves a plane from the depth capture time to the colour one.
    const SE3& T = *motion.T_rgb_depth;
    for (auto& plane : out.planes) {
      plane.normal = T.rotation() * plane.normal;
      plane.d -= plane.normal.dot(T.translation());
      plane.centroid = T * plane.centroid;
      for (auto& h : plane.hull) h = T * h;
    }
  }
}

void FrameBuilder::assign_planes(features::FrameFeatures& out) const {
  // The plane each point with depth lies on (the nearest within on_plane_distance).
  for (auto& p : out.points) {
    if (!p.has_depth()) continue;
    const Eigen::Vector3d p_c = camera_.unproject(p.keypoint.uv.cast<double>(), p.depth);
    double best = on_plane_distance_;
    for (std::size_t k = 0; k < out.planes.size(); ++k) {
      const double distance = std::abs(out.planes[k].distance(p_c));
      if (distance < best) {
        best = distance;
        p.plane = static_cast<int>(k);
      }
    }
  }
}

}  // namespace mcslam::slam
