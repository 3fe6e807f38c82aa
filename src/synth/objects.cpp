#include "mcslam/synth/objects.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace mcslam::synth {
namespace {

constexpr double kRadToDeg = 180.0 / 3.141592653589793;

/// Pixel count and bounding rectangle of every label 0 .. count - 1 in one pass.
struct LabelStats {
  int pixels = 0;
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;  // inclusive bounds
};

std::vector<LabelStats> label_stats(const cv::Mat& labels, int count) {
  CV_Assert(labels.type() == CV_16SC1);
  std::vector<LabelStats> stats(static_cast<std::size_t>(std::max(count, 0)));
  for (int y = 0; y < labels.rows; ++y) {
    const std::int16_t* row = labels.ptr<std::int16_t>(y);
    for (int x = 0; x < labels.cols; ++x) {
      const int k = row[x];
      if (k < 0 || k >= count) continue;
      LabelStats& s = stats[static_cast<std::size_t>(k)];
      if (s.pixels++ == 0) {
        s.x0 = s.x1 = x;
        s.y0 = s.y1 = y;
        continue;
      }
      s.x0 = std::min(s.x0, x), s.x1 = std::max(s.x1, x);
      s.y0 = std::min(s.y0, y), s.y1 = std::max(s.y1, y);
    }
  }
  return stats;
}

cv::Rect rect_of(const LabelStats& s) {
  return s.pixels > 0 ? cv::Rect(s.x0, s.y0, s.x1 - s.x0 + 1, s.y1 - s.y0 + 1) : cv::Rect();
}

}  // namespace

bool pose_changed(const SE3& before, const SE3& after) {
  const double moved = (after.translation() - before.translation()).norm();
  const double turned =
      rotation_angle(before.quaternion().conjugate() * after.quaternion()) * kRadToDeg;
  return moved > kMovingTranslation || turned > kMovingAngleDeg;
}

std::vector<ObjectState> object_states(const RenderedFrame& frame, const Scene& scene, double time,
                                       double frame_interval) {
  const int n = static_cast<int>(scene.objects.size());
  const std::vector<LabelStats> stats = label_stats(frame.labels, n);
  std::vector<ObjectState> states;
  states.reserve(scene.objects.size());
  for (int k = 0; k < n; ++k) {
    const SceneObject& object = scene.objects[static_cast<std::size_t>(k)];
    ObjectState state;
    state.index = k;
    state.class_name = object.class_name;
    state.motion = object.motion;
    state.visible_pixels = stats[static_cast<std::size_t>(k)].pixels;
    state.box = rect_of(stats[static_cast<std::size_t>(k)]);
    state.T_w_o = object.pose_at(time);
    state.moving = pose_changed(object.pose_at(time - frame_interval), state.T_w_o);
    states.push_back(std::move(state));
  }
  return states;
}

perception::FrameDetections oracle_detections(const RenderedFrame& frame, const Scene& scene,
                                              double timestamp, int min_pixels) {
  const int n = static_cast<int>(scene.objects.size());
  const std::vector<LabelStats> stats = label_stats(frame.labels, n);
  perception::FrameDetections out;
  out.timestamp = timestamp;
  for (int k = 0; k < n; ++k) {
    const LabelStats& s = stats[static_cast<std::size_t>(k)];
    if (s.pixels == 0 || s.pixels < min_pixels) continue;
    if (!scene.objects[static_cast<std::size_t>(k)].detectable) continue;
    perception::Detection d;
    const cv::Rect r = rect_of(s);
    d.box = cv::Rect2f(static_cast<float>(r.x), static_cast<float>(r.y),
                       static_cast<float>(r.width), static_cast<float>(r.height));
    d.class_name = scene.objects[static_cast<std::size_t>(k)].class_name;
    d.class_id = perception::coco_class_id(d.class_name);
    d.score = 1.0f;
    out.detections.push_back(std::move(d));
  }
  return out;
}

int oracle_min_pixels(int width, int height) {
  const double scaled = 400.0 * static_cast<double>(width) * height / (640.0 * 480.0);
  return std::max(1, static_cast<int>(std::lround(scaled)));
}

}  // namespace mcslam::synth
