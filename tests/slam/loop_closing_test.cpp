// Loop closing and relocalisation through the keyframe database on a rendered loop: every loop
// accepted is a true revisit (ground truth), the correction reduces the drift, and a camera that
// jumps back to the start is relocalised through the database.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "mcslam/eval/metrics.hpp"
#include "mcslam/slam/system.hpp"
#include "mcslam/synth/sequence.hpp"
#include "pipeline.hpp"
#include "support/small_room.hpp"
#include "synthetic_fixture.hpp"

namespace mcslam::slam {
namespace {

using Loop = test::RenderedSequence;

/// A 320 x 240 render of the loop path at its default pace (24 s a lap, 0.9 m/s at most), 1.2
/// laps. Half that lap drifts only 2 cm, hardly above the 6-8 mm tracking floor of these renders;
/// the full lap drifts 5-8 cm, which is what loop closing is for.
const Loop& rendered_loop() {
  static const std::unique_ptr<Loop> loop = [] {
    synth::SynthOptions o = test::small_room(864);
    o.path = synth::CameraPath::kLoop;
    o.loop_period = 24.0;
    o.depth_noise = true;
    return test::render(o);
  }();
  return *loop;
}

SystemOptions options(bool loops) {
  SystemOptions o;
  o.sequential = true;
  o.orb.num_features = 500;
  o.tracker.min_initial_points = 200;
  // Tracking that does not reach back to old keyframes by position (as ORB-SLAM2's, and the
  // default), so that the revisit is left to loop closing.
  o.tracker.spatial_keyframes = 0;
  o.place.loop.enabled = loops;
  // The map as it stands after the run, without the bundle adjustment of the whole map that
  // ends a run (which also reaches across the loop through the points tracking re-found).
  o.mapper.global_ba_iterations = 0;
  return o;
}

/// The ground-truth pose of a keyframe (by its timestamp).
SE3 truth_at(const Trajectory& groundtruth, double timestamp) {
  for (const auto& p : groundtruth)
    if (std::abs(p.timestamp - timestamp) < 1e-4) return p.T_w_c;
  ADD_FAILURE() << "no ground truth at " << timestamp;
  return SE3();
}

struct LoopRun {
  double ate = 0.0;
  int tracked = 0;
  LoopStatistics loops;
};

LoopRun run(bool loops) {
  const Loop& l = rendered_loop();
  System system(l.camera, options(loops));
  LoopRun r;
  for (std::size_t i = 0; i < l.frames.size(); ++i)
    r.tracked +=
        system.process(l.frames[i].rgb, l.frames[i].depth, l.groundtruth[i].timestamp).state ==
                TrackingState::kOk
            ? 1
            : 0;
  system.finish();
  r.ate = eval::evaluate(l.groundtruth, system.trajectory()).ate.translation.rmse;
  r.loops = system.loop_statistics();
  return r;
}

TEST(LoopClosing, ClosesTheLoopAtATrueRevisitAndCorrectsTheDrift) {
  const LoopRun off = run(false);
  const LoopRun on = run(true);
  const Loop& l = rendered_loop();
  int accepted = 0;
  for (const LoopEvent& e : on.loops.events) {
    std::printf("loop %llu-%llu accepted %d inliers %d correction %.4f m %.3f deg fused %d %s\n",
                static_cast<unsigned long long>(e.keyframe),
                static_cast<unsigned long long>(e.matched), e.accepted ? 1 : 0, e.inliers,
                e.correction_m, e.correction_deg, e.fused_points, e.reason.c_str());
    if (!e.accepted) continue;
    ++accepted;
    // A true revisit: the two keyframes' cameras were close and looked the same way.
    const SE3 a = truth_at(l.groundtruth, e.timestamp);
    const SE3 b = truth_at(l.groundtruth, e.matched_timestamp);
    EXPECT_LT((a.translation() - b.translation()).norm(), 0.5) << e.keyframe << "-" << e.matched;
    EXPECT_LT(rotation_angle(a.quaternion() * b.quaternion().conjugate()), 30.0 * M_PI / 180.0);
    EXPECT_GT(e.timestamp - e.matched_timestamp, 12.0);  // half a lap or more apart
  }
  EXPECT_GE(accepted, 1);
  EXPECT_EQ(on.tracked, static_cast<int>(l.frames.size()));
  // Measured: 0.0113 m with loop closing, 0.0542 m without (0.21x); the target is 1/3.
  EXPECT_LT(on.ate, off.ate / 3.0) << "with loops " << on.ate << ", without " << off.ate;
  std::printf("synthetic loop: ATE %.4f m with loop closing, %.4f m without; %d loop(s)\n", on.ate,
              off.ate, accepted);
}

TEST(LoopClosing, RelocalisesThroughTheDatabaseAfterAJumpBackToTheStart) {
  const Loop& l = rendered_loop();
  SystemOptions o = options(false);
  System system(l.camera, o);
  for (int i = 0; i < 200; ++i)
    system.process(l.frames[static_cast<std::size_t>(i)].rgb,
                   l.frames[static_cast<std::size_t>(i)].depth,
                   l.groundtruth[static_cast<std::size_t>(i)].timestamp);
  // The camera is back where it started (a second pass), 200 frames of motion later.
  bool relocalised = false;
  for (int i = 0; i < 10 && !relocalised; ++i) {
    const auto& f = l.frames[static_cast<std::size_t>(i)];
    const FrameResult r = system.process(f.rgb, f.depth, 100.0 + i / 30.0);
    if (!r.relocalised) continue;
    relocalised = true;
    ASSERT_TRUE(r.relocalisation.has_value());
    EXPECT_TRUE(r.relocalisation->by_database);
    ASSERT_TRUE(r.T_w_c.has_value());
    // Where the start was mapped (the map's frame is the first camera's).
    EXPECT_LT((r.T_w_c->translation() -
               (l.groundtruth[0].T_w_c.inverse() * l.groundtruth[static_cast<std::size_t>(i)].T_w_c)
                   .translation())
                  .norm(),
              0.05);
  }
  EXPECT_TRUE(relocalised);
}

// The loop closer on its own (no System): fed each new keyframe of the tracker and the mapper
// run inline, it finds the revisit, corrects the map through the mapper and leaves the keyframes
// nearer the truth than the drift they had.
TEST(LoopCloser, OnItsOwnClosesTheLoopAndPullsTheKeyframesToTheTruth) {
  const Loop& l = rendered_loop();
  const SystemOptions o = options(true);
  ASSERT_FALSE(o.place.vocabulary.empty());
  auto vocabulary =
      std::make_shared<const place::Vocabulary>(place::Vocabulary::load(o.place.vocabulary));
  test::Pipeline p(l, o, vocabulary);
  for (int i = 0; i < static_cast<int>(l.frames.size()); ++i)
    ASSERT_EQ(p.track(i).state, TrackingState::kOk) << i;
  const LoopStatistics stats = p.loops->statistics();
  int accepted = 0;
  for (const LoopEvent& e : stats.events) {
    if (!e.accepted) continue;
    ++accepted;
    const SE3 a = truth_at(l.groundtruth, e.timestamp);
    const SE3 b = truth_at(l.groundtruth, e.matched_timestamp);
    EXPECT_LT((a.translation() - b.translation()).norm(), 0.5) << e.keyframe << "-" << e.matched;
    EXPECT_FALSE(e.pose_graph_failed);
  }
  EXPECT_GE(accepted, 1);
  EXPECT_EQ(stats.full_ba_failed, 0);
  // The keyframes against the truth, aligned as a whole (the map's frame is the first camera's).
  Trajectory keyframes;
  for (const auto& [id, kf] : p.map.keyframes()) keyframes.push_back({kf.timestamp, kf.T_w_c()});
  std::sort(keyframes.begin(), keyframes.end(),
            [](const StampedPose& a, const StampedPose& b) { return a.timestamp < b.timestamp; });
  const double ate = eval::evaluate(l.groundtruth, keyframes).ate.translation.rmse;
  std::printf("loop closer on its own: %d loop(s), keyframe ATE %.4f m\n", accepted, ate);
  // System runs measure 0.011 m on every frame with loop closing and 0.054 m without.
  EXPECT_LT(ate, 0.02);
}

// The default mode: the mapper, the loop closer and its full bundle adjustment on their threads
// while frames are tracked. A frame tracked while a correction is applied must see the map
// either before or after it, never half moved: every frame's final pose (relative to its
// reference keyframe) stays near the truth around each correction, and no frame is lost. Twice,
// as the threads interleave differently on each run.
TEST(LoopClosing, ThreadedCorrectionsKeepEveryFrameAroundThemOnTheTruth) {
  const Loop& l = rendered_loop();
  for (int attempt = 0; attempt < 2; ++attempt) {
    SystemOptions o = options(true);
    o.sequential = false;
    System system(l.camera, o);
    int tracked = 0;
    for (std::size_t i = 0; i < l.frames.size(); ++i)
      tracked +=
          system.process(l.frames[i].rgb, l.frames[i].depth, l.groundtruth[i].timestamp).state ==
                  TrackingState::kOk
              ? 1
              : 0;
    system.finish();
    EXPECT_EQ(tracked, static_cast<int>(l.frames.size())) << "run " << attempt;
    const LoopStatistics loops = system.loop_statistics();
    std::vector<double> corrected_at;
    for (const LoopEvent& e : loops.events)
      if (e.accepted) corrected_at.push_back(e.timestamp);
    EXPECT_GE(corrected_at.size(), 1u) << "run " << attempt;
    EXPECT_EQ(system.solver_statistics().pose_graph_failures, 0);
    // Per-frame error of the final trajectory, aligned to the truth as a whole.
    const Trajectory estimate = system.trajectory();
    const auto pairs = eval::associate(l.groundtruth, estimate, 0.02);
    std::vector<Eigen::Vector3d> est, gt;
    for (const auto& [g, e] : pairs) {
      est.push_back(estimate[e].T_w_c.translation());
      gt.push_back(l.groundtruth[g].T_w_c.translation());
    }
    const SE3 T_gt_est = eval::align_se3(est, gt);
    double worst_near = 0.0, sum_sq = 0.0;
    for (std::size_t k = 0; k < pairs.size(); ++k) {
      const double error = (T_gt_est * est[k] - gt[k]).norm();
      sum_sq += error * error;
      const double t = estimate[pairs[k].second].timestamp;
      for (double c : corrected_at)
        if (t > c - 1.0 && t < c + 2.0) worst_near = std::max(worst_near, error);
    }
    const double ate = std::sqrt(sum_sq / static_cast<double>(pairs.size()));
    std::printf(
        "threaded loop run %d: ATE %.4f m, worst frame within [-1, +2] s of a correction "
        "%.4f m, %zu correction(s)\n",
        attempt, ate, worst_near, corrected_at.size());
    // Sequential runs measure 0.011 m; a frame tracked on a half-corrected map is off by a part
    // of the correction (5-8 cm here).
    EXPECT_LT(ate, 0.02) << "run " << attempt;
    EXPECT_LT(worst_near, 0.03) << "run " << attempt;
  }
}

}  // namespace
}  // namespace mcslam::slam
