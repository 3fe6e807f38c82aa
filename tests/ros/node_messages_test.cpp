// The ROS node's messages without ROS (src/ros/node_messages.hpp): the grid means what grid.pgm
// and grid.yaml mean, the markers follow the objects, map -> odom composes to the SLAM pose, and
// NodeOptions::check() rejects bad frame names.

#include "ros/node_messages.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <random>
#include <sstream>

#include "mapping/box_world.hpp"
#include "mcslam/mapping/export.hpp"
#include "mcslam/ros/node_options.hpp"
#include "mcslam/slam/objects.hpp"
#include "support/random_geometry.hpp"
#include "support/temp_dir.hpp"
#include "support/test_camera.hpp"

namespace mcslam::ros::detail {
namespace {

/// The box world's room and a box, mapped in a world frame that is not the room's: the SLAM
/// world is where the first camera was, never aligned with the floor.
struct TiltedWorld {
  SE3 G;  // p_slam_world = G * p_room
  test::BoxWorld room;
  mapping::FloorPlane floor;  // the room's floor in the SLAM world
  mapping::OccupancyGrid grid;
  Eigen::Vector3d box_centre;  // in the SLAM world

  TiltedWorld() {
    G = SE3(
        Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(1.0, -0.5, 0.3).normalized())),
        Eigen::Vector3d(0.3, -0.7, 1.1));
    room.boxes.push_back({{4.0, 2.3, 0.012}, {4.45, 2.75, 0.9}, false, {30, 120, 30}});
    mapping::OccupancyMap map;
    const PinholeCamera cam = test::make_camera();
    for (int i = 0; i < 3; ++i) {
      // Rendered in the room frame, mapped in the SLAM world.
      mapping::KeyframeDepth kf =
          room.render(i, test::look({2.6 + 0.1 * i, 2.3 + 0.2 * i, 1.2}, 0.05 * i), cam);
      kf.T_w_c = G * kf.T_w_c;
      map.insert(kf);
    }
    floor.normal = G.rotation() * Eigen::Vector3d::UnitZ();
    floor.d = -room.room_min.z() - floor.normal.dot(G.translation());
    grid = map.grid(floor);
    box_centre = G * Eigen::Vector3d(4.225, 2.525, 0.5);
  }
};

const TiltedWorld& tilted_world() {
  static const TiltedWorld world;
  return world;
}

/// Where a ROS consumer puts a cell's centre: info.origin in the floor frame, then tf map ->
/// floor.
Eigen::Vector3d cell_centre_in_map(const GridMessage& m, int col, int row) {
  const Eigen::Vector3d p_floor(m.origin.x() + (col + 0.5) * m.resolution,
                                m.origin.y() + (row + 0.5) * m.resolution, 0.0);
  return m.T_map_floor * p_floor;
}

TEST(RosNodeMessages, GridMessageIsTheGridInTheFloorFrame) {
  const TiltedWorld& w = tilted_world();
  const GridMessage m = grid_message(w.grid);
  ASSERT_GT(m.width, 0);
  ASSERT_GT(m.height, 0);
  EXPECT_EQ(m.width, w.grid.width);
  EXPECT_EQ(m.height, w.grid.height);
  EXPECT_DOUBLE_EQ(m.resolution, 0.05);
  EXPECT_EQ(m.cells, w.grid.cells);
  EXPECT_TRUE(m.T_map_floor.matrix().isApprox(w.grid.T_world_floor, 1e-12));
  // The floor frame's z is the floor's normal (up) and its xy plane lies on the floor.
  EXPECT_NEAR(m.T_map_floor.rotation().col(2).dot(w.floor.normal), 1.0, 1e-9);
  EXPECT_NEAR(w.floor.height(m.T_map_floor.translation()), 0.0, 1e-9);
  // Every cell's centre, placed as a consumer of the message places it, is that cell of the
  // grid (row 0 the lowest y, origin the corner of cell (0, 0)) and lies on the floor.
  std::size_t wrong = 0;
  for (int row = 0; row < m.height; ++row)
    for (int col = 0; col < m.width; ++col) {
      const Eigen::Vector3d p = cell_centre_in_map(m, col, row);
      const auto cell = w.grid.cell_of(p);
      if (!cell || (*cell)[0] != col || (*cell)[1] != row) ++wrong;
      if (std::abs(w.floor.height(p)) > 1e-9) ++wrong;
    }
  EXPECT_EQ(wrong, 0u);
  // The box stands where the message says an obstacle is.
  const Eigen::Vector3d b = m.T_map_floor.inverse() * w.box_centre;
  const int col = static_cast<int>(std::floor((b.x() - m.origin.x()) / m.resolution));
  const int row = static_cast<int>(std::floor((b.y() - m.origin.y()) / m.resolution));
  ASSERT_TRUE(col >= 0 && col < m.width && row >= 0 && row < m.height);
  EXPECT_EQ(m.cells[static_cast<std::size_t>(row) * m.width + col], 100);
  EXPECT_GT(w.grid.count(mapping::OccupancyGrid::kFree), 0u);
}

TEST(RosNodeMessages, GridMessageHasTheCellsAndOriginOfGridPgmAndYaml) {
  const TiltedWorld& w = tilted_world();
  const GridMessage m = grid_message(w.grid);
  test::TempDir dir("mcslam_ros_grid");
  mapping::write_map_server(w.grid, dir.file("grid.pgm"), dir.file("grid.yaml"));
  std::ifstream yaml(dir.file("grid.yaml"));
  std::string line, origin;
  while (std::getline(yaml, line))
    if (line.rfind("origin: ", 0) == 0) origin = line;
  char expected[128];
  std::snprintf(expected, sizeof expected, "origin: [%.6f, %.6f, 0.0]", m.origin.x(), m.origin.y());
  EXPECT_EQ(origin, expected);
  // The PGM's top row is the message's last row; 0 occupied, 254 free, 205 unknown.
  std::ifstream pgm(dir.file("grid.pgm"), std::ios::binary);
  std::string magic, comment;
  int width = 0, height = 0, maxval = 0;
  std::getline(pgm, magic);
  std::getline(pgm, comment);
  pgm >> width >> height >> maxval;
  pgm.get();
  ASSERT_EQ(width, m.width);
  ASSERT_EQ(height, m.height);
  std::size_t mismatches = 0;
  for (int r = 0; r < height; ++r)
    for (int c = 0; c < width; ++c) {
      const int x = pgm.get();
      const std::int8_t cell = m.cells[static_cast<std::size_t>(height - 1 - r) * width + c];
      const int expected_x = cell == 100 ? 0 : cell == 0 ? 254 : 205;
      if (x != expected_x) ++mismatches;
    }
  EXPECT_EQ(mismatches, 0u);
}

TEST(RosNodeMessages, VoxelPointsKeepCentresAndColours) {
  mapping::OccupiedVoxel a, b;
  a.centre = {1.025, -2.075, 0.525};
  a.rgb = {10, 20, 30};
  a.has_colour = true;
  b.centre = {0.0, 0.1, 0.2};  // no colour: the voxel's grey
  const std::vector<CloudPoint> points = voxel_points({a, b});
  ASSERT_EQ(points.size(), 2u);
  EXPECT_FLOAT_EQ(points[0].x, 1.025f);
  EXPECT_FLOAT_EQ(points[0].y, -2.075f);
  EXPECT_FLOAT_EQ(points[0].z, 0.525f);
  EXPECT_EQ(points[0].rgb, (std::array<std::uint8_t, 3>{10, 20, 30}));
  EXPECT_EQ(points[1].rgb, b.rgb);
  EXPECT_TRUE(voxel_points({}).empty());
}

slam::ObjectReport object(int track, slam::ObjectState state, bool box,
                          std::optional<Eigen::Vector3d> velocity) {
  slam::ObjectReport o;
  o.track_id = track;
  o.state = state;
  if (box)
    o.world_box = std::make_pair(Eigen::Vector3d(1.0, 2.0, 0.0), Eigen::Vector3d(1.6, 2.4, 1.8));
  o.velocity = velocity;
  return o;
}

TEST(RosNodeMessages, PeopleMarkersAreBoxesAndVelocityArrowsOfMovingObjects) {
  using slam::ObjectState;
  const std::vector<slam::ObjectReport> objects = {
      object(7, ObjectState::kDynamic, true, Eigen::Vector3d(0.5, 0.0, 0.0)),
      object(3, ObjectState::kConstrained, true, std::nullopt),
      object(4, ObjectState::kStatic, true, std::nullopt),    // not moving: no marker
      object(5, ObjectState::kDynamic, false, std::nullopt),  // no box (lost frame): none
      object(-1, ObjectState::kDynamic, true, Eigen::Vector3d::Zero())};  // standing still
  const std::vector<MarkerSpec> m = people_markers(objects);
  ASSERT_EQ(m.size(), 4u);
  EXPECT_EQ(m[0].shape, MarkerSpec::Shape::kCube);
  EXPECT_EQ(m[0].ns, "people");
  EXPECT_EQ(m[0].id, 7);
  EXPECT_TRUE(m[0].position.isApprox(Eigen::Vector3d(1.3, 2.2, 0.9)));
  EXPECT_TRUE(m[0].scale.isApprox(Eigen::Vector3d(0.6, 0.4, 1.8)));
  EXPECT_GT(m[0].rgba[0], 0.9f);  // red
  EXPECT_LT(m[0].rgba[1], 0.2f);
  EXPECT_EQ(m[1].shape, MarkerSpec::Shape::kArrow);
  EXPECT_EQ(m[1].id, 7);
  EXPECT_TRUE(m[1].start.isApprox(m[0].position));
  EXPECT_TRUE(m[1].end.isApprox(Eigen::Vector3d(1.8, 2.2, 0.9)));  // one second ahead
  EXPECT_EQ(m[2].shape, MarkerSpec::Shape::kCube);
  EXPECT_EQ(m[2].ns, "movers");
  EXPECT_EQ(m[2].id, 3);
  EXPECT_GT(m[2].rgba[1], 0.8f);  // yellow
  EXPECT_EQ(m[3].shape, MarkerSpec::Shape::kCube);
  EXPECT_EQ(m[3].id, -5);  // no track: -1 - its index
  EXPECT_TRUE(people_markers({}).empty());
}

TEST(RosNodeMessages, MapToOdomTimesOdomToCameraIsTheSlamPose) {
  std::mt19937 rng(47);
  for (int i = 0; i < 20; ++i) {
    const SE3 T_map_camera = test::random_pose(rng, 3.0);
    const SE3 T_odom_camera = test::random_pose(rng, 3.0);
    const SE3 T_map_odom = map_to_odom(T_map_camera, T_odom_camera);
    const SE3 composed = T_map_odom * T_odom_camera;
    EXPECT_LT((composed.translation() - T_map_camera.translation()).norm(), 1e-12);
    EXPECT_LT(rotation_angle(composed.quaternion() * T_map_camera.quaternion().conjugate()), 1e-12);
  }
  // With odometry that agrees with SLAM, odom is the map.
  const SE3 T = test::random_pose(rng);
  EXPECT_LT(map_to_odom(T, T).log().norm(), 1e-12);
}

TEST(RosNodeOptions, CheckRejectsBadFrameNamesAndTimeouts) {
  EXPECT_FALSE(NodeOptions{}.check());
  const auto problem = [](const std::function<void(NodeOptions&)>& change) {
    NodeOptions o;
    change(o);
    return o.check().value_or("");
  };
  EXPECT_NE(problem([](NodeOptions& o) { o.floor_frame = ""; }).find("floor_frame"),
            std::string::npos);
  EXPECT_NE(problem([](NodeOptions& o) { o.floor_frame = "/floor"; }).find("'/'"),
            std::string::npos);
  EXPECT_NE(problem([](NodeOptions& o) { o.map_frame = "my map"; }).find("whitespace"),
            std::string::npos);
  EXPECT_NE(problem([](NodeOptions& o) { o.camera_frame = ""; }).find("camera_frame"),
            std::string::npos);
  EXPECT_NE(problem([](NodeOptions& o) { o.odom_frame = "map"; }).find("must differ"),
            std::string::npos);
  EXPECT_NE(problem([](NodeOptions& o) { o.floor_frame = "camera"; }).find("must differ"),
            std::string::npos);
  EXPECT_NE(problem([](NodeOptions& o) { o.odom_frame = "odom\t"; }).find("odom_frame"),
            std::string::npos);
  EXPECT_EQ(problem([](NodeOptions& o) { o.odom_frame = "odom"; }), "");
  EXPECT_NE(problem([](NodeOptions& o) { o.odom_timeout_s = -0.01; }).find("odom_timeout_s"),
            std::string::npos);
  EXPECT_NE(problem([](NodeOptions& o) { o.odom_timeout_s = 1.5; }).find("odom_timeout_s"),
            std::string::npos);
  EXPECT_EQ(problem([](NodeOptions& o) { o.odom_timeout_s = 0.0; }), "");
  EXPECT_NE(problem([](NodeOptions& o) { o.grid_period_s = 0.0; }).find("grid_period_s"),
            std::string::npos);
}

}  // namespace
}  // namespace mcslam::ros::detail
