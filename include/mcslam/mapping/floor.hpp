#pragma once
// Which plane the 2D grid stands on. The sparse map's planes measure the floor best (fitted to
// thousands of depth pixels, refined by bundle adjustment), but a desk top is a large horizontal
// plane too and may be the lowest one the sparse map has when the floor is seen only at a slant
// (Bonn crowd's first 240 frames: a desk 0.73 m below the camera against the floor at 1.41 m).
// The voxels tell them apart: the floor is the lowest large layer of occupied voxels.

#include <optional>
#include <vector>

#include "mcslam/mapping/occupancy_map.hpp"

namespace mcslam::mapping {

/// Of `candidates` (horizontal planes of the sparse map, normals up), the one within
/// `height_tolerance` metres (at the first keyframe's camera) and `max_tilt_deg` of the floor the
/// voxels show (OccupancyMap::estimate_floor); the closest when several do. nullopt when none
/// agrees or there is no keyframe yet: the grid then stands on the voxels' floor.
/// 0.15 m is three voxels at the default resolution (the voxel floor is good to about one; a
/// desk or a seat lies 0.4-0.8 m above the floor). 10 degrees: two fits of one floor differ by
/// far less; a plane tilted by more would move the band by over 0.5 m at 3 m from the camera.
std::optional<FloorPlane> choose_floor(const OccupancyMap& map,
                                       const std::vector<FloorPlane>& candidates,
                                       double height_tolerance = 0.15, double max_tilt_deg = 10.0);

}  // namespace mcslam::mapping
