// Line and plane landmarks of map::Map, and the map export (PLY, JSON).
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "mcslam/map/export.hpp"
#include "mcslam/map/map.hpp"

namespace mcslam::map {
namespace {

/// A keyframe with `n_points` points, `n_lines` segments and `n_planes` planes.
KeyFrame make_keyframe(KeyFrameId id, int n_points, int n_lines, int n_planes,
                       const SE3& T_c_w = SE3()) {
  auto f = std::make_shared<features::FrameFeatures>();
  f->pyramid = std::make_shared<const features::ScalePyramid>(8, 1.2);
  for (int i = 0; i < n_points; ++i) {
    features::PointFeature p;
    p.keypoint.uv = Eigen::Vector2f(10.0f + 5.0f * static_cast<float>(i), 20.0f);
    p.depth = 2.0f;
    f->points.push_back(p);
  }
  for (int i = 0; i < n_lines; ++i) {
    features::LineFeature l;
    l.start = Eigen::Vector2f(10.0f, 10.0f + 10.0f * static_cast<float>(i));
    l.end = Eigen::Vector2f(200.0f, 10.0f + 10.0f * static_cast<float>(i));
    l.descriptor.bytes[static_cast<std::size_t>(i % 32)] = 0xff;
    f->lines.push_back(l);
  }
  for (int i = 0; i < n_planes; ++i) f->planes.emplace_back();
  KeyFrame kf;
  kf.id = id;
  kf.T_c_w = T_c_w;
  kf.features = f;
  return kf;
}

TEST(MapLines, AddObserveEraseAndSlots) {
  Map map;
  map.add_keyframe(make_keyframe(0, 0, 3, 0));
  map.add_keyframe(make_keyframe(1, 0, 3, 0));
  ASSERT_EQ(map.keyframe(0)->line_landmarks.size(), 3u);
  const LineId l = map.add_line({0, 0, 2}, {1, 0, 2}, 0, 1);
  EXPECT_EQ(map.keyframe(0)->line_landmarks[1], l);
  map.add_line_observation(l, 1, 2);
  EXPECT_EQ(map.line(l)->observations.size(), 2u);
  // One segment per keyframe: a second link from keyframe 1 is refused.
  map.add_line_observation(l, 1, 0);
  EXPECT_EQ(map.keyframe(1)->line_landmarks[0], kNoId);
  map.erase_line_observation(l, 0);
  EXPECT_EQ(map.keyframe(0)->line_landmarks[1], kNoId);
  ASSERT_NE(map.line(l), nullptr);
  map.erase_line_observation(l, 1);  // the last observation takes the line with it
  EXPECT_EQ(map.line(l), nullptr);
  EXPECT_EQ(map.keyframe(1)->line_landmarks[2], kNoId);
}

TEST(MapLines, ExtendCoversTheProjectionOfANewSegment) {
  Map map;
  map.add_keyframe(make_keyframe(0, 0, 1, 0));
  const LineId l = map.add_line({0, 0, 2}, {1, 0, 2}, 0, 0);
  // Overlapping and extending past the start, slightly off the line.
  map.extend_line(l, {-0.5, 0.01, 2.0}, {0.5, 0.0, 2.0});
  EXPECT_NEAR(map.line(l)->start_w.x(), -0.5, 1e-9);
  EXPECT_NEAR(map.line(l)->end_w.x(), 1.0, 1e-9);
  EXPECT_NEAR(map.line(l)->start_w.y(), 0.0, 1e-9);  // stays on the line
  // Inside: unchanged.
  map.extend_line(l, {0.2, 0, 2}, {0.3, 0, 2});
  EXPECT_NEAR(map.line(l)->length(), 1.5, 1e-9);
}

TEST(MapLines, ReplaceMovesObservationsAndCovisibilityCountsSharedLines) {
  Map map;
  for (KeyFrameId k = 0; k < 3; ++k) map.add_keyframe(make_keyframe(k, 0, 2, 0));
  const LineId a = map.add_line({0, 0, 2}, {1, 0, 2}, 0, 0);
  map.add_line_observation(a, 1, 0);
  const LineId b = map.add_line({0, 0, 2}, {0.5, 0, 2}, 2, 1);
  map.replace_line(b, a);
  EXPECT_EQ(map.line(b), nullptr);
  EXPECT_EQ(map.line(a)->observations.size(), 3u);
  EXPECT_EQ(map.keyframe(2)->line_landmarks[1], a);
  for (KeyFrameId k = 0; k < 3; ++k) map.update_covisibility(k);
  EXPECT_EQ(map.keyframe(0)->covisibility.at(2), 1);
  EXPECT_EQ(map.keyframe(2)->covisibility.at(1), 1);
}

TEST(MapPlanes, AddMergeExtendAndEraseWithKeyframe) {
  Map map;
  map.add_keyframe(make_keyframe(0, 0, 0, 2));
  map.add_keyframe(make_keyframe(1, 0, 0, 1));
  // The floor z = 0 seen from above: normal +z, d = 0; a 1 m square.
  const std::vector<Eigen::Vector3d> square = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  const PlaneId p = map.add_plane({0, 0, 2, 0}, square, 0, 0);  // normalised on the way in
  EXPECT_NEAR(map.plane(p)->normal.norm(), 1.0, 1e-12);
  EXPECT_EQ(map.plane(p)->hull.size(), 4u);
  // Extending with a point 2 m away (slightly above the plane: projected onto it).
  map.extend_plane(p, {{3, 0.5, 0.01}});
  double max_x = 0.0;
  for (const auto& h : map.plane(p)->hull) {
    max_x = std::max(max_x, h.x());
    EXPECT_NEAR(h.z(), 0.0, 1e-9);
  }
  EXPECT_NEAR(max_x, 3.0, 1e-6);
  const PlaneId q =
      map.add_plane({0, 0, 1, 0.01}, {{5, 5, -0.01}, {6, 5, -0.01}, {6, 6, -0.01}}, 1, 0);
  map.replace_plane(q, p);
  EXPECT_EQ(map.plane(q), nullptr);
  EXPECT_EQ(map.keyframe(1)->plane_landmarks[0], p);
  EXPECT_EQ(map.plane(p)->observations.size(), 2u);
  max_x = 0.0;
  for (const auto& h : map.plane(p)->hull) max_x = std::max(max_x, h.x());
  EXPECT_NEAR(max_x, 6.0, 1e-6);
  map.erase_keyframe(1);
  EXPECT_EQ(map.plane(p)->observations.size(), 1u);
  map.erase_keyframe(0);
  EXPECT_EQ(map.plane(p), nullptr);
}

TEST(MapExport, PlyHeaderCountsMatchTheBody) {
  Map map;
  map.add_keyframe(make_keyframe(0, 2, 1, 1));
  const PointId p0 = map.add_point({0, 0, 1}, 0, 0);
  map.add_point({0, 1, 1}, 0, 1);
  map.set_point_color(p0, {255, 0, 10});
  map.add_line({0, 0, 2}, {1, 0, 2}, 0, 0);
  map.add_plane({0, 0, 1, -3}, {{0, 0, 3}, {1, 0, 3}, {1, 1, 3}}, 0, 0);
  const std::string ply = map_to_ply(map);
  std::istringstream in(ply);
  std::string line;
  int vertices = -1, edges = -1, faces = -1;
  while (std::getline(in, line) && line != "end_header") {
    std::istringstream words(line);
    std::string w, kind;
    int n = 0;
    words >> w;
    if (w != "element") continue;
    words >> kind >> n;
    (kind == "vertex" ? vertices : kind == "edge" ? edges : faces) = n;
  }
  // 2 points + 2 line endpoints + 3 hull corners + 1 keyframe centre.
  EXPECT_EQ(vertices, 8);
  EXPECT_EQ(edges, 1);
  EXPECT_EQ(faces, 1);
  std::vector<std::string> body;
  while (std::getline(in, line)) body.push_back(line);
  ASSERT_EQ(body.size(), 10u);
  EXPECT_EQ(body[0].substr(body[0].size() - 8), "255 0 10");  // the coloured point
  EXPECT_EQ(body[8].substr(0, 4), "2 3 ");                    // the edge joins vertices 2, 3
  EXPECT_EQ(body[9].substr(0, 8), "3 4 5 6 ");                // the plane's polygon
}

TEST(MapExport, JsonListsLandmarksWithObservations) {
  Map map;
  map.add_keyframe(make_keyframe(0, 1, 1, 1));
  map.add_keyframe(make_keyframe(1, 1, 1, 1));
  const PointId p = map.add_point({0, 0, 1}, 0, 0);
  map.add_observation(p, 1, 0);
  map.add_line({0, 0, 2}, {1, 0, 2}, 1, 0);
  map.add_plane({1, 0, 0, -2}, {{2, 0, 0}, {2, 1, 0}, {2, 1, 1}}, 0, 0);
  const nlohmann::json j = map_to_json(map);
  ASSERT_EQ(j["keyframes"].size(), 2u);
  ASSERT_EQ(j["points"].size(), 1u);
  EXPECT_EQ(j["points"][0]["observations"], nlohmann::json::parse("[[0, 0], [1, 0]]"));
  ASSERT_EQ(j["lines"].size(), 1u);
  EXPECT_EQ(j["lines"][0]["observations"], nlohmann::json::parse("[[1, 0]]"));
  ASSERT_EQ(j["planes"].size(), 1u);
  EXPECT_DOUBLE_EQ(j["planes"][0]["d"].get<double>(), -2.0);
  EXPECT_EQ(j["planes"][0]["hull_w"].size(), 3u);
}

}  // namespace
}  // namespace mcslam::map
