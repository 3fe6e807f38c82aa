#pragma once
// Ground truth of the objects of a rendered synthetic frame: oracle detections (the boxes a
// perfect detector would report) and per-object visibility and motion, for dynamic-object tests.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "mcslam/core/se3.hpp"
#include "mcslam/perception/detection.hpp"
#include "mcslam/synth/renderer.hpp"
#include "mcslam/synth/scene.hpp"

namespace mcslam::synth {

/// An object counts as moving at a frame when its pose changed since the previous frame by more
/// than this translation (metres) or rotation angle (degrees).
inline constexpr double kMovingTranslation = 0.001;
inline constexpr double kMovingAngleDeg = 0.1;

/// Whether T_w_o changed by more than kMovingTranslation or kMovingAngleDeg from `before` to
/// `after`.
bool pose_changed(const SE3& before, const SE3& after);

/// The state of one scene object in one rendered frame.
struct ObjectState {
  int index = -1;  ///< into Scene::objects (also the value of its pixels in RenderedFrame::labels)
  std::string class_name;
  MotionKind motion = MotionKind::kStatic;
  int visible_pixels = 0;  ///< pixels whose label is this object
  /// Bounding rectangle of those pixels (x, y top-left, width, height in pixels, so it contains
  /// exactly the pixels x..x+width-1, y..y+height-1); empty when none is visible.
  cv::Rect box;
  /// pose_changed(pose at time - frame_interval, pose at time).
  bool moving = false;
  SE3 T_w_o;  ///< at the frame's time (the middle of the readout with a rolling shutter)
};

/// One state per object of the scene, in Scene::objects order. Visibility and boxes come from
/// frame.labels (so they match the image exactly, rolling shutter included); poses and the moving
/// flag from the object's pose_at at `time` and `time - frame_interval` (scene seconds).
std::vector<ObjectState> object_states(const RenderedFrame& frame, const Scene& scene, double time,
                                       double frame_interval);

/// The detections of a perfect detector: one per object with at least min_pixels visible pixels,
/// in Scene::objects order, with box = the bounding rectangle of its label pixels (as
/// ObjectState::box), class_name = SceneObject::class_name, class_id =
/// perception::coco_class_id(class_name) and score 1.
perception::FrameDetections oracle_detections(const RenderedFrame& frame, const Scene& scene,
                                              double timestamp, int min_pixels = 400);

/// The oracle's min_pixels for an image size: 400 at 640 x 480, scaled with the image area (at
/// least 1): 25 at 160 x 120.
int oracle_min_pixels(int width, int height);

}  // namespace mcslam::synth
