#pragma once
// How a 2D grid changed between two runs of one sequence (mcslam grid-compare): a run of the
// part without people (REF) against the whole (FULL). A cell that FULL holds occupied where REF
// saw the floor free, with no occupied REF cell next to it, is an obstacle that was not there:
// a person left in the map, or a wall moved by a wrong pose.

#include <cstddef>
#include <string>

#include "mcslam/mapping/occupancy_map.hpp"

namespace mcslam::mapping {

struct GridChange {
  /// FULL's occupied cells whose place REF saw (its cell there is free or occupied).
  std::size_t full_occupied_seen = 0;
  /// Of those, the ones REF saw free with no occupied REF cell within one cell.
  std::size_t appeared = 0;
  /// appeared / full_occupied_seen (0 when none).
  double appeared_rate = 0.0;
  /// REF's occupied cells whose place FULL saw, and the ones FULL holds free with no occupied
  /// FULL cell within one cell (what the longer run cleared: a moved object, or a lost wall).
  std::size_t ref_occupied_seen = 0;
  std::size_t vanished = 0;
};

/// Compares the grids through the world frame: each FULL cell's centre, on FULL's floor, is
/// looked up in REF's grid (projected along REF's floor normal), and the other way round.
GridChange compare_grids(const OccupancyGrid& ref, const OccupancyGrid& full);

/// A grid as `mcslam run` wrote it into `run_dir`: grid.pgm and grid.yaml (map_server's format)
/// and summary.json's occupancy.grid.T_world_grid. InputError naming the file that is missing
/// or broken.
OccupancyGrid read_run_grid(const std::string& run_dir);

}  // namespace mcslam::mapping
