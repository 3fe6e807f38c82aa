#pragma once
// A correction of the map (loop closing, a merged bundle adjustment of the whole map): new poses
// for some keyframes, with everything else following the keyframe it hangs on.

#include <unordered_map>
#include <utility>
#include <vector>

#include "mcslam/core/se3.hpp"
#include "mcslam/map/map.hpp"

namespace mcslam::map {

/// A correction of the map: keyframe poses (T_c_w) before and after, and optionally new
/// positions of landmarks. A listed keyframe moves by its own correction, before -> after,
/// applied to the pose it has now (so a local BA that refined it since `before` was taken keeps
/// its refinement). Keyframes without a new pose keep their pose relative to a corrected keyframe
/// (their strongest covisible one, else the closest earlier one); landmarks without a new
/// position move with their reference keyframe (the one that created them, else their first
/// observer). All of it is applied at once, under one write lock.
struct MapCorrection {
  std::unordered_map<KeyFrameId, SE3> before;
  std::unordered_map<KeyFrameId, SE3> after;
  /// Only the listed keyframes move, with the landmarks whose reference keyframe is listed; the
  /// rest of the map stays (the first, local step of a loop correction).
  bool listed_only = false;
  std::unordered_map<PointId, Eigen::Vector3d> points;
  /// Where the points of `points` were when the correction was computed: a point that moved
  /// since (local BA refined it) is moved with its keyframe instead of being set to a position
  /// solved from older data. Empty: `points` are set as given.
  std::unordered_map<PointId, Eigen::Vector3d> points_before;
  std::unordered_map<LineId, std::pair<Eigen::Vector3d, Eigen::Vector3d>> lines;
  std::unordered_map<PlaneId, Eigen::Vector4d> planes;
  /// Observations found to be outliers (erased first).
  std::vector<std::pair<KeyFrameId, PointId>> point_outliers;
  std::vector<std::pair<KeyFrameId, LineId>> line_outliers;
  std::vector<std::pair<KeyFrameId, PlaneId>> plane_outliers;
};

/// Call under the map's write lock.
void apply_correction(Map& map, const MapCorrection& correction);

}  // namespace mcslam::map
