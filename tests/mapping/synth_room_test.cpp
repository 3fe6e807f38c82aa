// The occupancy map of mcslam's own synthetic rooms (synth::make_room_scene, textured, rendered
// at 640 x 480): a person walking, four people, and the chair sliding on the floor, with the
// exact static geometry known. The people's pixels are the dynamic mask (their labels); the chair
// is not masked (an object that slides on the floor is an obstacle where it is).

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "mcslam/mapping/evaluation.hpp"
#include "mcslam/mapping/occupancy_map.hpp"
#include "mcslam/synth/renderer.hpp"
#include "mcslam/synth/scene.hpp"

namespace mcslam::mapping {
namespace {

struct SynthRun {
  synth::SynthOptions options;
  synth::Scene scene;
  Trajectory path;
  std::vector<int> keyframes;  ///< frame indices

  explicit SynthRun(const synth::SynthOptions& o)
      : options(o), scene(synth::make_room_scene(o)), path(synth::camera_path(o)) {}

  double time(int frame) const { return frame / options.fps; }

  /// The room's six planes and the static objects' boxes.
  std::vector<StaticSurface> static_surfaces() const {
    std::vector<StaticSurface> s;
    for (int a = 0; a < 3; ++a) {
      s.push_back(StaticSurface::plane(Eigen::Vector3d::Unit(a), -scene.room_min[a]));
      s.push_back(StaticSurface::plane(-Eigen::Vector3d::Unit(a), scene.room_max[a]));
    }
    for (const auto& object : scene.objects)
      if (object.motion == synth::MotionKind::kStatic)
        s.push_back(StaticSurface::box(object.pose_at(0.0), object.half_extents));
    return s;
  }

  /// The keyframes rendered, the people's pixels in the dynamic mask.
  std::vector<KeyframeDepth> render(bool depth_noise = false) const {
    synth::RenderOptions render_options;
    render_options.depth_noise = depth_noise;
    const synth::Renderer renderer(scene, options.camera(), render_options);
    std::vector<KeyframeDepth> out;
    for (int frame : keyframes) {
      const synth::RenderedFrame f = renderer.render(path[frame].T_w_c, time(frame));
      KeyframeDepth kf;
      kf.id = static_cast<KeyframeId>(frame);
      kf.T_w_c = path[frame].T_w_c;
      kf.camera = options.camera();
      kf.depth = f.depth;
      kf.colour = f.rgb;
      kf.dynamic_mask = cv::Mat::zeros(f.depth.size(), CV_8UC1);
      for (int v = 0; v < f.labels.rows; ++v)
        for (int u = 0; u < f.labels.cols; ++u) {
          const int label = f.labels.at<std::int16_t>(v, u);
          if (label >= 0 && scene.objects[label].class_name == "person")
            kf.dynamic_mask.at<std::uint8_t>(v, u) = 255;
        }
      out.push_back(kf);
    }
    return out;
  }
};

OccupancyMap build(const std::vector<KeyframeDepth>& keyframes, bool masks) {
  OccupancyMap map;
  for (KeyframeDepth kf : keyframes) {
    if (!masks) kf.dynamic_mask.release();
    map.insert(kf);
  }
  return map;
}

synth::SynthOptions people_options(int people) {
  synth::SynthOptions o;
  o.frames = 300;
  o.dynamic.enabled = true;
  o.dynamic.chair = false;
  o.dynamic.people = people;
  return o;
}

void report(const char* name, const MapQuality& masked, const MapQuality& unmasked,
            const OccupancyStats& stats) {
  std::printf(
      "[ synth ] %s, %zu keyframes: ghost rate %.4f with masks (%zu of %zu), %.4f "
      "without (%zu of %zu); completeness %.4f (%zu of %zu); insert median %.1f ms, "
      "p95 %.1f ms; %.0f bytes per keyframe, octree %zu bytes\n",
      name, stats.keyframes, masked.ghost_rate, masked.ghosts, masked.occupied, unmasked.ghost_rate,
      unmasked.ghosts, unmasked.occupied, masked.completeness, masked.surface_occupied,
      masked.surface_seen, stats.integration_ms.median, stats.integration_ms.p95,
      stats.keyframe_bytes_each(), stats.octree_bytes);
}

/// Occupied voxels (above the floor's) inside `object`'s box at time t, and outside the boxes at
/// the times in `except`.
std::size_t occupied_in_box(const OccupancyMap& map, const synth::SceneObject& object, double t,
                            const std::vector<double>& except = {}) {
  const auto inside = [&](const Eigen::Vector3d& p_w, double when) {
    const Eigen::Vector3d p = object.pose_at(when).inverse() * p_w;
    return (p.array().abs() <= object.half_extents.array()).all();
  };
  std::size_t n = 0;
  for (const auto& v : map.occupied_voxels()) {
    if (v.centre.z() < 0.1 || !inside(v.centre, t)) continue;
    bool excluded = false;
    for (double when : except) excluded = excluded || inside(v.centre, when);
    if (!excluded) ++n;
  }
  return n;
}

TEST(SynthRoom, ChairSlidingOnTheFloorIsWhereItIsNow) {
  // The chair stands still to 1 s, then slides back and forth along x (1.57-2.62 m, 0.5 m/s
  // peak, turning +-25 degrees), crossing its first place (x = 2.10) twice every 7 s;
  // keyframes every 15 frames to frame 390 (13 s), when it is at x = 1.60.
  synth::SynthOptions o;
  o.frames = 391;
  o.dynamic.enabled = true;
  o.dynamic.person = false;
  SynthRun run(o);
  for (int frame = 0; frame <= 390; frame += 15) run.keyframes.push_back(frame);
  std::vector<KeyframeDepth> keyframes = run.render();
  const std::size_t chair = run.scene.objects.size() - 1;
  ASSERT_EQ(run.scene.objects[chair].class_name, "chair");
  const auto& object = run.scene.objects[chair];
  // The chair's pixels as a mover's (the object stage's constrained mover).
  const synth::Renderer renderer(run.scene, o.camera());
  for (auto& kf : keyframes) {
    const auto f = renderer.render(kf.T_w_c, run.time(static_cast<int>(kf.id)));
    kf.mover_mask = f.labels == static_cast<int>(chair);
  }
  OccupancyMap as_mover;
  for (const auto& kf : keyframes) as_mover.insert(kf);
  OccupancyMap as_static;
  for (KeyframeDepth kf : keyframes) {
    kf.mover_mask.release();
    as_static.insert(kf);
  }
  const double end = run.time(390);
  const std::vector<double> recent = {run.time(360), run.time(375), end};
  const std::size_t now_mover = occupied_in_box(as_mover, object, end);
  const std::size_t first_mover = occupied_in_box(as_mover, object, 0.0, recent);
  const std::size_t first_static = occupied_in_box(as_static, object, 0.0, recent);
  std::printf(
      "[ synth ] chair sliding, %zu keyframes: %zu occupied voxels where it is now; at "
      "its first place %zu as a mover, %zu as a static object\n",
      keyframes.size(), now_mover, first_mover, first_static);
  // Where it is now, it is an obstacle. Its first place, which it crossed again and again: as
  // a mover, what remains (17 voxels, at its far corner) is what no keyframe saw through since
  // it last passed (at frame 360 the chair itself stands between that corner and the camera);
  // as a static object, 9 keyframes must see through each voxel before it is free.
  EXPECT_GT(now_mover, 50u);
  EXPECT_LT(first_mover * 4, first_static);
}

TEST(SynthRoom, PersonWalkingWithMasksLeavesNoGhosts) {
  SynthRun run(people_options(1));
  for (int frame = 0; frame < 300; frame += 20) run.keyframes.push_back(frame);
  const auto surfaces = run.static_surfaces();
  const auto keyframes = run.render();
  const OccupancyMap map = build(keyframes, true);
  const MapQuality masked = evaluate_map(map, surfaces);
  const MapQuality unmasked = evaluate_map(build(keyframes, false), surfaces);
  report("person walking", masked, unmasked, map.stats());
  EXPECT_LE(masked.ghost_rate, 0.01);
  EXPECT_GE(masked.completeness, 0.95);
  EXPECT_GT(unmasked.ghost_rate, masked.ghost_rate);
}

TEST(SynthRoom, FourPeopleWithKinectLikeDepth) {
  SynthRun run(people_options(4));
  for (int frame = 0; frame < 300; frame += 20) run.keyframes.push_back(frame);
  const auto surfaces = run.static_surfaces();
  const auto keyframes = run.render(true);
  const OccupancyMap map = build(keyframes, true);
  const MapQuality masked = evaluate_map(map, surfaces);
  const MapQuality unmasked = evaluate_map(build(keyframes, false), surfaces);
  report("four people, Kinect-like depth", masked, unmasked, map.stats());
  EXPECT_LE(masked.ghost_rate, 0.01);
  EXPECT_GE(masked.completeness, 0.95);
  EXPECT_GT(unmasked.ghost_rate, masked.ghost_rate);
}

}  // namespace
}  // namespace mcslam::mapping
