#include "mcslam/mapping/export.hpp"

#include <octomap/OcTree.h>

#include <bit>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "mcslam/core/error.hpp"

namespace mcslam::mapping {

namespace {

std::ofstream open_output(const std::string& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw InputError(file_error(path, "cannot write"));
  return out;
}

void finish_output(std::ofstream& out, const std::string& path) {
  out.flush();
  if (!out) throw InputError(file_error(path, "cannot write (write failed)"));
}

/// The grid as an 8-bit image, top row the grid's highest row, one pixel a cell.
cv::Mat grid_image(const OccupancyGrid& grid) {
  cv::Mat image(grid.height, grid.width, CV_8UC1);
  for (int row = 0; row < grid.height; ++row) {
    auto* out = image.ptr<std::uint8_t>(grid.height - 1 - row);
    for (int col = 0; col < grid.width; ++col) {
      const std::int8_t c = grid.at(col, row);
      out[col] = c == OccupancyGrid::kOccupied ? 0 : c == OccupancyGrid::kFree ? 254 : 205;
    }
  }
  return image;
}

std::string image_reference(const std::string& pgm_path, const std::string& yaml_path) {
  namespace fs = std::filesystem;
  const fs::path pgm = fs::absolute(pgm_path), yaml = fs::absolute(yaml_path);
  if (pgm.parent_path().lexically_normal() == yaml.parent_path().lexically_normal())
    return pgm.filename().string();
  return pgm.lexically_normal().string();
}

nlohmann::json matrix_rows(const Eigen::Matrix4d& T) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({T(r, 0), T(r, 1), T(r, 2), T(r, 3)});
  return rows;
}

}  // namespace

void write_octomap_binary(const OccupancyMap& map, const std::string& path) {
  // OcTree::writeBinaryConst's file format (its header, then the tree's data), written here
  // because the library's own writer reports its progress on stderr.
  const octomap::OcTree& tree = map.octree();
  std::ofstream out = open_output(path);
  out << "# Octomap OcTree binary file\n"
      << "# (feel free to add / change comments, but leave the first line as it is!)\n#\n"
      << "id " << tree.getTreeType() << "\n"
      << "size " << tree.size() << "\n"
      << "res " << tree.getResolution() << "\n"
      << "data\n";
  tree.writeBinaryData(out);
  finish_output(out, path);
}

void write_map_server(const OccupancyGrid& grid, const std::string& pgm_path,
                      const std::string& yaml_path) {
  std::ofstream pgm = open_output(pgm_path);
  pgm << "P5\n# mcslam occupancy grid, " << grid.resolution << " m/pixel\n"
      << grid.width << ' ' << grid.height << "\n255\n";
  const cv::Mat image = grid_image(grid);
  for (int r = 0; r < image.rows; ++r)
    pgm.write(reinterpret_cast<const char*>(image.ptr(r)), image.cols);
  finish_output(pgm, pgm_path);

  std::ofstream yaml = open_output(yaml_path);
  char origin[128];
  std::snprintf(origin, sizeof origin, "[%.6f, %.6f, 0.0]", grid.origin.x(), grid.origin.y());
  char resolution[64];
  std::snprintf(resolution, sizeof resolution, "%.6f", grid.resolution);
  yaml << "image: " << image_reference(pgm_path, yaml_path) << "\n"
       << "mode: trinary\n"
       << "resolution: " << resolution << "\n"
       << "origin: " << origin << "\n"
       << "negate: 0\n"
       << "occupied_thresh: 0.65\n"
       << "free_thresh: 0.196\n";
  finish_output(yaml, yaml_path);
}

void write_grid_png(const OccupancyGrid& grid, const std::string& path, int scale) {
  cv::Mat image = grid.width > 0 ? grid_image(grid) : cv::Mat(1, 1, CV_8UC1, cv::Scalar(205));
  cv::Mat big;
  cv::resize(image, big, {}, std::max(1, scale), std::max(1, scale), cv::INTER_NEAREST);
  bool written = false;
  try {
    written = cv::imwrite(path, big);
  } catch (const cv::Exception& e) {
    throw InputError(file_error(path, std::string("cannot write: ") + e.what()));
  }
  if (!written) throw InputError(file_error(path, "cannot write"));
}

void write_occupied_voxels_ply(const OccupancyMap& map, const std::string& path) {
  const auto voxels = map.occupied_voxels();
  std::ofstream out = open_output(path);
  out << "ply\nformat binary_little_endian 1.0\n"
      << "comment mcslam occupied voxel centres, resolution " << map.options().resolution << " m\n"
      << "element vertex " << voxels.size() << "\n"
      << "property float x\nproperty float y\nproperty float z\n"
      << "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
  static_assert(std::endian::native == std::endian::little, "the PLY is written little-endian");
  for (const auto& v : voxels) {
    const float xyz[3] = {static_cast<float>(v.centre.x()), static_cast<float>(v.centre.y()),
                          static_cast<float>(v.centre.z())};
    out.write(reinterpret_cast<const char*>(xyz), sizeof xyz);
    out.write(reinterpret_cast<const char*>(v.rgb.data()), 3);
  }
  finish_output(out, path);
}

nlohmann::json occupancy_summary(const OccupancyStats& stats, const OccupancyGrid& grid) {
  const auto& f = grid.floor;
  return {
      {"resolution", grid.resolution},
      {"grid",
       {{"width", grid.width},
        {"height", grid.height},
        {"origin", {grid.origin.x(), grid.origin.y()}},
        {"T_world_grid", matrix_rows(grid.T_world_grid)},
        {"T_world_floor", matrix_rows(grid.T_world_floor)},
        {"floor",
         {{"normal", {f.normal.x(), f.normal.y(), f.normal.z()}},
          {"d", f.d},
          {"estimated", grid.floor_estimated}}},
        {"cells",
         {{"occupied", grid.count(OccupancyGrid::kOccupied)},
          {"free", grid.count(OccupancyGrid::kFree)},
          {"unknown", grid.count(OccupancyGrid::kUnknown)}}}}},
      {"voxels", {{"occupied", stats.occupied_voxels}, {"free", stats.free_voxels}}},
      {"keyframes", stats.keyframes},
      // Keyframes and views integrated (a loaded session's, and in localisation the views that
      // are not stored): at least `keyframes`.
      {"integrated", stats.integration_ms.count},
      {"integration", stats.integration},
      {"time_per_keyframe_ms",
       {{"median", stats.integration_ms.median},
        {"p95", stats.integration_ms.p95},
        {"max", stats.integration_ms.max}}},
      {"rebuilds", stats.rebuilds},
      {"last_rebuild_ms", stats.last_rebuild_ms},
      {"memory_bytes",
       {{"octree", stats.octree_bytes},
        {"keyframes", stats.keyframe_bytes},
        {"colours", stats.colour_bytes},
        {"total", stats.total_bytes()},
        {"per_keyframe", stats.keyframe_bytes_each()}}},
  };
}

}  // namespace mcslam::mapping
