#include "mcslam/mapping/grid_change.hpp"

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "mcslam/core/error.hpp"

namespace mcslam::mapping {
namespace {

namespace fs = std::filesystem;

/// The world point at the centre of cell (col, row), on the grid's floor.
Eigen::Vector3d cell_centre(const OccupancyGrid& g, int col, int row) {
  const Eigen::Vector4d p((col + 0.5) * g.resolution, (row + 0.5) * g.resolution, 0.0, 1.0);
  return (g.T_world_grid * p).head<3>();
}

bool occupied_near(const OccupancyGrid& g, int col, int row) {
  for (int dr = -1; dr <= 1; ++dr)
    for (int dc = -1; dc <= 1; ++dc) {
      const int c = col + dc, r = row + dr;
      if (c >= 0 && r >= 0 && c < g.width && r < g.height && g.at(c, r) == OccupancyGrid::kOccupied)
        return true;
    }
  return false;
}

/// Occupied cells of `a` whose place `b` saw, and those that `b` saw free with nothing occupied
/// next to it.
std::pair<std::size_t, std::size_t> occupied_against(const OccupancyGrid& a,
                                                     const OccupancyGrid& b) {
  std::size_t seen = 0, unexplained = 0;
  for (int row = 0; row < a.height; ++row)
    for (int col = 0; col < a.width; ++col) {
      if (a.at(col, row) != OccupancyGrid::kOccupied) continue;
      const auto cell = b.cell_of(cell_centre(a, col, row));
      if (!cell) continue;
      const std::int8_t there = b.at((*cell)[0], (*cell)[1]);
      if (there == OccupancyGrid::kUnknown) continue;
      ++seen;
      if (there == OccupancyGrid::kFree && !occupied_near(b, (*cell)[0], (*cell)[1])) ++unexplained;
    }
  return {seen, unexplained};
}

nlohmann::json read_json(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(file_error(path, "cannot read"));
  nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
  if (j.is_discarded()) throw InputError(file_error(path, "not JSON"));
  return j;
}

/// map_server's resolution from grid.yaml (the other keys are mcslam's own, fixed).
double read_resolution(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(file_error(path, "cannot read"));
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("resolution:", 0) != 0) continue;
    std::istringstream value(line.substr(11));
    double r = 0.0;
    if (value >> r && r > 0.0) return r;
    break;
  }
  throw InputError(file_error(path, "no positive 'resolution:'"));
}

}  // namespace

GridChange compare_grids(const OccupancyGrid& ref, const OccupancyGrid& full) {
  GridChange out;
  std::tie(out.full_occupied_seen, out.appeared) = occupied_against(full, ref);
  std::tie(out.ref_occupied_seen, out.vanished) = occupied_against(ref, full);
  out.appeared_rate = out.full_occupied_seen == 0
                          ? 0.0
                          : static_cast<double>(out.appeared) / out.full_occupied_seen;
  return out;
}

OccupancyGrid read_run_grid(const std::string& run_dir) {
  const fs::path dir(run_dir);
  const std::string summary_path = (dir / "summary.json").string();
  const nlohmann::json summary = read_json(summary_path);
  const nlohmann::json* T = nullptr;
  if (summary.contains("occupancy") && summary["occupancy"].contains("grid") &&
      summary["occupancy"]["grid"].contains("T_world_grid"))
    T = &summary["occupancy"]["grid"]["T_world_grid"];
  if (!T || !T->is_array() || T->size() != 4)
    throw InputError(file_error(summary_path,
                                "no occupancy.grid.T_world_grid (a run without "
                                "the occupancy map?)"));
  OccupancyGrid grid;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) {
      const nlohmann::json& v = (*T)[r][c];
      if (!v.is_number()) throw InputError(file_error(summary_path, "T_world_grid is not 4x4"));
      grid.T_world_grid(r, c) = v.get<double>();
    }
  grid.resolution = read_resolution((dir / "grid.yaml").string());
  const std::string pgm_path = (dir / "grid.pgm").string();
  const cv::Mat image = cv::imread(pgm_path, cv::IMREAD_UNCHANGED);
  if (image.empty() || image.type() != CV_8UC1)
    throw InputError(file_error(pgm_path, "not an 8-bit grey PGM"));
  grid.width = image.cols;
  grid.height = image.rows;
  grid.cells.resize(static_cast<std::size_t>(grid.width) * grid.height);
  for (int row = 0; row < grid.height; ++row) {
    const auto* in = image.ptr<std::uint8_t>(grid.height - 1 - row);  // top row: highest y
    for (int col = 0; col < grid.width; ++col)
      grid.cells[static_cast<std::size_t>(row) * grid.width + col] =
          in[col] == 0     ? OccupancyGrid::kOccupied
          : in[col] == 254 ? OccupancyGrid::kFree
                           : OccupancyGrid::kUnknown;
  }
  return grid;
}

}  // namespace mcslam::mapping
