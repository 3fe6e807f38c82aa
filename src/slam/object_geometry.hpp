#pragma once
// Small helpers shared by the object stages (object_boxes.cpp, object_motion.cpp,
// object_movers.cpp): boxes and pixels, medians, an object's depth band, static predictions and
// descriptor matches. Internal to the slam module.

#include <Eigen/Core>
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <utility>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/features/frame_features.hpp"
#include "mcslam/features/matching.hpp"

namespace mcslam::slam::object_geometry {

inline bool contains(const cv::Rect2f& r, const Eigen::Vector2f& p) {
  return p.x() >= r.x && p.y() >= r.y && p.x() < r.x + r.width && p.y() < r.y + r.height;
}

inline cv::Rect2f grown(const cv::Rect2f& r, float dx, float dy) {
  return {r.x - dx, r.y - dy, r.width + 2 * dx, r.height + 2 * dy};
}

/// A box grown by 5 % a frame of `age` (at most 30 %): objects move while a detection ages.
inline cv::Rect2f aged(const cv::Rect2f& r, int age) {
  const float grow = std::min(0.3f, 0.05f * static_cast<float>(age));
  return grown(r, grow * r.width / 2, grow * r.height / 2);
}

template <typename T>
T median_of(std::vector<T> v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

/// The object's depth band among the depths of a box's features: they are split into clusters
/// where sorted depths jump by more than `gap`; the object is the largest cluster or, given the
/// object's depth when it was last seen (`last_depth` > 0), the cluster whose median is nearest
/// to it: an object's depth changes by its speed times the time since (a person walking, 5 cm
/// a frame at 30 Hz), while the largest cluster is the background once a box spans most of the
/// image.
inline std::optional<std::pair<float, float>> object_band(std::vector<float> depths, double gap,
                                                          float last_depth = -1.0f) {
  if (depths.empty()) return std::nullopt;
  std::sort(depths.begin(), depths.end());
  std::size_t best_start = 0, best_size = 0, start = 0;
  float best_offset = std::numeric_limits<float>::infinity();
  for (std::size_t i = 1; i <= depths.size(); ++i) {
    if (i < depths.size() && depths[i] - depths[i - 1] <= gap) continue;
    const std::size_t size = i - start;
    const float offset = std::abs(depths[start + size / 2] - last_depth);
    if (last_depth > 0.0f ? offset < best_offset : size > best_size) {
      best_size = size;
      best_start = start;
      best_offset = offset;
    }
    start = i;
  }
  return std::make_pair(depths[best_start], depths[best_start + best_size - 1]);
}

/// Whether point `p` lies on a frame plane flagged in `moving_plane`.
inline bool on_moving_plane(const features::PointFeature& p,
                            const std::vector<std::uint8_t>& moving_plane) {
  return p.plane >= 0 && static_cast<std::size_t>(p.plane) < moving_plane.size() &&
         moving_plane[static_cast<std::size_t>(p.plane)] != 0;
}

/// Where pixel `uv` (with `depth`; <= 0: none, then moved by the rotation alone) would be in a
/// frame at T_to_from if it were static; nullopt behind that camera.
inline std::optional<Eigen::Vector2d> static_prediction(const PinholeCamera& camera,
                                                        const SE3& T_to_from,
                                                        const Eigen::Vector2d& uv, double depth) {
  const Eigen::Vector3d p = depth > 0.0 ? T_to_from * camera.unproject(uv, depth)
                                        : T_to_from.rotation() * camera.unproject(uv, 1.0);
  if (p.z() <= 1e-6) return std::nullopt;
  return camera.project(p);
}

/// The candidate whose ORB descriptor is closest to `descriptor`, when within `max_distance`
/// and clearly better than the second closest (ratio 0.8); -1 otherwise. `best` gets its
/// distance.
inline int unambiguous_match(const features::OrbDescriptor& descriptor,
                             const std::vector<int>& candidates,
                             const std::vector<features::PointFeature>& points, int max_distance,
                             int* best = nullptr) {
  int first = 256, second = 256, index = -1;
  for (int j : candidates) {
    const int d =
        features::hamming_distance(descriptor, points[static_cast<std::size_t>(j)].descriptor);
    if (d < first) {
      second = first;
      first = d;
      index = j;
    } else if (d < second) {
      second = d;
    }
  }
  if (best) *best = first;
  if (index < 0 || first > max_distance || first > 0.8 * second) return -1;
  return index;
}

}  // namespace mcslam::slam::object_geometry
