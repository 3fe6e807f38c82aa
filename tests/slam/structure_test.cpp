// Lines and planes in the whole system: the low-texture room that points alone cannot track,
// the feature switches, and the per-point plane labels.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "mcslam/eval/metrics.hpp"
#include "mcslam/slam/frame.hpp"
#include "mcslam/slam/system.hpp"
#include "synthetic_fixture.hpp"

namespace mcslam::slam {
namespace {

struct StructureRun {
  Trajectory trajectory;
  int tracked = 0;
  std::size_t lines_in_map = 0;
  std::size_t planes_in_map = 0;
};

StructureRun run_structure(const test::RenderedSequence& seq, const FeatureSwitches& use) {
  SystemOptions options;
  options.sequential = true;
  options.use = use;
  System system(seq.camera, options);
  StructureRun r;
  for (std::size_t i = 0; i < seq.frames.size(); ++i) {
    const auto& f = seq.frames[i];
    r.tracked +=
        system.process(f.rgb, f.depth, seq.groundtruth[i].timestamp).state == TrackingState::kOk
            ? 1
            : 0;
  }
  system.finish();
  r.trajectory = system.trajectory();
  r.lines_in_map = system.map().num_lines();
  r.planes_in_map = system.map().num_planes();
  return r;
}

double ate(const test::RenderedSequence& seq, const StructureRun& r) {
  if (r.trajectory.size() < 3) return 1e9;
  return eval::evaluate(seq.groundtruth, r.trajectory).ate.translation.rmse;
}

const test::RenderedSequence& low_texture_room() {
  return test::rendered_sequence(150, true, 1.0, 1, synth::TextureLevel::kLow);
}

TEST(Structure, LowTextureRoomNeedsLinesAndPlanes) {
  const auto& seq = low_texture_room();
  const StructureRun points = run_structure(seq, {true, false, false});
  const StructureRun all = run_structure(seq, {true, true, true});
  std::printf(
      "low-texture room: points %d/150 tracked (ATE %.4f), points+lines+planes %d/150 "
      "(ATE %.4f), map %zu lines %zu planes\n",
      points.tracked, ate(seq, points), all.tracked, ate(seq, all), all.lines_in_map,
      all.planes_in_map);
  EXPECT_LT(points.tracked, 75);  // the point-only baseline cannot track it
  EXPECT_GE(all.tracked, 148);
  EXPECT_LT(ate(seq, all), 0.03);
  EXPECT_GT(all.lines_in_map, 10u);
  EXPECT_GE(all.planes_in_map, 2u);
}

TEST(Structure, EveryFeatureCombinationTracksTheTexturedRoom) {
  const auto& seq = test::rendered_sequence(90, true);
  for (const FeatureSwitches use :
       {FeatureSwitches{true, true, false}, FeatureSwitches{true, false, true},
        FeatureSwitches{true, true, true}}) {
    const StructureRun r = run_structure(seq, use);
    EXPECT_GE(r.tracked, 89) << use.points << use.lines << use.planes;
    EXPECT_LT(ate(seq, r), 0.015) << use.points << use.lines << use.planes;
    EXPECT_EQ(r.lines_in_map > 0, use.lines);
    EXPECT_EQ(r.planes_in_map > 0, use.planes);
  }
}

TEST(Structure, PointsKnowTheirPlane) {
  const auto& seq = test::rendered_sequence(90, false);
  SystemOptions options;
  FrameBuilder builder(seq.camera, options);
  const auto& f = seq.frames[30];
  cv::Mat gray;
  cv::cvtColor(f.rgb, gray, cv::COLOR_BGR2GRAY);
  const Frame frame = builder.build(0, 0.0, gray, f.depth);
  ASSERT_FALSE(frame.features->planes.empty());
  int on_plane = 0;
  for (const auto& p : frame.features->points) {
    if (p.plane < 0) continue;
    ++on_plane;
    const auto& plane = frame.features->planes[static_cast<std::size_t>(p.plane)];
    const Eigen::Vector3d p_c = seq.camera.unproject(p.keypoint.uv.cast<double>(), p.depth);
    EXPECT_LT(std::abs(plane.distance(p_c)), options.tracker.on_plane_distance);
  }
  // Walls and floor carry most of the room's texture.
  EXPECT_GT(on_plane, static_cast<int>(frame.features->points.size()) / 3);
}

}  // namespace
}  // namespace mcslam::slam
