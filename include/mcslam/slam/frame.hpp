#pragma once
// A frame ready for tracking: its immutable features, built from an undistorted RGB-D pair.

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/core/timing.hpp"
#include "mcslam/features/frame_features.hpp"
#include "mcslam/features/lines.hpp"
#include "mcslam/features/orb.hpp"
#include "mcslam/features/planes.hpp"
#include "mcslam/perception/detection.hpp"
#include "mcslam/slam/options.hpp"

namespace mcslam {
class Worker;
}  // namespace mcslam

namespace mcslam::slam {

/// Detected objects of a frame, in undistorted pixel coordinates (the features' frame).
struct FrameObjects {
  std::vector<perception::Detection> boxes;
  /// Detected on this frame's own image; false: the newest boxes of an earlier frame (the
  /// detector was still busy), `age` frames old.
  bool fresh = true;
  int age = 0;
};

struct Frame {
  std::uint64_t id = 0;
  double timestamp = 0.0;
  std::shared_ptr<const features::FrameFeatures> features;
  /// The camera's rolling-shutter readout time (s; 0: a global shutter or not corrected) with
  /// which the features were moved to the middle row's time (FrameMotion).
  double readout_time = 0.0;
  /// Null when no detector or detections file is in use (geometry only).
  std::shared_ptr<const FrameObjects> objects;
};

/// Known camera motion around the frame, used to undo capture-time effects.
struct FrameMotion {
  /// From the depth image's capture time to the colour image's: each keypoint's depth is read
  /// where the depth camera saw that point and moved to the colour capture time; depths that
  /// disagree along the way (depth discontinuities) are dropped.
  std::optional<SE3> T_rgb_depth;
  /// Angular velocity (rad/s, camera frame) and rolling-shutter readout time (s; > 0: rows read
  /// top to bottom, < 0: bottom to top): keypoints are moved to where they would be seen at the
  /// middle row's time.
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();
  double readout_time = 0.0;
  /// Where moving objects are expected in this image (undistorted pixels): the boxes of the
  /// previous frame's moving objects, grown by their possible motion, each up to a depth (the
  /// object's far side; 0: the whole box; < 0: a static object's box, left out of the region).
  /// What is farther inside a box is the background seen past the object. ORB keeps its features
  /// there at most orb.moving_density times as dense as the image average
  /// (features::OrbExtractor::extract).
  struct MovingRegion {
    cv::Rect2f box;
    float max_depth = 0.0f;
  };
  std::vector<MovingRegion> moving_regions;
};

/// The part of a frame's features that does not depend on the camera's motion, and the costly
/// part of building a frame: ORB keypoints and descriptors, line segments with their 3D endpoints
/// fitted in the depth image, and the planes of the depth image. A run can find them ahead, on
/// another thread, while the frame before is tracked (System::extract_features); FrameBuilder
/// then only finishes them with the motion (depth moved to the colour time, rolling shutter).
struct DetectedFeatures {
  features::OrbFeatures orb;
  std::vector<features::LineFeature> lines;
  std::vector<features::PlaneFeature> planes;
  cv::Size size;  ///< of the images they were found in
  /// Extraction times (ms), each on its own thread.
  double orb_ms = 0.0;
  double line_ms = 0.0;
  double plane_ms = 0.0;
  /// What the calling thread waited for the lines and planes after its own points.
  double wait_ms = 0.0;
};

/// Extracts the feature kinds switched on in the options (ORB points with their depth and
/// virtual right coordinate, line segments with 3D endpoints, planes) and tells which plane each
/// point lies on. `gray` is CV_8UC1 and `depth` is CV_32FC1 in metres (0 = missing), both
/// undistorted and of the camera's size.
class FrameBuilder {
 public:
  FrameBuilder(const PinholeCamera& camera, const SystemOptions& options);
  ~FrameBuilder();
  /// detect(), then finish(). Stage times go to `times` when given: orb_extract, then
  /// extract_wait (the wait for lines and planes, extracted on their own threads meanwhile), and
  /// line_extract and plane_extract as concurrent stages (see StageTimes), then feature_finish.
  Frame build(std::uint64_t id, double timestamp, const cv::Mat& gray, const cv::Mat& depth,
              const FrameMotion& motion = {}, StageTimes* times = nullptr) const;
  /// The motion-independent features: points on this thread, lines and planes on their own
  /// meanwhile. `moving` as in OrbExtractor::extract (see needs_moving_mask()). Not thread-safe
  /// (the line extractor's buffers): one call at a time per builder.
  DetectedFeatures detect(const cv::Mat& gray, const cv::Mat& depth,
                          const cv::Mat& moving = {}) const;
  /// The frame from features that detect() found in the same images. Stage time:
  /// feature_finish.
  Frame finish(std::uint64_t id, double timestamp, DetectedFeatures detected, const cv::Mat& gray,
               const cv::Mat& depth, const FrameMotion& motion = {},
               StageTimes* times = nullptr) const;
  /// True when the points depend on the frame before (orb.moving_density > 0 limits them where
  /// it saw movers): detect() then needs that frame's moving regions and cannot run ahead.
  bool needs_moving_mask() const { return orb_.options().moving_density > 0.0; }
  const std::shared_ptr<const features::ScalePyramid>& pyramid() const { return pyramid_; }

 private:
  std::optional<float> depth_at(const cv::Mat& depth, double u, double v) const;
  void finish_points(features::OrbFeatures orb, const cv::Mat& depth, const FrameMotion& motion,
                     features::FrameFeatures& out) const;
  void finish_lines(std::vector<features::LineFeature> lines, const FrameMotion& motion,
                    features::FrameFeatures& out) const;
  /// Planes found in the depth image, moved to the colour time.
  void finish_planes(std::vector<features::PlaneFeature> planes, const FrameMotion& motion,
                     features::FrameFeatures& out) const;
  void assign_planes(features::FrameFeatures& out) const;
  /// The rotation that moves a bearing seen at image row v to the middle row's time.
  Eigen::Matrix3d rolling_shutter_rotation(const FrameMotion& motion, double v) const;

  PinholeCamera camera_;
  FeatureSwitches use_;
  double min_depth_;
  double max_depth_;
  double on_plane_distance_;
  features::OrbExtractor orb_;
  std::unique_ptr<features::LineExtractor> lines_;
  std::unique_ptr<features::PlaneExtractor> planes_;
  /// The threads lines_ and planes_ run on, one each (detect() is called for every frame).
  std::unique_ptr<Worker> line_worker_;
  std::unique_ptr<Worker> plane_worker_;
  std::shared_ptr<const features::ScalePyramid> pyramid_;
};

}  // namespace mcslam::slam
