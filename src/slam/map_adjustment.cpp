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

/// Builds a MapAdjustment in steps: the local keyframes' poses, then their points, lines and
/// planes with every observation, each observer's pose added on first use (fixed unless local;
/// the map's first keyframe always fixed).
class AdjustmentBuilder {
 public:
  AdjustmentBuilder(const map::Map& map, const std::vector<map::KeyFrameId>& local,
                    MapAdjustment& a)
      : map_(map), local_(local), local_set_(local.begin(), local.end()), a_(a) {
    first_keyframe_ = map::kNoId;
    for (const auto& kv : map.keyframes()) first_keyframe_ = std::min(first_keyframe_, kv.first);
    for (map::KeyFrameId kf_id : local) add_pose(kf_id, false);
  }

  /// The points the local keyframes see, with every observation.
  void add_points(double depth_weight, optim::DepthTerm depth_term) {
    auto& problem = a_.problem;
    auto& point_ids = a_.point_ids;
    std::unordered_set<map::PointId> seen;
    for (map::KeyFrameId kf_id : local_) {
      for (map::PointId pid : map_.keyframe(kf_id)->landmarks) {
        if (pid == map::kNoId || seen.count(pid) != 0) continue;
        const map::MapPoint* mp = map_.point(pid);
        if (mp == nullptr) continue;
        seen.insert(pid);
        problem.points.push_back(mp->p_w);
        point_ids.push_back(pid);
      }
    }
    for (std::size_t k = 0; k < point_ids.size(); ++k) {
      const map::MapPoint* mp = map_.point(point_ids[k]);
      for (const auto& [kf_id, index] : mp->observations) {
        const map::KeyFrame* kf = map_.keyframe(kf_id);
        if (kf == nullptr) continue;
        optim::BundleAdjustmentProblem::Observation obs;
        obs.pose = add_observer(kf_id);
        obs.point = static_cast<int>(k);
        obs.measurement = measurement_of(kf->features->points[static_cast<std::size_t>(index)],
                                         *kf->features->pyramid, depth_weight, depth_term);
        problem.observations.push_back(obs);
        a_.observation_ids.emplace_back(kf_id, point_ids[k]);
      }
    }
  }

  /// The lines of the local keyframes, with every observation.
  void add_lines(const TrackerOptions& tracker) {
    auto& problem = a_.problem;
    auto& line_ids = a_.line_ids;
    std::unordered_set<map::LineId> seen;
    for (map::KeyFrameId kf_id : local_)
      for (map::LineId lid : map_.keyframe(kf_id)->line_landmarks)
        if (lid != map::kNoId && map_.line(lid) != nullptr && seen.insert(lid).second)
          line_ids.push_back(lid);
    for (std::size_t k = 0; k < line_ids.size(); ++k) {
      const map::MapLine* ml = map_.line(line_ids[k]);
      problem.lines.push_back({ml->start_w, ml->end_w});
      for (const auto& [kf_id, index] : ml->observations) {
        const map::KeyFrame* kf = map_.keyframe(kf_id);
        if (kf == nullptr) continue;
        optim::BundleAdjustmentProblem::LineObservation obs;
        obs.pose = add_observer(kf_id);
        obs.line = static_cast<int>(k);
        obs.measurement = line_measurement_of(kf->features->lines[static_cast<std::size_t>(index)],
                                              tracker.line_sigma);
        problem.line_observations.push_back(obs);
        a_.line_observation_ids.emplace_back(kf_id, line_ids[k]);
      }
    }
  }

  /// The planes the local keyframes see, with every observation.
  void add_planes(const TrackerOptions& tracker) {
    auto& problem = a_.problem;
    auto& plane_ids = a_.plane_ids;
    std::unordered_set<map::PlaneId> seen;
    for (map::KeyFrameId kf_id : local_)
      for (map::PlaneId pid : map_.keyframe(kf_id)->plane_landmarks)
        if (pid != map::kNoId && map_.plane(pid) != nullptr && seen.insert(pid).second)
          plane_ids.push_back(pid);
    for (std::size_t k = 0; k < plane_ids.size(); ++k) {
      const map::MapPlane* mp = map_.plane(plane_ids[k]);
      problem.planes.push_back(mp->coefficients());
      for (const auto& [kf_id, index] : mp->observations) {
        const map::KeyFrame* kf = map_.keyframe(kf_id);
        if (kf == nullptr) continue;
        optim::BundleAdjustmentProblem::PlaneObservation obs;
        obs.pose = add_observer(kf_id);
        obs.plane = static_cast<int>(k);
        obs.measurement =
            plane_measurement_of(kf->features->planes[static_cast<std::size_t>(index)],
                                 tracker.plane_angle_sigma_deg, tracker.plane_distance_sigma);
        problem.plane_observations.push_back(obs);
        a_.plane_observation_ids.emplace_back(kf_id, plane_ids[k]);
      }
    }
  }

 private:
  /// The index of the keyframe's pose, added (fixed as asked, or when it is the first keyframe)
  /// when it is new.
  int add_pose(map::KeyFrameId kf_id, bool fixed) {
    auto& problem = a_.problem;
    const auto [it, inserted] =
        a_.pose_index.emplace(kf_id, static_cast<int>(problem.poses.size()));
    if (inserted) {
      problem.poses.push_back(map_.keyframe(kf_id)->T_c_w);
      problem.pose_fixed.push_back(fixed || kf_id == first_keyframe_);
    }
    return it->second;
  }
  /// The pose index of an observing keyframe: fixed unless local.
  int add_observer(map::KeyFrameId kf_id) { return add_pose(kf_id, local_set_.count(kf_id) == 0); }

  const map::Map& map_;
  const std::vector<map::KeyFrameId>& local_;
  std::unordered_set<map::KeyFrameId> local_set_;
  MapAdjustment& a_;
  map::KeyFrameId first_keyframe_ = map::kNoId;
};

}  // namespace

MapAdjustment build_adjustment(const map::Map& map, const std::vector<map::KeyFrameId>& local,
                               const MapperOptions& mapper, const TrackerOptions& tracker) {
  MapAdjustment a;
  AdjustmentBuilder builder(map, local, a);
  builder.add_points(mapper.depth_weight, mapper.disparity_residual ? optim::DepthTerm::kDisparity
                                                                    : optim::DepthTerm::kRightU);
  builder.add_lines(tracker);
  builder.add_planes(tracker);
  a.lines_before = a.problem.lines;
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
