#pragma once
// The dense map's files of `mcslam run` (docs/occupancy.md): occupancy.bt, grid.pgm and
// grid.yaml, grid.png, occupancy_voxels.ply, and summary.json's `occupancy`.

#include <filesystem>
#include <nlohmann/json.hpp>

#include "mcslam/mapping/worker.hpp"

namespace mcslam::app {

/// Writes the files into `out` (InputError naming a file that cannot be written) and returns
/// the summary: the grid's transforms from the world frame, cells and voxels by state, the
/// mapping thread's time per keyframe and its memory.
nlohmann::json write_occupancy_outputs(const mapping::MappingWorker& occupancy,
                                       const std::filesystem::path& out);

}  // namespace mcslam::app
