#include "occupancy_outputs.hpp"

#include "mcslam/mapping/export.hpp"

namespace mcslam::app {

nlohmann::json write_occupancy_outputs(const mapping::MappingWorker& occupancy,
                                       const std::filesystem::path& out) {
  const std::shared_ptr<const mapping::OccupancySnapshot> snapshot = occupancy.snapshot();
  occupancy.with_map([&](const mapping::OccupancyMap& map) {
    mapping::write_octomap_binary(map, (out / "occupancy.bt").string());
    mapping::write_occupied_voxels_ply(map, (out / "occupancy_voxels.ply").string());
  });
  mapping::write_map_server(snapshot->grid, (out / "grid.pgm").string(),
                            (out / "grid.yaml").string());
  mapping::write_grid_png(snapshot->grid, (out / "grid.png").string());
  nlohmann::json j = mapping::occupancy_summary(snapshot->stats, snapshot->grid);
  j["files"] = {"occupancy.bt", "grid.pgm", "grid.yaml", "grid.png", "occupancy_voxels.ply"};
  return j;
}

}  // namespace mcslam::app
