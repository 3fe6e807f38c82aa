#include "mcslam/mapping/floor.hpp"

#include <cmath>

namespace mcslam::mapping {

std::optional<FloorPlane> choose_floor(const OccupancyMap& map,
                                       const std::vector<FloorPlane>& candidates,
                                       double height_tolerance, double max_tilt_deg) {
  if (candidates.empty() || map.keyframes().empty()) return std::nullopt;
  const FloorPlane voxels = map.estimate_floor();
  const Eigen::Vector3d camera = map.keyframes().front().T_w_c.translation();
  const double min_cos = std::cos(max_tilt_deg * M_PI / 180.0);
  std::optional<FloorPlane> best;
  double best_gap = height_tolerance;
  for (FloorPlane c : candidates) {
    const double norm = c.normal.norm();
    if (!(norm > 0.5)) continue;
    c.normal /= norm;
    c.d /= norm;
    if (c.normal.dot(voxels.normal) < min_cos) continue;
    const double gap = std::abs(c.height(camera) - voxels.height(camera));
    if (gap <= best_gap) {
      best = c;
      best_gap = gap;
    }
  }
  return best;
}

}  // namespace mcslam::mapping
