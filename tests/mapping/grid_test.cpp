#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "mapping/box_world.hpp"
#include "mcslam/mapping/occupancy_map.hpp"
#include "support/test_camera.hpp"

namespace mcslam::mapping {
namespace {

using test::BoxWorld;
using test::look;
using test::WorldBox;

/// The room with a static chair, seen from 6 keyframes 2.4-3 m in front of the +x wall.
OccupancyMap chair_room(BoxWorld& world) {
  world.boxes.push_back({{4.0, 2.3, 0.012}, {4.45, 2.75, 0.9}, false, {30, 120, 30}});
  OccupancyMap map;
  const PinholeCamera cam = test::make_camera();
  for (int i = 0; i < 6; ++i)
    map.insert(world.render(i, look({2.5 + 0.1 * i, 2.0 + 0.2 * i, 1.2}, 0.1 - 0.04 * i), cam));
  return map;
}

std::int8_t cell_at(const OccupancyGrid& grid, const Eigen::Vector3d& p) {
  const auto cell = grid.cell_of(p);
  return cell ? grid.at((*cell)[0], (*cell)[1]) : OccupancyGrid::kUnknown;
}

TEST(OccupancyGrid, WallAndChairCellsOccupiedFloorInFrontFreeUnseenUnknown) {
  BoxWorld world;
  const OccupancyMap map = chair_room(world);
  const FloorPlane floor{Eigen::Vector3d::UnitZ(), -world.room_min.z()};
  const OccupancyGrid grid = map.grid(floor);
  ASSERT_GT(grid.width, 20);
  ASSERT_GT(grid.height, 20);
  EXPECT_FALSE(grid.floor_estimated);
  EXPECT_DOUBLE_EQ(grid.resolution, 0.05);
  EXPECT_EQ(grid.cells.size(), static_cast<std::size_t>(grid.width) * grid.height);
  // Floor frame: x, y along the world's (the floor is the world's z = 0.012), origin under the
  // world origin; the grid frame at the lower-left corner of cell (0, 0).
  EXPECT_TRUE((grid.T_world_floor.block<3, 3>(0, 0).isIdentity(1e-12)));
  EXPECT_NEAR(grid.T_world_floor(2, 3), world.room_min.z(), 1e-12);
  EXPECT_NEAR(grid.T_world_grid(0, 3), grid.origin.x(), 1e-12);
  EXPECT_NEAR(grid.T_world_grid(1, 3), grid.origin.y(), 1e-12);
  EXPECT_NEAR(std::fmod(std::abs(grid.origin.x()) + 1e-9, 0.05), 0.0, 1e-6);

  // The wall in view, at every height of the band.
  int wall = 0;
  for (double y = 1.8; y <= 3.2; y += 0.05)
    wall += cell_at(grid, {world.room_max.x() - 0.01, y, 1.0}) == OccupancyGrid::kOccupied;
  EXPECT_GE(wall, 28);
  EXPECT_EQ(cell_at(grid, {4.2, 2.5, 0.5}), OccupancyGrid::kOccupied);  // the chair
  // The floor in front of the chair and of the wall.
  for (double x = 3.6; x < 3.95; x += 0.05) EXPECT_EQ(cell_at(grid, {x, 2.5, 0.5}), 0) << x;
  for (double x = 5.0; x < 5.9; x += 0.05) EXPECT_EQ(cell_at(grid, {x, 3.0, 0.5}), 0) << x;
  // Behind the cameras: never seen.
  EXPECT_EQ(cell_at(grid, {1.0, 2.5, 0.5}), OccupancyGrid::kUnknown);
  // Cells by state.
  const std::size_t occupied = grid.count(OccupancyGrid::kOccupied);
  const std::size_t free = grid.count(OccupancyGrid::kFree);
  const std::size_t unknown = grid.count(OccupancyGrid::kUnknown);
  EXPECT_EQ(occupied + free + unknown, grid.cells.size());
  EXPECT_GT(free, 5 * occupied);
  std::printf("[ grid ] %d x %d cells: %zu occupied, %zu free, %zu unknown\n", grid.width,
              grid.height, occupied, free, unknown);
}

TEST(OccupancyGrid, HeightBandDecidesWhatIsAnObstacle) {
  BoxWorld world;
  const OccupancyMap base = chair_room(world);
  const FloorPlane floor{Eigen::Vector3d::UnitZ(), -world.room_min.z()};
  // A band above the chair (0.9 m): the chair is no obstacle, its cell is seen free above it.
  OccupancyOptions high;
  high.band_min = 1.0;
  high.band_max = 1.5;
  OccupancyMap map(high);
  for (const auto& kf : base.keyframes()) map.insert(kf);
  const OccupancyGrid grid = map.grid(floor);
  EXPECT_EQ(cell_at(grid, {4.2, 2.5, 0.5}), OccupancyGrid::kFree);
  EXPECT_EQ(cell_at(grid, {world.room_max.x() - 0.01, 2.5, 1.2}), OccupancyGrid::kOccupied);
}

TEST(OccupancyGrid, EstimatedFloorIsTheRoomsFloor) {
  BoxWorld world;
  const OccupancyMap map = chair_room(world);
  // The cameras are pitched 14 degrees down: their "up" is not the floor's normal, the fit is.
  const FloorPlane floor = map.estimate_floor();
  EXPECT_GT(floor.normal.z(), std::cos(1.0 * std::numbers::pi / 180.0)) << floor.normal.transpose();
  EXPECT_NEAR(-floor.d / floor.normal.z(), world.room_min.z(), 0.03);
  const OccupancyGrid estimated = map.grid();
  EXPECT_TRUE(estimated.floor_estimated);
  EXPECT_EQ(cell_at(estimated, {4.2, 2.5, 0.5}), OccupancyGrid::kOccupied);
  EXPECT_EQ(cell_at(estimated, {3.8, 2.5, 0.5}), OccupancyGrid::kFree);
  // Against the grid over the true floor: nearly the same cells.
  const OccupancyGrid truth = map.grid(FloorPlane{Eigen::Vector3d::UnitZ(), -world.room_min.z()});
  const double ratio = static_cast<double>(estimated.count(OccupancyGrid::kOccupied)) /
                       static_cast<double>(truth.count(OccupancyGrid::kOccupied));
  EXPECT_NEAR(ratio, 1.0, 0.1);
}

TEST(OccupancyGrid, EstimatedFloorInTheFirstCameraFrame) {
  // SLAM's world is the first keyframe's camera frame: the floor is tilted against the voxels'
  // axes (the camera is pitched down 14 degrees) and 1.2 m below the origin.
  BoxWorld world;
  world.boxes.push_back({{4.0, 2.3, 0.012}, {4.45, 2.75, 0.9}, false, {30, 120, 30}});
  const PinholeCamera cam = test::make_camera();
  const SE3 T_w_c0 = look({2.5, 2.0, 1.2}, 0.1);
  const SE3 T_c0_w = T_w_c0.inverse();
  OccupancyMap map;
  for (int i = 0; i < 6; ++i) {
    auto kf = world.render(i, look({2.5 + 0.1 * i, 2.0 + 0.2 * i, 1.2}, 0.1 - 0.04 * i), cam);
    kf.T_w_c = T_c0_w * kf.T_w_c;
    map.insert(kf);
  }
  const Eigen::Vector3d n_true = T_c0_w.rotation() * Eigen::Vector3d::UnitZ();
  const double d_true = T_w_c0.translation().z() - world.room_min.z();
  const FloorPlane floor = map.estimate_floor();
  EXPECT_GT(floor.normal.dot(n_true), std::cos(2.0 * std::numbers::pi / 180.0));
  EXPECT_NEAR(floor.d, d_true, 0.03);
  const OccupancyGrid grid = map.grid();
  EXPECT_EQ(cell_at(grid, T_c0_w * Eigen::Vector3d(4.2, 2.5, 0.5)), OccupancyGrid::kOccupied);
  EXPECT_EQ(cell_at(grid, T_c0_w * Eigen::Vector3d(3.7, 2.5, 0.5)), OccupancyGrid::kFree);
  EXPECT_EQ(cell_at(grid, T_c0_w * Eigen::Vector3d(world.room_max.x() - 0.01, 3.0, 1.0)),
            OccupancyGrid::kOccupied);
  std::printf("[ floor ] estimated in the first camera's frame: %.2f degrees off, %.1f mm\n",
              std::acos(std::min(1.0, floor.normal.dot(n_true))) * 180.0 / std::numbers::pi,
              1000.0 * (floor.d - d_true));
}

TEST(OccupancyGrid, EmptyMapGivesAnEmptyGrid) {
  OccupancyMap map;
  const OccupancyGrid grid = map.grid();
  EXPECT_EQ(grid.width, 0);
  EXPECT_EQ(grid.height, 0);
  EXPECT_TRUE(grid.cells.empty());
  EXPECT_FALSE(grid.cell_of({0.0, 0.0, 0.0}).has_value());
}

}  // namespace
}  // namespace mcslam::mapping
