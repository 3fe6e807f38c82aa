#pragma once
// The occupancy map as files other tools open. Each throws InputError naming the file when it
// cannot be written.

#include <nlohmann/json.hpp>
#include <string>

#include "mcslam/mapping/occupancy_map.hpp"

namespace mcslam::mapping {

/// OctoMap's binary format (occupancy.bt): the maximum-likelihood tree (each node occupied or
/// free), which octovis opens and octomap_server loads. The map itself is not changed.
void write_octomap_binary(const OccupancyMap& map, const std::string& path);

/// The ROS map_server / nav2 map: a PGM (P5, 8 bit; 0 occupied, 254 free, 205 unknown; the top
/// image row is the grid's highest row) and its YAML: image (the PGM's file name when both are
/// in one folder, else its absolute path), mode trinary, resolution, origin [x, y, yaw] (the
/// lower-left pixel's corner in the grid's floor frame, OccupancyGrid::origin, yaw 0), negate 0,
/// occupied_thresh 0.65 and free_thresh 0.196.
///
/// map_server reads a pixel x as p = (255 - x) / 255 and in trinary mode takes p >
/// occupied_thresh as occupied, p < free_thresh as free and anything else as unknown: 0 -> 1.0
/// occupied, 254 -> 0.004 free, 205 -> 0.196 (50/255 = 0.19608) unknown only because
/// free_thresh is 0.196, the value ROS 1's map_saver writes. nav2's map_saver wrote 0.25, which
/// reads 205 back as free (slam_toolbox #587; fixed to 0.196 by navigation2 #5278).
void write_map_server(const OccupancyGrid& grid, const std::string& pgm_path,
                      const std::string& yaml_path);

/// A picture of the grid (PNG, or what the extension names): free white, occupied black,
/// unknown grey, each cell `scale` pixels a side, the grid's highest row at the top.
void write_grid_png(const OccupancyGrid& grid, const std::string& path, int scale = 4);

/// The occupied voxel centres as a binary little-endian PLY: x, y, z (float) and red, green,
/// blue (uchar; the mean colour of the measurements that hit the voxel, grey when none had a
/// colour).
void write_occupied_voxels_ply(const OccupancyMap& map, const std::string& path);

/// The map in figures, for summary.json's "occupancy": resolution, the grid (width, height,
/// origin, T_world_grid and T_world_floor as 4x4 row lists, the floor and whether it was
/// estimated, cells by state), voxels by state, keyframes, the time per keyframe (median, p95,
/// max, ms), rebuilds and memory (bytes: octree, keyframes, colours, total, per keyframe).
nlohmann::json occupancy_summary(const OccupancyStats& stats, const OccupancyGrid& grid);

}  // namespace mcslam::mapping
