#pragma once
// The dense map of a run on a synthetic sequence (`mcslam synth`) scored against the scene's
// exact static geometry (its objects.json): summary.json `occupancy.quality`.

#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mcslam/core/se3.hpp"
#include "mcslam/mapping/occupancy_map.hpp"

namespace mcslam::app {

/// What objects.json of `mcslam synth` says of the scene over a run's frames (world frame of
/// the ground truth).
struct SyntheticScene {
  Eigen::Vector3d room_min = Eigen::Vector3d::Zero();
  Eigen::Vector3d room_max = Eigen::Vector3d::Zero();
  struct Object {
    std::string class_name;
    std::string motion;  ///< "static", "free" (people) or "slide" (a pushed chair)
    Eigen::Vector3d half_size = Eigen::Vector3d::Zero();
    SE3 first;  ///< pose at the run's first frame
    SE3 last;   ///< pose at the run's last frame
  };
  std::vector<Object> objects;
};

/// Reads `path` (objects.json of mcslam synth, with its "room"), taking each object's pose at
/// the frames nearest to t_first and t_last. nullopt when the file is absent or of another
/// format; InputError naming the file when it is that format but unreadable or inconsistent.
std::optional<SyntheticScene> read_synthetic_scene(const std::filesystem::path& path,
                                                   double t_first, double t_last);

/// The map scored against the scene: the static surfaces are the room's six planes, the static
/// objects, and every sliding object where it stands at the end (a pushed chair is an obstacle
/// where it is now). T_est_gt maps ground-truth world points into the run's world frame (the
/// inverse of the ATE alignment). Returns
///   ghost_rate, ghosts, occupied (mapping::evaluate_map: occupied voxels farther than a voxel
///     from every static surface), completeness, surface_seen, surface_occupied;
///   movers: per sliding object, its first place (voxel centres inside its first box, above the
///     floor's voxel and away from its final box by a voxel: occupied, free, unknown; all free
///     or unknown means the map forgot it) and its final place (the share of its final box's
///     surface voxels seen from 3 keyframes that are occupied).
nlohmann::json evaluate_synthetic_map(const mapping::OccupancyMap& map, const SyntheticScene& scene,
                                      const SE3& T_est_gt);

}  // namespace mcslam::app
