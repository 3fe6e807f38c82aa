#pragma once
// Bundle adjustment of a set of keyframes as data copied out of the map (so that the solver runs
// without the map's lock) and the way back into the map; and map corrections (loop closing):
// new poses for some keyframes, with everything else following the keyframe it hangs on.
// Internal to the slam module.

#include <unordered_map>
#include <utility>
#include <vector>

#include "mcslam/core/se3.hpp"
#include "mcslam/map/correction.hpp"
#include "mcslam/map/map.hpp"
#include "mcslam/optim/bundle_adjustment.hpp"
#include "mcslam/slam/options.hpp"

namespace mcslam::slam {

struct MapAdjustment {
  optim::BundleAdjustmentProblem problem;
  std::unordered_map<map::KeyFrameId, int> pose_index;
  std::vector<map::PointId> point_ids;  // problem.points[k] is point_ids[k]
  std::vector<std::pair<map::KeyFrameId, map::PointId>> observation_ids;
  std::vector<map::LineId> line_ids;
  std::vector<std::pair<map::KeyFrameId, map::LineId>> line_observation_ids;
  std::vector<map::PlaneId> plane_ids;
  std::vector<std::pair<map::KeyFrameId, map::PlaneId>> plane_observation_ids;
  std::vector<optim::BundleAdjustmentProblem::Line> lines_before;

  bool empty() const {
    return problem.observations.empty() && problem.line_observations.empty() &&
           problem.plane_observations.empty();
  }
};

/// The keyframes `local` (optimised), every landmark they see, and the other keyframes that see
/// those (fixed); the map's first keyframe is always fixed. The points' depth residual and its
/// weight come from `mapper`, the lines' and planes' sigmas from `tracker`. Call under the map's
/// read lock (or from its writer).
MapAdjustment build_adjustment(const map::Map& map, const std::vector<map::KeyFrameId>& local,
                               const MapperOptions& mapper, const TrackerOptions& tracker);

/// Writes an adjustment's result back: outlier observations erased, poses and landmarks set,
/// covisibility updated. Call under the map's write lock.
void apply_adjustment(map::Map& map, const MapAdjustment& a,
                      const optim::BundleAdjustmentResult& result);

/// The correction that an adjustment's solved problem makes (poses and points before: as
/// built, so that what the map refined meanwhile keeps its refinement; see MapCorrection).
map::MapCorrection correction_of(const MapAdjustment& solved,
                                 const optim::BundleAdjustmentResult& result,
                                 const std::vector<SE3>& poses_before,
                                 const std::vector<Eigen::Vector3d>& points_before);

}  // namespace mcslam::slam
