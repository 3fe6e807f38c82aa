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
  // Map::erase_observation recomputes the descriptor of a point that loses an observation.
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
    map.update_point_geometry(a.point_ids[k]);  // the descriptor does not depend on it
  }
  for (std::size_t k = 0; k < a.line_ids.size(); ++k)
    if (const auto ends = onto_line(a.problem.lines[k], a.lines_before[k]))
      map.set_line_endpoints(a.line_ids[k], ends->first, ends->second);
  for (std::size_t k = 0; k < a.plane_ids.size(); ++k)
    map.set_plane(a.plane_ids[k], a.problem.planes[k]);
  for (const auto& kv : a.pose_index) map.update_covisibility(kv.first);
}

map::MapCorrection correction_of(const MapAdjustment& solved,
                                 const optim::BundleAdjustmentResult& result,
                                 const std::vector<SE3>& poses_before,
                                 const std::vector<Eigen::Vector3d>& points_before) {
  map::MapCorrection c;
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
  for (std::size_t k = 0; k < solved.point_ids.size(); ++k) {
    c.points.emplace(solved.point_ids[k], solved.problem.points[k]);
    c.points_before.emplace(solved.point_ids[k], points_before[k]);
  }
  for (std::size_t k = 0; k < solved.line_ids.size(); ++k)
    if (const auto ends = onto_line(solved.problem.lines[k], solved.lines_before[k]))
      c.lines.emplace(solved.line_ids[k], *ends);
  for (std::size_t k = 0; k < solved.plane_ids.size(); ++k)
    c.planes.emplace(solved.plane_ids[k], solved.problem.planes[k]);
  return c;
}

}  // namespace mcslam::slam
