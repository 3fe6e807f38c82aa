#include "map_adjustment.hpp"

#include <algorithm>
#include <optional>
#include <unordered_set>

#include "measurement.hpp"

namespace mcslam::slam {
namespace {

/// Residual (7) fixes the infinite line, not where the endpoints sit along it (they drift): the
/// segment keeps its extent, moved onto the optimised line.
std::optional<std::pair<Eigen::Vector3d, Eigen::Vector3d>> onto_line(
    const optim::BundleAdjustmentProblem::Line& optimised,
    const optim::BundleAdjustmentProblem::Line& before) {
  const Eigen::Vector3d& s = optimised.start;
  const Eigen::Vector3d& e = optimised.end;
  if (!((e - s).norm() > 1e-9)) return std::nullopt;
  const Eigen::Vector3d dir = (e - s).normalized();
  const auto onto = [&](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return s + dir * dir.dot(p - s);
  };
  return std::make_pair(onto(before.start), onto(before.end));
}

}  // namespace

MapAdjustment build_adjustment(const map::Map& map, const std::vector<map::KeyFrameId>& local,
                               double depth_weight, const TrackerOptions& tracker) {
  std::unordered_set<map::KeyFrameId> local_set(local.begin(), local.end());

  MapAdjustment a;
  auto& problem = a.problem;
  auto& pose_index = a.pose_index;
  auto& point_ids = a.point_ids;
  auto& observation_ids = a.observation_ids;
  std::unordered_map<map::PointId, int> point_index;
  const map::KeyFrameId first_keyframe = [&] {
    map::KeyFrameId first = map::kNoId;
    for (const auto& kv : map.keyframes()) first = std::min(first, kv.first);
    return first;
  }();
  const auto add_pose = [&](map::KeyFrameId kf_id, bool fixed) {
    const auto [it, inserted] = pose_index.emplace(kf_id, static_cast<int>(problem.poses.size()));
    if (inserted) {
      problem.poses.push_back(map.keyframe(kf_id)->T_c_w);
      problem.pose_fixed.push_back(fixed || kf_id == first_keyframe);
    }
    return it->second;
  };
  for (map::KeyFrameId kf_id : local) add_pose(kf_id, false);
  for (map::KeyFrameId kf_id : local) {
    for (map::PointId pid : map.keyframe(kf_id)->landmarks) {
      if (pid == map::kNoId || point_index.count(pid) != 0) continue;
      const map::MapPoint* mp = map.point(pid);
      if (mp == nullptr) continue;
      point_index.emplace(pid, static_cast<int>(problem.points.size()));
      problem.points.push_back(mp->p_w);
      point_ids.push_back(pid);
    }
  }
  for (std::size_t k = 0; k < point_ids.size(); ++k) {
    const map::MapPoint* mp = map.point(point_ids[k]);
    for (const auto& [kf_id, index] : mp->observations) {
      const map::KeyFrame* kf = map.keyframe(kf_id);
      if (kf == nullptr) continue;
      optim::BundleAdjustmentProblem::Observation obs;
      obs.pose = add_pose(kf_id, local_set.count(kf_id) == 0);
      obs.point = static_cast<int>(k);
      obs.measurement = measurement_of(kf->features->points[static_cast<std::size_t>(index)],
                                       *kf->features->pyramid, depth_weight);
      problem.observations.push_back(obs);
      observation_ids.emplace_back(kf_id, point_ids[k]);
    }
  }
  // Lines of the local keyframes, with every observation.
  auto& line_ids = a.line_ids;
  auto& line_observation_ids = a.line_observation_ids;
  {
    std::unordered_set<map::LineId> seen;
    for (map::KeyFrameId kf_id : local)
      for (map::LineId lid : map.keyframe(kf_id)->line_landmarks)
        if (lid != map::kNoId && map.line(lid) != nullptr && seen.insert(lid).second)
          line_ids.push_back(lid);
  }
  for (std::size_t k = 0; k < line_ids.size(); ++k) {
    const map::MapLine* ml = map.line(line_ids[k]);
    problem.lines.push_back({ml->start_w, ml->end_w});
    for (const auto& [kf_id, index] : ml->observations) {
      const map::KeyFrame* kf = map.keyframe(kf_id);
      if (kf == nullptr) continue;
      optim::BundleAdjustmentProblem::LineObservation obs;
      obs.pose = add_pose(kf_id, local_set.count(kf_id) == 0);
      obs.line = static_cast<int>(k);
      obs.measurement = line_measurement_of(kf->features->lines[static_cast<std::size_t>(index)],
                                            tracker.line_sigma);
      problem.line_observations.push_back(obs);
      line_observation_ids.emplace_back(kf_id, line_ids[k]);
    }
  }
  // Planes seen by the local keyframes, with every observation (other keyframes fixed).
  auto& plane_ids = a.plane_ids;
  auto& plane_observation_ids = a.plane_observation_ids;
  {
    std::unordered_set<map::PlaneId> seen;
    for (map::KeyFrameId kf_id : local)
      for (map::PlaneId pid : map.keyframe(kf_id)->plane_landmarks)
        if (pid != map::kNoId && map.plane(pid) != nullptr && seen.insert(pid).second)
          plane_ids.push_back(pid);
  }
  for (std::size_t k = 0; k < plane_ids.size(); ++k) {
    const map::MapPlane* mp = map.plane(plane_ids[k]);
    problem.planes.push_back(mp->coefficients());
    for (const auto& [kf_id, index] : mp->observations) {
      const map::KeyFrame* kf = map.keyframe(kf_id);
      if (kf == nullptr) continue;
      optim::BundleAdjustmentProblem::PlaneObservation obs;
      obs.pose = add_pose(kf_id, local_set.count(kf_id) == 0);
      obs.plane = static_cast<int>(k);
      obs.measurement =
          plane_measurement_of(kf->features->planes[static_cast<std::size_t>(index)],
                               tracker.plane_angle_sigma_deg, tracker.plane_distance_sigma);
      problem.plane_observations.push_back(obs);
      plane_observation_ids.emplace_back(kf_id, plane_ids[k]);
    }
  }
  a.lines_before = problem.lines;
  return a;
}

void apply_adjustment(map::Map& map, const MapAdjustment& a,
                      const optim::BundleAdjustmentResult& result) {
  for (std::size_t k = 0; k < a.observation_ids.size(); ++k)
    if (!result.inlier[k])
      map.erase_observation(a.observation_ids[k].second, a.observation_ids[k].first);
  for (std::size_t k = 0; k < a.line_observation_ids.size(); ++k)
    if (!result.line_inlier[k])
      map.erase_line_observation(a.line_observation_ids[k].second, a.line_observation_ids[k].first);
  for (std::size_t k = 0; k < a.plane_observation_ids.size(); ++k)
    if (!result.plane_inlier[k])
      map.erase_plane_observation(a.plane_observation_ids[k].second,
                                  a.plane_observation_ids[k].first);
  for (const auto& [kf_id, index] : a.pose_index)
    if (!a.problem.pose_fixed[static_cast<std::size_t>(index)])
      map.set_keyframe_pose(kf_id, a.problem.poses[static_cast<std::size_t>(index)]);
  for (std::size_t k = 0; k < a.point_ids.size(); ++k) {
    if (map.point(a.point_ids[k]) == nullptr) continue;
    map.set_point_position(a.point_ids[k], a.problem.points[k]);
    map.update_point_appearance(a.point_ids[k]);
  }
  for (std::size_t k = 0; k < a.line_ids.size(); ++k)
    if (const auto ends = onto_line(a.problem.lines[k], a.lines_before[k]))
      map.set_line_endpoints(a.line_ids[k], ends->first, ends->second);
  for (std::size_t k = 0; k < a.plane_ids.size(); ++k)
    map.set_plane(a.plane_ids[k], a.problem.planes[k]);
  for (const auto& kv : a.pose_index) map.update_covisibility(kv.first);
}

MapCorrection correction_of(const MapAdjustment& solved,
                            const optim::BundleAdjustmentResult& result,
                            const std::vector<SE3>& poses_before) {
  MapCorrection c;
  for (std::size_t k = 0; k < solved.observation_ids.size(); ++k)
    if (!result.inlier[k]) c.point_outliers.push_back(solved.observation_ids[k]);
  for (std::size_t k = 0; k < solved.line_observation_ids.size(); ++k)
    if (!result.line_inlier[k]) c.line_outliers.push_back(solved.line_observation_ids[k]);
  for (std::size_t k = 0; k < solved.plane_observation_ids.size(); ++k)
    if (!result.plane_inlier[k]) c.plane_outliers.push_back(solved.plane_observation_ids[k]);
  for (const auto& [kf_id, index] : solved.pose_index) {
    const auto k = static_cast<std::size_t>(index);
    c.before.emplace(kf_id, poses_before[k]);
    c.after.emplace(kf_id, solved.problem.poses[k]);
  }
  for (std::size_t k = 0; k < solved.point_ids.size(); ++k)
    c.points.emplace(solved.point_ids[k], solved.problem.points[k]);
  for (std::size_t k = 0; k < solved.line_ids.size(); ++k)
    if (const auto ends = onto_line(solved.problem.lines[k], solved.lines_before[k]))
      c.lines.emplace(solved.line_ids[k], *ends);
  for (std::size_t k = 0; k < solved.plane_ids.size(); ++k)
    c.planes.emplace(solved.plane_ids[k], solved.problem.planes[k]);
  return c;
}

void apply_correction(map::Map& map, const MapCorrection& correction) {
  if (correction.after.empty()) return;
  for (const auto& [kf, point] : correction.point_outliers)
    if (map.point(point) != nullptr) map.erase_observation(point, kf);
  for (const auto& [kf, line] : correction.line_outliers)
    if (map.line(line) != nullptr) map.erase_line_observation(line, kf);
  for (const auto& [kf, plane] : correction.plane_outliers)
    if (map.plane(plane) != nullptr) map.erase_plane_observation(plane, kf);
  // Old and new pose of every keyframe.
  struct Move {
    SE3 old_T_c_w;
    SE3 new_T_c_w;
  };
  std::unordered_map<map::KeyFrameId, Move> moves;
  std::vector<map::KeyFrameId> corrected;
  for (const auto& [id, T] : correction.after)
    if (map.keyframe(id) != nullptr) corrected.push_back(id);
  std::sort(corrected.begin(), corrected.end());
  if (corrected.empty()) return;
  const auto old_pose = [&](map::KeyFrameId id) {
    const auto it = correction.before.find(id);
    return it != correction.before.end() ? it->second : map.keyframe(id)->T_c_w;
  };
  for (map::KeyFrameId id : corrected) moves[id] = {old_pose(id), correction.after.at(id)};
  for (const auto& [id, kf] : map.keyframes()) {
    if (moves.count(id) != 0) continue;
    // The keyframe it hangs on: its strongest covisible corrected keyframe, else the closest
    // earlier corrected one (else the first).
    map::KeyFrameId ref = map::kNoId;
    for (map::KeyFrameId other : map.best_covisible(id, kf.covisibility.size()))
      if (correction.after.count(other) != 0 && map.keyframe(other) != nullptr) {
        ref = other;
        break;
      }
    if (ref == map::kNoId) {
      auto it = std::upper_bound(corrected.begin(), corrected.end(), id);
      ref = it == corrected.begin() ? corrected.front() : *(it - 1);
    }
    const Move& r = moves.at(ref);
    moves[id] = {kf.T_c_w, kf.T_c_w * r.old_T_c_w.inverse() * r.new_T_c_w};
  }
  for (const auto& [id, m] : moves) map.set_keyframe_pose(id, m.new_T_c_w);

  // World-to-world motion of what hangs on keyframe `id`: p' = T_new^-1 T_old p.
  const auto motion_of = [&](map::KeyFrameId id) -> std::optional<SE3> {
    const auto it = moves.find(id);
    if (it == moves.end()) return std::nullopt;
    return it->second.new_T_c_w.inverse() * it->second.old_T_c_w;
  };
  const auto reference_motion = [&](map::KeyFrameId first, const auto& observations) {
    if (auto m = motion_of(first)) return m;
    for (const auto& obs : observations)
      if (auto m = motion_of(obs.first)) return m;
    return std::optional<SE3>();
  };
  std::vector<map::PointId> point_ids;
  for (const auto& [id, p] : map.points()) point_ids.push_back(id);
  for (map::PointId id : point_ids) {
    const map::MapPoint& p = *map.point(id);
    if (const auto it = correction.points.find(id); it != correction.points.end()) {
      map.set_point_position(id, it->second);
    } else if (const auto m = reference_motion(p.first_keyframe, p.observations)) {
      map.set_point_position(id, (*m) * p.p_w);
    }
    map.update_point_appearance(id);
  }
  std::vector<map::LineId> line_ids;
  for (const auto& [id, l] : map.lines()) line_ids.push_back(id);
  for (map::LineId id : line_ids) {
    const map::MapLine& l = *map.line(id);
    if (const auto it = correction.lines.find(id); it != correction.lines.end()) {
      map.set_line_endpoints(id, it->second.first, it->second.second);
    } else if (const auto m = reference_motion(l.first_keyframe, l.observations)) {
      map.set_line_endpoints(id, (*m) * l.start_w, (*m) * l.end_w);
    }
  }
  std::vector<map::PlaneId> plane_ids;
  for (const auto& [id, p] : map.planes()) plane_ids.push_back(id);
  for (map::PlaneId id : plane_ids) {
    const map::MapPlane& p = *map.plane(id);
    const auto m = reference_motion(p.first_keyframe, p.observations);
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
  map.bump_version();
}

}  // namespace mcslam::slam
