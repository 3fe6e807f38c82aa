#include "mcslam/mapping/occupancy_map.hpp"

#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <array>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "mapping/box_world.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/mapping/evaluation.hpp"
#include "support/test_camera.hpp"

namespace mcslam::mapping {
namespace {

using test::BoxWorld;
using test::look;
using test::WorldBox;

/// Keyframes 2.7-3.3 m in front of the +x wall (x = 5.987), moving sideways and turning a little.
std::vector<SE3> wall_path(int n) {
  std::vector<SE3> poses;
  for (int i = 0; i < n; ++i) {
    const double s = n == 1 ? 0.0 : static_cast<double>(i) / (n - 1) - 0.5;
    poses.push_back(look({2.7 + 0.3 * s, 2.5 + 0.8 * s, 1.2}, -0.3 * s));
  }
  return poses;
}

void insert_all(OccupancyMap& map, const BoxWorld& world, const std::vector<SE3>& poses,
                KeyframeId first_id = 0) {
  const PinholeCamera cam = test::make_camera();
  for (std::size_t i = 0; i < poses.size(); ++i)
    map.insert(world.render(first_id + i, poses[i], cam));
}

/// The share of grid points p(a, b) (a, b in [0, 1]) in `expected` state.
double share_in_state(const OccupancyMap& map, VoxelState expected,
                      const std::function<Eigen::Vector3d(double, double)>& p, int n = 20) {
  int hits = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      if (map.state(p((i + 0.5) / n, (j + 0.5) / n)) == expected) ++hits;
  return static_cast<double>(hits) / (n * n);
}

/// Whether the surface at x = face (seen from -x, on a voxel boundary of the default 5 cm
/// grid) is occupied at (y, z): in the voxel in front of the boundary or the one behind it,
/// whichever the measurements landed in.
bool face_occupied(const OccupancyMap& map, double face, double y, double z) {
  return map.state({face - 0.01, y, z}) == VoxelState::kOccupied ||
         map.state({face + 0.01, y, z}) == VoxelState::kOccupied;
}

std::size_t occupied_inside(const OccupancyMap& map, const WorldBox& box, double margin) {
  std::size_t n = 0;
  for (const auto& v : map.occupied_voxels())
    if (box.contains(v.centre, margin)) ++n;
  return n;
}

TEST(OccupancyMap, WallSeenFromSeveralKeyframesIsOccupiedAndTheSpaceInFrontFree) {
  BoxWorld world;
  OccupancyMap map;
  insert_all(map, world, wall_path(5));
  const double wall = world.room_max.x() - 0.01;
  // The part of the wall that every keyframe sees, and the space in front of it within every
  // keyframe's view: y in [1.7, 3.3], z in [0.4, 1.4] (the view's top edge is 1.53 m high at
  // x = 4.5).
  const auto on_wall = [&](double x) {
    return [x](double a, double b) { return Eigen::Vector3d(x, 1.7 + 1.6 * a, 0.4 + 1.0 * b); };
  };
  EXPECT_GE(share_in_state(map, VoxelState::kOccupied, on_wall(wall)), 0.99);
  EXPECT_GE(share_in_state(map, VoxelState::kFree, on_wall(wall - 0.12)), 0.99);
  EXPECT_GE(share_in_state(map, VoxelState::kFree, on_wall(4.5)), 0.99);
  // Behind the wall and behind the cameras nothing is known.
  EXPECT_GE(share_in_state(map, VoxelState::kUnknown, on_wall(world.room_max.x() + 0.2)), 0.99);
  EXPECT_GE(share_in_state(map, VoxelState::kUnknown, on_wall(1.0)), 0.99);
  // The floor in view is occupied, the air above it free.
  EXPECT_EQ(map.state({4.5, 2.5, 0.03}), VoxelState::kOccupied);
  EXPECT_EQ(map.state({4.5, 2.5, 0.2}), VoxelState::kFree);
  // No occupied voxel off the room's surfaces.
  const MapQuality q = evaluate_map(map, world.static_surfaces());
  EXPECT_EQ(q.ghosts, 0u) << q.occupied << " occupied";
  const OccupancyStats s = map.stats();
  std::printf(
      "[ wall ] 5 keyframes: %zu occupied, %zu free voxels, %zu leaves, insert median "
      "%.1f ms p95 %.1f ms\n",
      s.occupied_voxels, s.free_voxels, s.leaf_nodes, s.integration_ms.median,
      s.integration_ms.p95);
}

TEST(OccupancyMap, DynamicPixelsAreNeverOccupiedButFreeTheirRay) {
  BoxWorld world;
  const WorldBox person{{4.3, 2.3, 0.012}, {4.7, 2.7, 1.75}, true, {0, 0, 255}};
  world.boxes.push_back(person);
  OccupancyMap masked;
  insert_all(masked, world, wall_path(5));
  // Above the floor's voxels, nothing of the person is occupied.
  WorldBox body = person;
  body.min.z() = 0.1;
  EXPECT_EQ(occupied_inside(masked, body, 0.05), 0u);
  // The space between the cameras and the person is free.
  const auto before = [](double a, double b) {
    return Eigen::Vector3d(3.8 + 0.4 * a, 2.45 + 0.1 * b, 0.8 + 0.5 * b);
  };
  EXPECT_GE(share_in_state(masked, VoxelState::kFree, before), 0.99);
  // The person is there: with the mask off, it is in the map.
  world.boxes.back().dynamic = false;
  OccupancyMap unmasked;
  insert_all(unmasked, world, wall_path(5));
  EXPECT_GT(occupied_inside(unmasked, body, 0.05), 50u);
  // use_masks = false (the ablation) ignores the mask it is given: the same map as no mask.
  world.boxes.back().dynamic = true;
  OccupancyOptions ignore;
  ignore.use_masks = false;
  OccupancyMap ignored(ignore);
  insert_all(ignored, world, wall_path(5));
  EXPECT_EQ(occupied_inside(ignored, body, 0.05), occupied_inside(unmasked, body, 0.05));
  EXPECT_EQ(ignored.stats().occupied_voxels, unmasked.stats().occupied_voxels);
}

TEST(OccupancyMap, TransientViewsAreIntegratedButNotStored) {
  BoxWorld world;
  const PinholeCamera cam = test::make_camera();
  const std::vector<SE3> path = wall_path(4);
  OccupancyMap stored;
  insert_all(stored, world, path);
  OccupancyMap transient;
  insert_all(transient, world, {path[0], path[1]});
  for (std::size_t i = 2; i < path.size(); ++i)
    transient.integrate_transient(world.render(100 + i, path[i], cam));
  // The same octree as inserting all four, but only two keyframes kept.
  EXPECT_EQ(transient.stats().occupied_voxels, stored.stats().occupied_voxels);
  EXPECT_EQ(transient.stats().free_voxels, stored.stats().free_voxels);
  EXPECT_EQ(transient.keyframes().size(), 2u);
  EXPECT_EQ(transient.stats().integration_ms.count, 4u);
  EXPECT_LT(transient.stats().keyframe_bytes, stored.stats().keyframe_bytes);
  // A rebuild forgets them.
  transient.rebuild();
  OccupancyMap two;
  insert_all(two, world, {path[0], path[1]});
  EXPECT_EQ(transient.stats().occupied_voxels, two.stats().occupied_voxels);
}

TEST(OccupancyMap, PushedChairIsOccupiedWhereItIsAndItsFirstPlaceFree) {
  const WorldBox first{{4.0, 1.9, 0.012}, {4.45, 2.35, 0.9}, false, {30, 120, 30}};
  WorldBox last = first;
  last.min.y() += 1.0;
  last.max.y() += 1.0;
  BoxWorld world;
  world.boxes.push_back(first);
  const PinholeCamera cam = test::make_camera();
  OccupancyMap map;
  // 16 keyframes 1.8 m in front of the chair's places, moving sideways across both.
  std::vector<SE3> poses;
  for (int i = 0; i < 16; ++i) poses.push_back(look({2.2, 2.0 + i / 15.0, 1.2}, 0.0, 0.35));
  for (std::size_t i = 0; i < poses.size(); ++i) {
    // Keyframes 0-4 see it at its first place, 5-15 (11, more than the 9 misses a voxel at
    // clamp_max needs) at its last place.
    if (i == 5) world.boxes[0] = last;
    map.insert(world.render(i, poses[i], cam));
  }
  WorldBox above_floor = first;
  above_floor.min.z() = 0.1;
  EXPECT_EQ(occupied_inside(map, above_floor, 0.0), 0u);
  EXPECT_EQ(map.state({4.2, 2.1, 0.5}), VoxelState::kFree);
  above_floor = last;
  above_floor.min.z() = 0.1;
  EXPECT_GT(occupied_inside(map, above_floor, 0.05), 100u);
  EXPECT_TRUE(face_occupied(map, last.min.x(), 0.5 * (last.min.y() + last.max.y()), 0.5));
  EXPECT_TRUE(face_occupied(map, last.min.x(), last.min.y() + 0.2, last.max.z() - 0.01));
  // Its voxels keep the chair's colour (green, BGR 30,120,30).
  bool green = false;
  for (const auto& v : map.occupied_voxels())
    if (last.contains(v.centre, 0.0) && v.has_colour && v.rgb[1] == 120) green = true;
  EXPECT_TRUE(green);
}

/// A chair (a mover's box in BoxWorld) and its place 1 m along +y, seen by 5 keyframes 1.8 m in
/// front of them moving sideways.
struct PushedChair {
  WorldBox first{{4.0, 1.9, 0.012}, {4.45, 2.35, 0.9}, false, {30, 120, 30}, true};
  WorldBox last = moved(first, 1.0);
  std::vector<SE3> poses = path();

  static WorldBox moved(WorldBox box, double dy) {
    box.min.y() += dy;
    box.max.y() += dy;
    return box;
  }
  static std::vector<SE3> path() {
    std::vector<SE3> out;
    for (int i = 0; i < 5; ++i) out.push_back(look({2.2, 2.2 + 0.15 * i, 1.2}, 0.0, 0.35));
    return out;
  }
};

TEST(OccupancyMap, AMoverIsForgottenWhereItLeftAtOnce) {
  // The chair pushed after 3 keyframes and seen 2 more times: as a static object its first
  // place needs 9 keyframes to clear; marked as a mover, the first keyframe seeing through it.
  const PushedChair chair;
  const WorldBox& first = chair.first;
  const WorldBox& last = chair.last;
  const std::vector<SE3>& poses = chair.poses;
  const PinholeCamera cam = test::make_camera();
  const auto build = [&](bool mover) {
    BoxWorld world;
    world.boxes.push_back(first);
    world.boxes[0].mover = mover;
    OccupancyMap map;
    for (std::size_t i = 0; i < poses.size(); ++i) {
      if (i == 3) {
        world.boxes[0].min = last.min;
        world.boxes[0].max = last.max;
      }
      map.insert(world.render(i, poses[i], cam));
    }
    return map;
  };
  WorldBox first_above = first, last_above = last;
  first_above.min.z() = last_above.min.z() = 0.1;
  const OccupancyMap as_mover = build(true);
  EXPECT_EQ(occupied_inside(as_mover, first_above, 0.0), 0u);
  EXPECT_GT(occupied_inside(as_mover, last_above, 0.05), 100u);
  EXPECT_TRUE(face_occupied(as_mover, last.min.x(), 0.5 * (last.min.y() + last.max.y()), 0.5));
  const OccupancyMap as_static = build(false);
  EXPECT_GT(occupied_inside(as_static, first_above, 0.0), 100u);
  // After it left, the static room behind it is mapped as usual.
  EXPECT_EQ(as_mover.state({4.5, 2.1, 0.03}), VoxelState::kOccupied);
}

TEST(OccupancyMap, AnObjectSeenStillIsForgottenWhereItStoodOnceItMoves) {
  // The chair stands still for 3 keyframes (a static box, track 7), then is pushed: the
  // keyframe that first sees it move (moving_objects {7}) relabels where the earlier keyframes
  // saw it, and its own rays and the next keyframe's free that place at once.
  const PushedChair chair;
  const WorldBox& first = chair.first;
  const WorldBox& last = chair.last;
  const std::vector<SE3>& poses = chair.poses;
  const PinholeCamera cam = test::make_camera();
  const auto build = [&](bool tell_the_map) {
    BoxWorld world;
    world.boxes.push_back(first);
    OccupancyMap map;
    for (std::size_t i = 0; i < poses.size(); ++i) {
      if (i == 3) world.boxes[0] = last;
      KeyframeDepth kf = world.render(i, poses[i], cam);  // the box's pixels in mover_mask
      const cv::Rect box = cv::boundingRect(kf.mover_mask);
      if (i < 3) {
        kf.mover_mask.setTo(0);  // still: a static object
        if (tell_the_map) kf.still_objects.push_back({7, cv::Rect2f(box), 1.0f, 3.0f});
      } else if (tell_the_map) {
        kf.moving_objects.push_back(7);
      }
      map.insert(kf);
    }
    return map;
  };
  WorldBox first_above = first, last_above = last;
  first_above.min.z() = last_above.min.z() = 0.1;
  const OccupancyMap told = build(true);
  EXPECT_EQ(occupied_inside(told, first_above, 0.0), 0u);
  EXPECT_GT(occupied_inside(told, last_above, 0.05), 100u);
  // Not told, the 2 keyframes after the push leave its first place as it was.
  const OccupancyMap untold = build(false);
  EXPECT_GT(occupied_inside(untold, first_above, 0.0), 100u);
  // The relabelled samples are movers' in what the map keeps (a rebuild or a saved session
  // gives the same map).
  OccupancyMap rebuilt = told.clone();
  rebuilt.rebuild();
  EXPECT_EQ(occupied_inside(rebuilt, first_above, 0.0), 0u);
  std::size_t movers = 0;
  for (const auto& kf : told.keyframes())
    movers += static_cast<std::size_t>(cv::countNonZero(kf.kind == KeyframeSamples::kMover));
  EXPECT_GT(movers, 1000u);
}

TEST(OccupancyMap, CorrectionRebuildsWithoutADoubledWall) {
  BoxWorld world;
  const PinholeCamera cam = test::make_camera();
  const auto poses = wall_path(8);
  OccupancyMap map;
  std::unordered_map<KeyframeId, SE3> corrected;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    auto kf = world.render(i, poses[i], cam);
    if (i >= 4) {  // odometry drifted by 20 cm along x: these put the wall 20 cm too far
      kf.T_w_c.set_translation(kf.T_w_c.translation() + Eigen::Vector3d(0.2, 0.0, 0.0));
      corrected[i] = poses[i];
    }
    map.insert(kf);
  }
  const auto surfaces = world.static_surfaces();
  const MapQuality drifted = evaluate_map(map, surfaces);
  EXPECT_GT(drifted.ghost_rate, 0.05) << "the drifted keyframes double the wall";
  EXPECT_TRUE(map.correct(corrected));
  const MapQuality fixed = evaluate_map(map, surfaces);
  EXPECT_LE(fixed.ghost_rate, 0.01);
  EXPECT_EQ(fixed.ghosts, 0u);
  // Rebuilt from the stored samples, it is the map the true poses give.
  OccupancyMap truth;
  insert_all(truth, world, poses);
  EXPECT_EQ(map.stats().occupied_voxels, truth.stats().occupied_voxels);
  EXPECT_EQ(map.stats().free_voxels, truth.stats().free_voxels);
  // Poses that did not move (or moved less than a quarter voxel) do not rebuild.
  EXPECT_FALSE(map.correct(corrected));
  const OccupancyStats s = map.stats();
  EXPECT_EQ(s.rebuilds, 1u);
  // A correction that lists only some keyframes: the others follow the closest earlier listed
  // one (keyframes 5-7 keyframe 4) or, with none earlier, stay (keyframes 0-3).
  const SE3 drift(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.2, 0.0, 0.0));
  EXPECT_TRUE(map.correct(
      {{4, drift * poses[4]}, {5, drift * poses[5]}, {6, drift * poses[6]}, {7, drift * poses[7]}},
      true));
  EXPECT_GT(evaluate_map(map, surfaces).ghost_rate, 0.05);
  EXPECT_TRUE(map.correct({{4, poses[4]}}));
  EXPECT_EQ(evaluate_map(map, surfaces).ghosts, 0u);
  EXPECT_EQ(map.stats().occupied_voxels, truth.stats().occupied_voxels);
  std::printf(
      "[ correction ] ghost rate drifted %.3f, corrected %.4f; rebuild of %zu keyframes "
      "%.1f ms\n",
      drifted.ghost_rate, fixed.ghost_rate, s.keyframes, s.last_rebuild_ms);
}

TEST(OccupancyMap, MemoryPerKeyframeIsBounded) {
  BoxWorld world;
  OccupancyMap map;
  insert_all(map, world, wall_path(4));
  const OccupancyStats s = map.stats();
  ASSERT_EQ(s.keyframes, 4u);
  // VGA at step 3: 213 x 160 samples of 2 (depth) + 1 (mask) + 3 (colour) bytes = 204,480.
  const auto& kf = map.keyframes().front();
  EXPECT_EQ(kf.step, 3);
  EXPECT_EQ(kf.depth_mm.cols, 213);
  EXPECT_EQ(kf.depth_mm.rows, 160);
  EXPECT_EQ(kf.bytes(), 213u * 160u * 6u);
  EXPECT_LT(s.keyframe_bytes_each(), 210000.0);
  OccupancyOptions no_colour;
  no_colour.store_colour = false;
  OccupancyMap grey(no_colour);
  insert_all(grey, world, wall_path(1));
  EXPECT_EQ(grey.keyframes().front().bytes(), 213u * 160u * 3u);
  std::printf(
      "[ memory ] %.0f bytes per keyframe (%.0f without colour); octree %zu bytes, "
      "colours %zu bytes, %zu in all for 4 keyframes\n",
      s.keyframe_bytes_each(), grey.stats().keyframe_bytes_each(), s.octree_bytes, s.colour_bytes,
      s.total_bytes());
}

TEST(OccupancyMap, FarMeasurementsFreeTheirRayUpToMaxRangeOnly) {
  BoxWorld world;
  OccupancyOptions o;
  o.max_range = 2.0;
  OccupancyMap map(o);
  // 3.3 m from the wall, the wall is beyond max_range: nothing occupied on it, the first
  // 2 m of every ray free.
  insert_all(map, world, {look({2.7, 2.5, 1.2}, 0.0, 0.0)});
  EXPECT_EQ(map.state({world.room_max.x() - 0.01, 2.5, 1.2}), VoxelState::kUnknown);
  EXPECT_EQ(map.state({4.5, 2.5, 1.2}), VoxelState::kFree);
  EXPECT_EQ(map.state({5.2, 2.5, 1.2}), VoxelState::kUnknown);
}

TEST(OccupancyMap, RejectsImagesThatDoNotMatchTheCamera) {
  BoxWorld world;
  OccupancyMap map;
  auto kf = world.render(7, wall_path(1)[0], test::make_camera());
  kf.dynamic_mask = cv::Mat::zeros(10, 10, CV_8UC1);
  try {
    map.insert(kf);
    ADD_FAILURE() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("keyframe 7"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("dynamic mask"), std::string::npos) << e.what();
  }
  EXPECT_EQ(map.stats().keyframes, 0u);
  // Stored samples (from a saved session) are checked too.
  kf.dynamic_mask.release();
  KeyframeSamples samples = sample_keyframe(kf, map.options());
  samples.depth_mm = cv::Mat::zeros(5, 5, CV_16UC1);
  EXPECT_THROW(map.insert(samples), InputError);
}

TEST(OccupancyMap, CloneIsIndependent) {
  BoxWorld world;
  OccupancyMap map;
  insert_all(map, world, wall_path(2));
  OccupancyMap copy = map.clone();
  EXPECT_EQ(copy.stats().occupied_voxels, map.stats().occupied_voxels);
  EXPECT_EQ(copy.occupied_voxels().size(), map.occupied_voxels().size());
  const std::size_t before = map.stats().occupied_voxels;
  SE3 moved = map.keyframes()[1].T_w_c;
  moved.set_translation(moved.translation() + Eigen::Vector3d(0.3, 0.0, 0.0));
  EXPECT_TRUE(copy.correct({{1, moved}}));
  EXPECT_EQ(map.stats().occupied_voxels, before);
  EXPECT_EQ(map.stats().rebuilds, 0u);
  EXPECT_NE(copy.stats().occupied_voxels, before);
  // The copy keeps the settings (hits and clamping) of the original.
  EXPECT_DOUBLE_EQ(copy.octree().getProbHit(), map.octree().getProbHit());
  EXPECT_DOUBLE_EQ(copy.octree().getClampingThresMax(), map.octree().getClampingThresMax());
}

TEST(OccupancyMap, StoredSamplesRebuildTheSameMap) {
  // What a saved session keeps (keyframes()) inserted into a new map gives the same map.
  BoxWorld world;
  world.boxes.push_back({{4.0, 2.3, 0.012}, {4.45, 2.75, 0.9}, false, {30, 120, 30}});
  OccupancyMap map;
  insert_all(map, world, wall_path(3));
  OccupancyMap loaded;
  for (const auto& samples : map.keyframes()) loaded.insert(samples);
  EXPECT_EQ(loaded.stats().occupied_voxels, map.stats().occupied_voxels);
  EXPECT_EQ(loaded.stats().free_voxels, map.stats().free_voxels);
  EXPECT_EQ(loaded.occupied_voxels().size(), map.occupied_voxels().size());
  // A keyframe given again replaces the stored one (and rebuilds).
  loaded.insert(map.keyframes().front());
  EXPECT_EQ(loaded.stats().keyframes, 3u);
  EXPECT_EQ(loaded.stats().rebuilds, 1u);
  EXPECT_EQ(loaded.stats().occupied_voxels, map.stats().occupied_voxels);
}

TEST(OccupancyMap, SettlingWhenTheTreeDoublesGivesTheTreeOfSettlingEachKeyframe) {
  // Integrating settles (updates the inner nodes, prunes) only when the tree has doubled; after
  // settle() the octree is the one settled after every keyframe, node for node.
  BoxWorld world;
  world.boxes.push_back({{4.0, 2.3, 0.012}, {4.45, 2.75, 0.9}, false, {30, 120, 30}});
  const PinholeCamera cam = test::make_camera();
  const auto poses = wall_path(6);
  OccupancyMap each, deferred;
  std::size_t unsettled = 0;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const KeyframeDepth kf = world.render(i, poses[i], cam);
    each.insert(kf);
    each.settle();
    deferred.insert(kf);
    if (deferred.octree().size() != each.octree().size()) ++unsettled;
  }
  EXPECT_GT(unsettled, 0u) << "the deferred map was settled after every keyframe too";
  deferred.settle();
  std::ostringstream a, b;
  each.octree().writeBinaryData(a);
  deferred.octree().writeBinaryData(b);
  EXPECT_EQ(a.str(), b.str());
  EXPECT_EQ(deferred.octree().size(), each.octree().size());
  const octomap::OcTree& t = each.octree();
  const octomap::OcTree& u = deferred.octree();
  std::size_t inner = 0;
  for (auto it = t.begin_tree(), end = t.end_tree(); it != end; ++it) {
    if (it.getDepth() == 0) continue;  // search(key, 0) searches to the finest depth
    const octomap::OcTreeNode* other = u.search(it.getKey(), it.getDepth());
    ASSERT_NE(other, nullptr);
    ASSERT_EQ(other->getLogOdds(), it->getLogOdds()) << "depth " << it.getDepth();
    inner += it.isLeaf() ? 0 : 1;
  }
  EXPECT_GT(inner, 0u);
}

TEST(OccupancyMap, RebuildWithHelperThreadsGivesTheMapOfOneThread) {
  // The rebuild's helpers gather keyframes' marks in parallel; the octree takes them in the
  // keyframes' order: node for node and colour for colour the map integrated one by one.
  BoxWorld world;
  world.boxes.push_back({{4.0, 2.3, 0.012}, {4.45, 2.75, 0.9}, false, {30, 120, 30}});
  world.boxes.push_back({{3.6, 1.6, 0.012}, {3.9, 1.9, 1.7}, true});
  world.boxes.push_back({{4.6, 3.1, 0.012}, {5.0, 3.5, 0.8}, false, {90, 20, 160}, true});
  const PinholeCamera cam = test::make_camera();
  const auto poses = wall_path(4);
  std::vector<KeyframeDepth> views;
  for (std::size_t k = 0; k < poses.size(); ++k) views.push_back(world.render(k, poses[k], cam));
  const auto bytes = [](const OccupancyMap& m) {
    std::ostringstream out;
    m.octree().writeBinaryData(out);
    return out.str();
  };
  OccupancyMap incremental;
  for (const KeyframeDepth& view : views) incremental.insert(view);
  incremental.settle();
  const auto colours = [](const OccupancyMap& m) {
    std::vector<std::array<int, 3>> c;
    for (const auto& v : m.occupied_voxels()) c.push_back({v.rgb[0], v.rgb[1], v.rgb[2]});
    return c;
  };
  for (const int threads : {1, 2, 8}) {  // 2: the ring wraps; 8: more helpers than keyframes
    OccupancyOptions options;
    options.rebuild_threads = threads;
    OccupancyMap map(options);
    for (const KeyframeDepth& view : views) map.insert(view);
    map.rebuild();
    map.settle();
    EXPECT_EQ(map.stats().rebuilds, 1u);
    EXPECT_EQ(bytes(map), bytes(incremental)) << threads << " threads";
    EXPECT_EQ(colours(map), colours(incremental)) << threads << " threads";
  }
}

TEST(OccupancyMap, IntegrationAtTheEndGivesTheMapOfTheRebuildAfterACorrection) {
  // "at_end" stores keyframes and corrections and integrates them once: the map a live one has
  // after a correction rebuilt it, node for node and colour for colour.
  BoxWorld world;
  world.boxes.push_back({{4.0, 2.3, 0.012}, {4.45, 2.75, 0.9}, false, {30, 120, 30}});
  world.boxes.push_back({{3.6, 1.6, 0.012}, {3.9, 1.9, 1.7}, true});
  const PinholeCamera cam = test::make_camera();
  const auto poses = wall_path(4);
  OccupancyOptions at_end;
  at_end.integration = "at_end";
  OccupancyMap live, deferred(at_end);
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const KeyframeDepth view = world.render(k, poses[k], cam);
    live.insert(view);
    deferred.insert(view);
  }
  EXPECT_TRUE(deferred.pending());
  EXPECT_EQ(deferred.octree().size(), 0u);  // nothing integrated yet
  // The final bundle adjustment moves every keyframe by 3 cm.
  std::unordered_map<KeyframeId, SE3> moved;
  for (const auto& kf : live.keyframes())
    moved[kf.id] = SE3(kf.T_w_c.quaternion(), kf.T_w_c.translation() + Eigen::Vector3d(0.03, 0, 0));
  EXPECT_TRUE(live.correct(moved));
  EXPECT_TRUE(deferred.correct(moved));
  EXPECT_EQ(deferred.stats().rebuilds, 0u);
  EXPECT_EQ(deferred.stats().integration, "at_end");
  EXPECT_TRUE(deferred.integrate_pending());
  EXPECT_FALSE(deferred.pending());
  EXPECT_FALSE(deferred.integrate_pending());
  live.settle();
  deferred.settle();
  std::ostringstream a, b;
  live.octree().writeBinaryData(a);
  deferred.octree().writeBinaryData(b);
  EXPECT_EQ(a.str(), b.str());
  const auto colours = [](const OccupancyMap& m) {
    std::vector<std::array<int, 3>> c;
    for (const auto& v : m.occupied_voxels()) c.push_back({v.rgb[0], v.rgb[1], v.rgb[2]});
    return c;
  };
  EXPECT_EQ(colours(deferred), colours(live));
  EXPECT_GT(live.stats().occupied_voxels, 100u);
}

/// One keyframe at the origin looking along +z at a wall face-on: a 64 x 48 image (5.5 voxels
/// wide at 3.5 m), every pixel a sample at depth(u, v).
template <typename Depth>
KeyframeSamples wall_samples(Depth&& depth) {
  KeyframeSamples s;
  s.camera = test::make_camera(525.0, 525.0, 31.5, 23.5);
  s.camera.width = 64;
  s.camera.height = 48;
  s.depth_mm = cv::Mat(48, 64, CV_16UC1);
  for (int v = 0; v < 48; ++v)
    for (int u = 0; u < 64; ++u) s.depth_mm.at<std::uint16_t>(v, u) = depth(u, v);
  s.kind = cv::Mat::zeros(48, 64, CV_8UC1);
  return s;
}

TEST(OccupancyMap, ANoiseTailBehindASurfaceIsNotAnObstacle) {
  // The wall at the centre of the voxels from 3.50 to 3.55 m; one pixel in 64 measures it
  // 5 cm too far, in the voxel behind (its centre a voxel behind the wall), where no ray
  // passes to free it.
  const auto tail = [](int u, int v) -> std::uint16_t {
    return u % 8 == 0 && v % 8 == 0 ? 3575 : 3525;
  };
  const Eigen::Vector3d wall(0.0, 0.0, 3.525), behind(0.0, 0.0, 3.575);
  OccupancyMap yielding;
  yielding.insert(wall_samples(tail));
  EXPECT_EQ(yielding.state(wall), VoxelState::kOccupied);
  EXPECT_EQ(yielding.state(behind), VoxelState::kUnknown);
  OccupancyOptions off;
  off.tail_yield_ratio = 0.0;
  OccupancyMap kept(off);
  kept.insert(wall_samples(tail));
  EXPECT_EQ(kept.state(behind), VoxelState::kOccupied);
  // A wall on the boundary of two voxels puts about as many samples in each: both hold it.
  OccupancyMap boundary;
  boundary.insert(
      wall_samples([](int u, int v) -> std::uint16_t { return (u + v) % 2 == 0 ? 3545 : 3555; }));
  EXPECT_EQ(boundary.state({0.0, 0.0, 3.525}), VoxelState::kOccupied);
  EXPECT_EQ(boundary.state({0.0, 0.0, 3.575}), VoxelState::kOccupied);
}

}  // namespace
}  // namespace mcslam::mapping
