#include "mcslam/map/correction.hpp"

#include <algorithm>
#include <optional>
#include <unordered_map>
#include <vector>

namespace mcslam::map {

namespace {

/// The keyframe a landmark moves with: the one that created it while it exists, else its first
/// observer that exists.
template <typename Observations>
KeyFrameId reference_keyframe(const Map& map, KeyFrameId first, const Observations& observations) {
  if (map.keyframe(first) != nullptr) return first;
  for (const auto& obs : observations)
    if (map.keyframe(obs.first) != nullptr) return obs.first;
  return kNoId;
}

/// Old and new pose of a keyframe.
struct Move {
  SE3 old_T_c_w;
  SE3 new_T_c_w;
};
using Moves = std::unordered_map<KeyFrameId, Move>;

/// Removes the observations the correction found to be outliers. erase_observation recomputes the
/// descriptor of a point that loses an observation.
void erase_outliers(Map& map, const MapCorrection& correction) {
  for (const auto& [kf, point] : correction.point_outliers)
    if (map.point(point) != nullptr) map.erase_observation(point, kf);
  for (const auto& [kf, line] : correction.line_outliers)
    if (map.line(line) != nullptr) map.erase_line_observation(line, kf);
  for (const auto& [kf, plane] : correction.plane_outliers)
    if (map.plane(plane) != nullptr) map.erase_plane_observation(plane, kf);
}

/// The moves of the listed keyframes that exist and, unless listed_only, of every other keyframe
/// (with the keyframe it hangs on). Empty when no listed keyframe exists.
Moves keyframe_moves(const Map& map, const MapCorrection& correction) {
  Moves moves;
  std::vector<KeyFrameId> corrected;
  for (const auto& [id, T] : correction.after)
    if (map.keyframe(id) != nullptr) corrected.push_back(id);
  std::sort(corrected.begin(), corrected.end());
  if (corrected.empty()) return moves;
  // A listed keyframe at pose C now, corrected from B to A: C B^-1 A (A when C = B). Its world
  // motion, p' = A^-1 B p, is the same whatever local BA did to it since B.
  for (KeyFrameId id : corrected) {
    const SE3& now = map.keyframe(id)->T_c_w;
    const SE3& after = correction.after.at(id);
    const auto b = correction.before.find(id);
    moves[id] = {now, b != correction.before.end() ? now * b->second.inverse() * after : after};
  }
  for (const auto& [id, kf] : map.keyframes()) {
    if (moves.count(id) != 0 || correction.listed_only) continue;
    // The keyframe it hangs on: its strongest covisible corrected keyframe, else the closest
    // earlier corrected one (else the first).
    KeyFrameId ref = kNoId;
    for (KeyFrameId other : map.best_covisible(id, kf.covisibility.size()))
      if (correction.after.count(other) != 0 && map.keyframe(other) != nullptr) {
        ref = other;
        break;
      }
    if (ref == kNoId) {
      auto it = std::upper_bound(corrected.begin(), corrected.end(), id);
      ref = it == corrected.begin() ? corrected.front() : *(it - 1);
    }
    const Move& r = moves.at(ref);
    moves[id] = {kf.T_c_w, kf.T_c_w * r.old_T_c_w.inverse() * r.new_T_c_w};
  }
  return moves;
}

/// World-to-world motion of a landmark: p' = T_new^-1 T_old p of the keyframe it moves with
/// (reference_keyframe); nothing when that keyframe did not move.
template <typename Observations>
std::optional<SE3> landmark_motion(const Map& map, const Moves& moves, KeyFrameId first,
                                   const Observations& observations) {
  const auto it = moves.find(reference_keyframe(map, first, observations));
  if (it == moves.end()) return std::nullopt;
  return it->second.new_T_c_w.inverse() * it->second.old_T_c_w;
}

/// Points take their solved position when they have not moved since the solve (or no positions
/// at the solve were given), else move with their reference keyframe.
void move_points(Map& map, const MapCorrection& correction, const Moves& moves) {
  const auto unchanged_since_solved = [&](PointId id, const Eigen::Vector3d& p_w) {
    if (correction.points_before.empty()) return true;
    const auto it = correction.points_before.find(id);
    return it != correction.points_before.end() && it->second == p_w;
  };
  std::vector<PointId> point_ids;
  for (const auto& [id, p] : map.points()) point_ids.push_back(id);
  for (PointId id : point_ids) {
    const MapPoint& p = *map.point(id);
    const auto solved = correction.points.find(id);
    const auto m = landmark_motion(map, moves, p.first_keyframe, p.observations);
    if (solved != correction.points.end() && unchanged_since_solved(id, p.p_w)) {
      map.set_point_position(id, solved->second);
    } else if (m) {
      map.set_point_position(id, (*m) * p.p_w);
    } else if (solved == correction.points.end()) {
      continue;  // neither solved nor moved: nothing about it changed
    }
    map.update_point_geometry(id);  // a move changes no descriptor
  }
}

/// Lines take their solved endpoints, else move with their reference keyframe.
void move_lines(Map& map, const MapCorrection& correction, const Moves& moves) {
  std::vector<LineId> line_ids;
  for (const auto& [id, l] : map.lines()) line_ids.push_back(id);
  for (LineId id : line_ids) {
    const MapLine& l = *map.line(id);
    if (const auto it = correction.lines.find(id); it != correction.lines.end()) {
      map.set_line_endpoints(id, it->second.first, it->second.second);
    } else if (const auto m = landmark_motion(map, moves, l.first_keyframe, l.observations)) {
      map.set_line_endpoints(id, (*m) * l.start_w, (*m) * l.end_w);
    }
  }
}

/// Planes take their solved coefficients, else move with their reference keyframe; their hulls
/// always move with it.
void move_planes(Map& map, const MapCorrection& correction, const Moves& moves) {
  std::vector<PlaneId> plane_ids;
  for (const auto& [id, p] : map.planes()) plane_ids.push_back(id);
  for (PlaneId id : plane_ids) {
    const MapPlane& p = *map.plane(id);
    const auto m = landmark_motion(map, moves, p.first_keyframe, p.observations);
    std::vector<Eigen::Vector3d> hull = p.hull;
    if (m)
      for (auto& h : hull) h = (*m) * h;
    if (const auto it = correction.planes.find(id); it != correction.planes.end()) {
      map.set_plane(id, it->second);
    } else if (m) {
      // n . p + d = 0 and p' = R p + t: (R n) . p' + d - (R n) . t = 0.
      const Eigen::Vector3d n = m->rotation() * p.normal;
      map.set_plane(id, Eigen::Vector4d(n.x(), n.y(), n.z(), p.d - n.dot(m->translation())));
    }
    map.set_plane_hull(id, hull);
  }
}

}  // namespace

void apply_correction(Map& map, const MapCorrection& correction) {
  if (correction.after.empty()) return;
  map.count_correction();
  erase_outliers(map, correction);
  const Moves moves = keyframe_moves(map, correction);
  if (moves.empty()) return;
  for (const auto& [id, m] : moves) map.set_keyframe_pose(id, m.new_T_c_w);
  move_points(map, correction, moves);
  move_lines(map, correction, moves);
  move_planes(map, correction, moves);
  map.bump_version();
}

}  // namespace mcslam::map
