#include "mcslam/mapping/export.hpp"

#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "mapping/box_world.hpp"
#include "support/temp_dir.hpp"
#include "support/test_camera.hpp"

namespace mcslam::mapping {
namespace {

using test::BoxWorld;
using test::look;

OccupancyMap small_map() {
  BoxWorld world;
  world.boxes.push_back({{4.0, 2.3, 0.012}, {4.45, 2.75, 0.9}, false, {30, 120, 30}});
  OccupancyMap map;
  const PinholeCamera cam = test::make_camera();
  for (int i = 0; i < 3; ++i)
    map.insert(world.render(i, look({2.6 + 0.1 * i, 2.3 + 0.2 * i, 1.2}, 0.05 * i), cam));
  return map;
}

std::string read_all(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// map_server's trinary reading of a pixel (negate 0): p = (255 - x) / 255; p > occupied_thresh
/// occupied, p < free_thresh free, else unknown.
std::int8_t map_server_value(std::uint8_t x, double occupied_thresh, double free_thresh) {
  const double p = (255.0 - x) / 255.0;
  if (p > occupied_thresh) return 100;
  if (p < free_thresh) return 0;
  return -1;
}

class ExportTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { map_ = new OccupancyMap(small_map()); }
  static void TearDownTestSuite() {
    delete map_;
    map_ = nullptr;
  }
  static OccupancyMap* map_;
  test::TempDir dir_{"mcslam_mapping_export"};
};
OccupancyMap* ExportTest::map_ = nullptr;

TEST_F(ExportTest, MapServerPgmAndYamlReadBackAsTheGrid) {
  const OccupancyGrid grid = map_->grid(FloorPlane{Eigen::Vector3d::UnitZ(), -0.012});
  ASSERT_GT(grid.width, 0);
  write_map_server(grid, dir_.file("grid.pgm"), dir_.file("grid.yaml"));
  const std::string pgm = read_all(dir_.file("grid.pgm"));
  std::istringstream in(pgm);
  std::string magic, comment;
  int w = 0, h = 0, maxval = 0;
  std::getline(in, magic);
  std::getline(in, comment);
  in >> w >> h >> maxval;
  in.get();  // the single whitespace after maxval
  EXPECT_EQ(magic, "P5");
  EXPECT_EQ(comment.front(), '#');
  EXPECT_EQ(w, grid.width);
  EXPECT_EQ(h, grid.height);
  EXPECT_EQ(maxval, 255);
  const std::string pixels = pgm.substr(static_cast<std::size_t>(in.tellg()));
  ASSERT_EQ(pixels.size(), static_cast<std::size_t>(w) * h);
  // Only 0, 254, 205; map_server with the thresholds written reads back every cell (the top
  // image row is the grid's highest row).
  std::size_t mismatches = 0;
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const auto x = static_cast<std::uint8_t>(pixels[static_cast<std::size_t>(r) * w + c]);
      EXPECT_TRUE(x == 0 || x == 254 || x == 205) << int(x);
      if (map_server_value(x, 0.65, 0.196) != grid.at(c, h - 1 - r)) ++mismatches;
    }
  EXPECT_EQ(mismatches, 0u);
  // nav2's old default free_thresh (0.25) would read the unknown 205 as free: why 0.196.
  EXPECT_EQ(map_server_value(205, 0.65, 0.25), 0);
  EXPECT_EQ(map_server_value(205, 0.65, 0.196), -1);

  char origin[128];
  std::snprintf(origin, sizeof origin, "origin: [%.6f, %.6f, 0.0]\n", grid.origin.x(),
                grid.origin.y());
  EXPECT_EQ(read_all(dir_.file("grid.yaml")), std::string("image: grid.pgm\n"
                                                          "mode: trinary\n"
                                                          "resolution: 0.050000\n") +
                                                  origin +
                                                  "negate: 0\n"
                                                  "occupied_thresh: 0.65\n"
                                                  "free_thresh: 0.196\n");
  // The origin is the lower-left cell's corner in the floor frame: a multiple of the resolution.
  EXPECT_NEAR(grid.origin.x() / 0.05, std::round(grid.origin.x() / 0.05), 1e-9);
  EXPECT_LT(grid.origin.x(), 2.7);
}

TEST_F(ExportTest, YamlNamesAnImageInAnotherFolderByItsPath) {
  const OccupancyGrid grid = map_->grid();
  std::filesystem::create_directory(dir_ / "maps");
  write_map_server(grid, dir_.file("maps/grid.pgm"), dir_.file("grid.yaml"));
  const std::string yaml = read_all(dir_.file("grid.yaml"));
  EXPECT_EQ(
      yaml.rfind("image: " + std::filesystem::absolute(dir_ / "maps/grid.pgm").string() + "\n", 0),
      0u)
      << yaml;
}

TEST_F(ExportTest, GridPictureIsScaledUp) {
  const OccupancyGrid grid = map_->grid();
  write_grid_png(grid, dir_.file("grid.png"), 4);
  const cv::Mat image = cv::imread(dir_.file("grid.png"), cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 4 * grid.width);
  EXPECT_EQ(image.rows, 4 * grid.height);
}

TEST_F(ExportTest, OctomapBinaryLoadsBackWithTheSameOccupiedVoxels) {
  write_octomap_binary(*map_, dir_.file("occupancy.bt"));
  octomap::OcTree loaded(0.1);
  ASSERT_TRUE(loaded.readBinary(dir_.file("occupancy.bt")));
  EXPECT_DOUBLE_EQ(loaded.getResolution(), 0.05);
  std::size_t occupied = 0, agree = 0;
  for (auto it = loaded.begin_leafs(); it != loaded.end_leafs(); ++it) {
    if (!loaded.isNodeOccupied(*it)) continue;
    ++occupied;
    const auto c = it.getCoordinate();
    agree += map_->state({c.x(), c.y(), c.z()}) == VoxelState::kOccupied;
  }
  EXPECT_EQ(occupied, map_->occupied_voxels().size());
  EXPECT_EQ(agree, occupied);
  // Byte for byte what OctoMap's own writer gives (which reports on stderr, so is not used).
  ASSERT_TRUE(map_->octree().writeBinaryConst(dir_.file("octomap.bt")));
  EXPECT_EQ(read_all(dir_.file("occupancy.bt")), read_all(dir_.file("octomap.bt")));
}

TEST_F(ExportTest, PlyHasAHeaderAndOneColouredVertexPerOccupiedVoxel) {
  write_occupied_voxels_ply(*map_, dir_.file("voxels.ply"));
  const std::string ply = read_all(dir_.file("voxels.ply"));
  const std::size_t n = map_->occupied_voxels().size();
  const std::string end = "end_header\n";
  const std::size_t header_end = ply.find(end);
  ASSERT_NE(header_end, std::string::npos);
  const std::string header = ply.substr(0, header_end + end.size());
  EXPECT_EQ(header.rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u);
  EXPECT_NE(header.find("element vertex " + std::to_string(n) + "\n"), std::string::npos);
  EXPECT_NE(header.find("property float x\nproperty float y\nproperty float z\n"
                        "property uchar red\nproperty uchar green\nproperty uchar blue\n"),
            std::string::npos);
  EXPECT_EQ(ply.size(), header.size() + n * 15);
  // The chair's voxels are green (BGR 30, 120, 30), the room's grey (180).
  std::size_t green = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const auto* rgb =
        reinterpret_cast<const std::uint8_t*>(ply.data() + header.size() + i * 15 + 12);
    green += rgb[0] == 30 && rgb[1] == 120 && rgb[2] == 30;
  }
  EXPECT_GT(green, 50u);
}

TEST_F(ExportTest, SummaryHasTheGridTransformAndTheFigures) {
  const OccupancyGrid grid = map_->grid();
  const OccupancyStats stats = map_->stats();
  const nlohmann::json j = occupancy_summary(stats, grid);
  EXPECT_DOUBLE_EQ(j["resolution"].get<double>(), 0.05);
  ASSERT_EQ(j["grid"]["T_world_grid"].size(), 4u);
  EXPECT_DOUBLE_EQ(j["grid"]["T_world_grid"][0][3].get<double>(), grid.T_world_grid(0, 3));
  EXPECT_EQ(j["grid"]["width"].get<int>(), grid.width);
  EXPECT_TRUE(j["grid"]["floor"]["estimated"].get<bool>());
  const auto& cells = j["grid"]["cells"];
  EXPECT_EQ(cells["occupied"].get<std::size_t>() + cells["free"].get<std::size_t>() +
                cells["unknown"].get<std::size_t>(),
            grid.cells.size());
  EXPECT_EQ(j["voxels"]["occupied"].get<std::size_t>(), stats.occupied_voxels);
  EXPECT_EQ(j["keyframes"].get<std::size_t>(), 3u);
  EXPECT_GT(j["time_per_keyframe_ms"]["median"].get<double>(), 0.0);
  EXPECT_EQ(j["memory_bytes"]["total"].get<std::size_t>(), stats.total_bytes());
}

TEST_F(ExportTest, UnwritableOutputsNameTheFile) {
  const std::string missing = dir_.file("no/such/folder/");
  const OccupancyGrid grid = map_->grid();
  test::expect_input_error([&] { write_octomap_binary(*map_, missing + "a.bt"); },
                           {missing + "a.bt", "cannot write"});
  test::expect_input_error([&] { write_map_server(grid, missing + "g.pgm", dir_.file("g.yaml")); },
                           {missing + "g.pgm", "cannot write"});
  test::expect_input_error([&] { write_map_server(grid, dir_.file("g.pgm"), missing + "g.yaml"); },
                           {missing + "g.yaml", "cannot write"});
  test::expect_input_error([&] { write_grid_png(grid, missing + "g.png"); },
                           {missing + "g.png", "cannot write"});
  test::expect_input_error([&] { write_occupied_voxels_ply(*map_, missing + "v.ply"); },
                           {missing + "v.ply", "cannot write"});
}

}  // namespace
}  // namespace mcslam::mapping
