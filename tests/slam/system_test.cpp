#include "mcslam/slam/system.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <thread>

#include "mcslam/core/error.hpp"
#include "mcslam/core/thread_failure.hpp"
#include "mcslam/eval/metrics.hpp"
#include "synthetic_fixture.hpp"

namespace mcslam::slam {
namespace {

SystemOptions sequential_options() {
  SystemOptions o;
  o.sequential = true;
  return o;
}

struct RunResult {
  Trajectory trajectory;
  int tracked = 0;
  int lost = 0;
  int relocalised = 0;
};

RunResult run(const test::RenderedSequence& seq, const SystemOptions& options, int first = 0,
              int last = -1) {
  System system(seq.camera, options);
  RunResult r;
  const int end = last < 0 ? static_cast<int>(seq.frames.size()) : last;
  for (int i = first; i < end; ++i) {
    const auto& f = seq.frames[static_cast<std::size_t>(i)];
    const FrameResult fr =
        system.process(f.rgb, f.depth, seq.groundtruth[static_cast<std::size_t>(i)].timestamp);
    r.tracked += fr.state == TrackingState::kOk ? 1 : 0;
    r.lost += fr.state == TrackingState::kLost ? 1 : 0;
    r.relocalised += fr.relocalised ? 1 : 0;
  }
  system.finish();
  r.trajectory = system.trajectory();
  return r;
}

TEST(System, TracksSyntheticRoomToMillimetres) {
  const auto& seq = test::rendered_sequence(150, false);
  const RunResult r = run(seq, sequential_options());
  EXPECT_EQ(r.tracked, 150);
  const auto report = eval::evaluate(seq.groundtruth, r.trajectory);
  EXPECT_LT(report.ate.translation.rmse, 0.005) << eval::to_text(report);
  EXPECT_LT(report.rpe_frame.rotation.rmse, 0.002);
}

// The frame after the map's first has no velocity to predict it: a camera that moved far since
// (here frame K of the room, the first after frame 0) has left the matching window around its
// last pose, and the pose is found by matching descriptors against the keyframe instead.
// Measured: frames 4, 8, 12 (4, 8, 11 degrees on) found to 1.6, 0.4, 1.7 mm; by the window
// around the last pose alone 2.2 mm, then lost at frame 8.
TEST(System, TheFrameAfterTheFirstIsFoundWithoutAVelocity) {
  const auto& seq = test::rendered_sequence(150, false);
  for (const std::size_t k : {std::size_t{4}, std::size_t{8}, std::size_t{12}}) {
    System system(seq.camera, sequential_options());
    for (const std::size_t i : {std::size_t{0}, k}) {
      const FrameResult r =
          system.process(seq.frames[i].rgb, seq.frames[i].depth, seq.groundtruth[i].timestamp);
      ASSERT_TRUE(r.T_w_c.has_value()) << k;
    }
    const Trajectory online = system.online_trajectory();
    // The camera's motion from frame 0 to frame k, estimated against the ground truth's.
    const SE3 truth = seq.groundtruth[0].T_w_c.inverse() * seq.groundtruth[k].T_w_c;
    const SE3 estimate = online[0].T_w_c.inverse() * online[1].T_w_c;
    const SE3 error = truth.inverse() * estimate;
    std::printf("frame %zu after frame 0: moved %.1f mm, %.2f deg; error %.2f mm, %.3f deg\n", k,
                truth.translation().norm() * 1e3, rotation_angle(truth.quaternion()) * 180 / M_PI,
                error.translation().norm() * 1e3, rotation_angle(error.quaternion()) * 180 / M_PI);
    EXPECT_LT(error.translation().norm(), 0.003) << k;
  }
}

TEST(System, TracksSyntheticRoomWithKinectNoiseAndFastMotion) {
  const auto& seq = test::rendered_sequence(120, true, 2.5);
  const RunResult r = run(seq, sequential_options());
  EXPECT_GE(r.tracked, 119);
  const auto report = eval::evaluate(seq.groundtruth, r.trajectory);
  EXPECT_LT(report.ate.translation.rmse, 0.012) << eval::to_text(report);
}

// A live camera drops frames when the pipeline falls behind: after a gap the constant-velocity
// prediction must span the frame's own interval, not the last step's. Fast motion (speed 2.5),
// every frame up to 20, then two frames in a row and three dropped (the velocity of one step
// predicts a gap of four, 133 ms and ~8 degrees of turn). Measured: 60 of 60 frames tracked, 389
// pose inliers on a frame after a gap; with one step's motion as the prediction 52 of 60 and 239.
TEST(System, TracksAcrossDroppedFramesWithTheMotionOverTheGap) {
  const auto& seq = test::rendered_sequence(120, true, 2.5);
  System system(seq.camera, sequential_options());
  int tracked = 0, frames = 0, inliers_after_gaps = 0, gaps = 0;
  for (int i = 0; i < static_cast<int>(seq.frames.size()); i += i < 20 || i % 5 == 0 ? 1 : 4) {
    const auto& f = seq.frames[static_cast<std::size_t>(i)];
    const FrameResult fr =
        system.process(f.rgb, f.depth, seq.groundtruth[static_cast<std::size_t>(i)].timestamp);
    ++frames;
    tracked += fr.state == TrackingState::kOk ? 1 : 0;
    if (i > 20 && i % 5 == 0) {  // the frame after a gap
      inliers_after_gaps += fr.inliers;
      ++gaps;
    }
  }
  system.finish();
  const auto report = eval::evaluate(seq.groundtruth, system.trajectory());
  std::printf("after gaps: %d of %d frames tracked, %.0f pose inliers a frame, ATE %.2f mm\n",
              tracked, frames, static_cast<double>(inliers_after_gaps) / gaps,
              report.ate.translation.rmse * 1e3);
  EXPECT_EQ(tracked, frames);
  EXPECT_LT(report.ate.translation.rmse, 0.012) << eval::to_text(report);
}

// With tracker.pose_filter on, the online pose is the frame's own pose fused with the motion
// model; tracking and the final trajectory go on from the frame's own pose, so that trajectory()
// is the same with or without the filter, and the online pose's frame-to-frame error (RPE over
// one frame) is smaller with it. A lag leaves both as they are and adds the lagged poses, one per
// tracked frame, smoother still. Measured: 1.94 mm filtered, 2.18 not, 1.76 lagged by 5 frames;
// ATE 4.92, 4.56 and 4.48 mm.
TEST(System, TheOnlinePoseIsFilteredAndTheFinalTrajectoryIsNot) {
  const auto& seq = test::rendered_sequence(120, true, 2.5);
  struct Out {
    Trajectory online, final_poses, lagged;
  };
  const auto online_run = [&](bool filter, int lag) {
    SystemOptions options = sequential_options();
    options.tracker.pose_filter.enabled = filter;
    options.tracker.pose_filter.lag = lag;
    // The rendered room's noise is the optimiser's own model (1 px, Kinect-like depth): its
    // covariance as it is. (At the default 6 this fast camera, 2.5 times the usual speed,
    // outruns the densities, adaptive as they are: 3.0 mm instead of 2.1, ATE 10.6 mm instead of
    // 3.4; docs/tracking.md.)
    options.tracker.pose_filter.measurement_noise_scale = 1.0;
    System system(seq.camera, options);
    std::size_t given_out = 0;
    for (std::size_t i = 0; i < seq.frames.size(); ++i) {
      const FrameResult r =
          system.process(seq.frames[i].rgb, seq.frames[i].depth, seq.groundtruth[i].timestamp);
      if (r.lagged) {
        EXPECT_EQ(r.lagged->timestamp, seq.groundtruth[given_out].timestamp);
        ++given_out;
      }
    }
    EXPECT_EQ(given_out, lag > 0 ? seq.frames.size() - lag : 0u);
    system.finish();
    return Out{system.online_trajectory(), system.trajectory(), system.lagged_trajectory()};
  };
  const Out off = online_run(false, 0);
  const Out on = online_run(true, 0);
  const Out lagged = online_run(true, 5);
  const auto expect_same = [](const Trajectory& a, const Trajectory& b) {
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t i = 0; i < a.size(); ++i) {
      EXPECT_EQ(a[i].T_w_c.translation(), b[i].T_w_c.translation()) << i;
      EXPECT_EQ(a[i].T_w_c.quaternion().coeffs(), b[i].T_w_c.quaternion().coeffs()) << i;
    }
  };
  expect_same(on.final_poses, off.final_poses);
  expect_same(lagged.final_poses, off.final_poses);
  expect_same(lagged.online, on.online);
  EXPECT_TRUE(on.lagged.empty());
  ASSERT_EQ(lagged.lagged.size(), lagged.online.size());
  for (std::size_t i = 0; i < lagged.online.size(); ++i)
    EXPECT_EQ(lagged.lagged[i].timestamp, lagged.online[i].timestamp);
  const auto e_off = eval::evaluate(seq.groundtruth, off.online);
  const auto e_on = eval::evaluate(seq.groundtruth, on.online);
  const auto e_lag = eval::evaluate(seq.groundtruth, lagged.lagged);
  std::printf(
      "online RPE over one frame %.2f mm filtered, %.2f mm not, %.2f mm lagged by 5; ATE %.2f / "
      "%.2f / %.2f mm\n",
      e_on.rpe_frame.translation.rmse * 1e3, e_off.rpe_frame.translation.rmse * 1e3,
      e_lag.rpe_frame.translation.rmse * 1e3, e_on.ate.translation.rmse * 1e3,
      e_off.ate.translation.rmse * 1e3, e_lag.ate.translation.rmse * 1e3);
  EXPECT_LT(e_on.rpe_frame.translation.rmse, 0.9 * e_off.rpe_frame.translation.rmse);
  EXPECT_LT(e_on.ate.translation.rmse, 1.25 * e_off.ate.translation.rmse);
  EXPECT_LT(e_lag.rpe_frame.translation.rmse, e_on.rpe_frame.translation.rmse);
  EXPECT_LT(e_lag.ate.translation.rmse, e_on.ate.translation.rmse);
}

TEST(System, ThreadedMappingTracksToo) {
#ifdef MCSLAM_TSAN
  // Under ThreadSanitizer the run is for its threads (60 frames: keyframes and local bundle
  // adjustments while the tracker reads the map; 150 took 69 s there); the release build checks
  // the accuracy of the whole 150.
  constexpr int kFrames = 60;
#else
  constexpr int kFrames = 150;
#endif
  const auto& seq = test::rendered_sequence(kFrames, false);
  SystemOptions options;
  options.sequential = false;
  const RunResult r = run(seq, options);
  EXPECT_EQ(r.tracked, kFrames);
  EXPECT_LT(eval::evaluate(seq.groundtruth, r.trajectory).ate.translation.rmse, 0.01);
}

// system.wait_for_keyframe_points: a keyframe handed to an idle mapper is in the map, with the
// points it created, when process() returns (the wait is timed as keyframe_wait); off, no frame
// waits.
TEST(System, AKeyframeHandedToAnIdleMapperIsInTheMapWhenTheFrameReturns) {
  const auto& seq = test::rendered_sequence(60, false);
#ifdef MCSLAM_TSAN
  const std::vector<bool> settings = {true};  // the waiting's threads (the other is a plain run)
#else
  const std::vector<bool> settings = {true, false};
#endif
  for (const bool wait : settings) {
    SystemOptions options;
    options.sequential = false;
    options.wait_for_keyframe_points = wait;
    System system(seq.camera, options);
    int waited = 0;
    for (std::size_t i = 0; i < seq.frames.size(); ++i) {
      const double t = seq.groundtruth[i].timestamp;
      const FrameResult r = system.process(seq.frames[i].rgb, seq.frames[i].depth, t);
      const bool timed = std::any_of(r.times.stages.begin(), r.times.stages.end(),
                                     [](const auto& s) { return s.first == "keyframe_wait"; });
      if (!wait) {
        EXPECT_FALSE(timed) << i;
        continue;
      }
      if (!timed) continue;
      EXPECT_TRUE(r.keyframe) << i;
      ++waited;
      auto lock = system.map().read_lock();
      const map::KeyFrame* inserted = nullptr;
      for (const auto& [id, kf] : system.map().keyframes())
        if (kf.timestamp == t) inserted = &kf;
      ASSERT_NE(inserted, nullptr) << "frame " << i;
      EXPECT_GT(std::count_if(inserted->landmarks.begin(), inserted->landmarks.end(),
                              [&](map::PointId p) {
                                const map::MapPoint* mp = system.map().point(p);
                                return mp != nullptr && mp->observations.count(inserted->id) != 0;
                              }),
                50)
          << "frame " << i;
    }
    system.finish();
    if (wait) {
      EXPECT_GE(waited, 2);
    }
  }
}

// tracker.keyframe_interval: a keyframe once that long has passed since the last one, while
// tracking, whatever share of the reference keyframe's landmarks the frame still sees. The room
// at half the usual speed leaves ORB-SLAM2's rule alone longer gaps; with 0.5 s none is longer
// than the interval and a frame (sequential: the mapper is always idle). Measured: 2.00 s and 6
// keyframes by the rule alone, 0.53 s and 9 with 0.5 s.
TEST(System, AKeyframeIsDueOnceTheIntervalHasPassed) {
  const auto& seq = test::rendered_sequence(90, true, 0.5);
  const auto longest_gap = [&](double interval, int* keyframes) {
    SystemOptions options = sequential_options();
    options.tracker.keyframe_interval = interval;
    System system(seq.camera, options);
    double last = -1.0, longest = 0.0;
    *keyframes = 0;
    for (std::size_t i = 0; i < seq.frames.size(); ++i) {
      const double t = seq.groundtruth[i].timestamp;
      const FrameResult r = system.process(seq.frames[i].rgb, seq.frames[i].depth, t);
      EXPECT_EQ(r.state, TrackingState::kOk) << i;
      if (!r.keyframe) continue;
      if (last >= 0.0) longest = std::max(longest, t - last);
      last = t;
      ++*keyframes;
    }
    return longest;
  };
  int rule_only = 0, with_interval = 0;
  const double gap_rule = longest_gap(0.0, &rule_only);
  const double gap_interval = longest_gap(0.5, &with_interval);
  std::printf(
      "longest gap between keyframes: %.2f s (%d keyframes) by the rule alone, %.2f s (%d) "
      "with 0.5 s\n",
      gap_rule, rule_only, gap_interval, with_interval);
  EXPECT_GT(gap_rule, 0.5 + 1.5 / 30.0);
  EXPECT_LE(gap_interval, 0.5 + 1.5 / 30.0);
  EXPECT_GT(with_interval, rule_only);
}

// New map points take their colour from their keyframe's image, undistorted (by the mapper, on
// its thread): the colour at the keypoint in System::undistort's image, not in the raw one.
TEST(System, NewPointsTakeTheirColourFromTheUndistortedImage) {
  const auto& seq = test::rendered_sequence(3, false);
  PinholeCamera camera = seq.camera;
  camera.distortion = {0.05, 0.0, 0.0, 0.0, 0.0};
  System system(camera, sequential_options());
  system.process(seq.frames[0].rgb, seq.frames[0].depth, seq.groundtruth[0].timestamp);
  const cv::Mat expected = system.undistort(seq.frames[0].rgb);
  const map::Map& map = system.map();
  ASSERT_EQ(map.num_keyframes(), 1u);
  const map::KeyFrame& kf = map.keyframes().begin()->second;
  int checked = 0, moved = 0;
  for (const auto& [id, point] : map.points()) {
    const auto seen = point.observations.find(kf.id);
    ASSERT_NE(seen, point.observations.end());
    const Eigen::Vector2f uv =
        kf.features->points[static_cast<std::size_t>(seen->second)].keypoint.uv;
    const int x = std::clamp(static_cast<int>(std::lround(uv.x())), 0, expected.cols - 1);
    const int y = std::clamp(static_cast<int>(std::lround(uv.y())), 0, expected.rows - 1);
    const cv::Vec3b bgr = expected.at<cv::Vec3b>(y, x);
    EXPECT_EQ(point.color, (std::array<std::uint8_t, 3>{bgr[2], bgr[1], bgr[0]})) << id;
    moved += seq.frames[0].rgb.at<cv::Vec3b>(y, x) != bgr ? 1 : 0;
    ++checked;
  }
  EXPECT_GT(checked, 50);
  // The distortion moves the texture under most keypoints: the raw image would colour them
  // otherwise.
  EXPECT_GT(moved, checked / 2);
}

// The trajectory and the statistics may be read from another thread (a viewer, a ROS publisher)
// while frames are processed: ThreadSanitizer checks it (the readers copy the frame records
// under their own lock).
TEST(System, TrajectoryMayBeReadFromAnotherThreadWhileFramesAreProcessed) {
  const auto& seq = test::rendered_sequence(60, false);
  SystemOptions options;
  options.sequential = false;
  System system(seq.camera, options);
  std::atomic<bool> done{false};
  std::size_t longest = 0;
  std::thread reader([&] {
    while (!done) {
      longest = std::max(longest, system.trajectory().size());
      longest = std::max(longest, system.online_trajectory().size());
      (void)system.keyframe_trajectory();
      (void)system.solver_statistics();
      (void)system.mapper_times();
    }
  });
  int tracked = 0;
  for (int i = 0; i < 60; ++i)
    tracked += system.process(seq.frames[i].rgb, seq.frames[i].depth, seq.groundtruth[i].timestamp)
                           .state == TrackingState::kOk
                   ? 1
                   : 0;
  done = true;
  reader.join();
  system.finish();
  EXPECT_EQ(tracked, 60);
  EXPECT_LE(longest, 60u);
  EXPECT_EQ(system.trajectory().size(), 60u);
  const SolverStatistics solver = system.solver_statistics();
  EXPECT_EQ(solver.pose_failures + solver.bundle_adjustment_failures, 0);
}

// A background thread that throws ends neither the process nor the caller's thread: the next
// process() (or finish()) throws BackgroundThreadError naming it, and what was tracked before
// stays readable (the CLI writes it: cli_test).
TEST(System, AMapperThreadThatThrowsIsReportedByTheNextFrame) {
  const auto& seq = test::rendered_sequence(60, false);
  SystemOptions options;
  options.sequential = false;
  System system(seq.camera, options);
  system.inject_failure("mapper", 2);
  std::string failure;
  int processed = 0;
  try {
    for (int i = 0; i < 60; ++i, ++processed)
      system.process(seq.frames[i].rgb, seq.frames[i].depth, seq.groundtruth[i].timestamp);
    system.finish();
  } catch (const BackgroundThreadError& e) {
    failure = e.what();
  }
  EXPECT_NE(failure.find("the mapper (mcslam-mapper) thread failed"), std::string::npos) << failure;
  EXPECT_NE(failure.find("failure injected at keyframe 2"), std::string::npos) << failure;
  EXPECT_NE(system.background_failure().find("mapper"), std::string::npos);
  EXPECT_GT(processed, 0);
  EXPECT_LT(processed, 60);
  EXPECT_EQ(static_cast<int>(system.online_trajectory().size()), processed);
  EXPECT_FALSE(system.trajectory().empty());
  EXPECT_THROW(system.finish(), BackgroundThreadError);  // stops the threads, says it again
}

TEST(System, AnUnknownThreadToInjectIntoIsAnInputError) {
  const auto& seq = test::rendered_sequence(3, false);
  System system(seq.camera, sequential_options());
  EXPECT_THROW(system.inject_failure("tracker", 1), InputError);
  EXPECT_THROW(system.inject_failure("detector", 1), InputError);  // no model in this run
}

// process() may be handed a grey image in a buffer the caller reuses: the frame keeps its own
// copy (the next frame's boxes are carried by the optical flow from it).
TEST(System, ACallersGreyBufferMayBeReused) {
  const auto& seq = test::rendered_sequence(30, false);
  PinholeCamera camera = seq.camera;
  camera.distortion = {0, 0, 0, 0, 0};
  std::vector<cv::Mat> grey;
  for (const auto& f : seq.frames) {
    cv::Mat g;
    cv::cvtColor(f.rgb, g, cv::COLOR_BGR2GRAY);
    grey.push_back(g);
  }
  System fresh(camera, sequential_options());
  System reusing(camera, sequential_options());
  cv::Mat buffer(grey[0].size(), CV_8UC1);
  cv::Mat depth_buffer(grey[0].size(), CV_32FC1);
  for (std::size_t i = 0; i < grey.size(); ++i) {
    const double t = seq.groundtruth[i].timestamp;
    const FrameResult a = fresh.process(grey[i].clone(), seq.frames[i].depth.clone(), t);
    grey[i].copyTo(buffer);
    seq.frames[i].depth.copyTo(depth_buffer);
    const FrameResult b = reusing.process(buffer, depth_buffer, t);
    ASSERT_TRUE(b.frame_features);
    EXPECT_NE(b.frame_features->image.data, buffer.data) << i;
    buffer.setTo(0);  // the caller writes its next image
    depth_buffer.setTo(0);
    ASSERT_EQ(a.T_w_c.has_value(), b.T_w_c.has_value()) << i;
  }
  fresh.finish();
  reusing.finish();
  const Trajectory ta = fresh.trajectory(), tb = reusing.trajectory();
  ASSERT_EQ(ta.size(), tb.size());
  for (std::size_t i = 0; i < ta.size(); ++i)
    EXPECT_LT((ta[i].T_w_c.translation() - tb[i].T_w_c.translation()).norm(), 1e-9) << i;
}

TEST(System, SequentialModeIsDeterministic) {
  const auto& seq = test::rendered_sequence(60, false);
  const RunResult a = run(seq, sequential_options(), 0, 60);
  const RunResult b = run(seq, sequential_options(), 0, 60);
  ASSERT_EQ(a.trajectory.size(), b.trajectory.size());
  for (std::size_t i = 0; i < a.trajectory.size(); ++i) {
    EXPECT_EQ(a.trajectory[i].timestamp, b.trajectory[i].timestamp);
    EXPECT_EQ((a.trajectory[i].T_w_c.translation() - b.trajectory[i].T_w_c.translation()).norm(),
              0.0);
  }
}

TEST(System, FeaturesExtractedAheadOnAnotherThreadGiveTheSameTrajectory) {
  // A run extracts frame k + 1's features on its reader's thread while frame k is processed
  // (System::extract_features): the poses must be the very ones of the frame's own extraction
  // (sequential, so deterministic), and ThreadSanitizer checks the overlap. 20 frames (a few
  // keyframes), rendered alone, keep the sanitizers' runs short.
  constexpr std::size_t kFrames = 20;
  const auto& seq = test::rendered_sequence(static_cast<int>(kFrames), false);
  const RunResult plain = run(seq, sequential_options(), 0, static_cast<int>(kFrames));
  SystemOptions options = sequential_options();
  options.extract_ahead = "true";
  System system(seq.camera, options);
  ASSERT_TRUE(system.can_extract_ahead());
  const auto prepared = [&](std::size_t i) {
    PreparedImages images = system.prepare(seq.frames[i].rgb, seq.frames[i].depth);
    system.extract_features(images);
    return images;
  };
  PreparedImages next = prepared(0);
  ASSERT_NE(next.features, nullptr);
  for (std::size_t i = 0; i < kFrames; ++i) {
    PreparedImages images = std::move(next);
    std::thread reader([&] {
      if (i + 1 < kFrames) next = prepared(i + 1);
    });
    const FrameResult r = system.process(images, seq.groundtruth[i].timestamp);
    reader.join();
    EXPECT_EQ(r.state, TrackingState::kOk) << i;
    const auto extracted_here =
        std::find_if(r.times.stages.begin(), r.times.stages.end(),
                     [](const auto& s) { return s.first == "extract_wait"; });
    EXPECT_EQ(extracted_here, r.times.stages.end()) << "frame " << i << " extracted again";
  }
  system.finish();
  const Trajectory ahead = system.trajectory();
  ASSERT_EQ(ahead.size(), plain.trajectory.size());
  for (std::size_t i = 0; i < ahead.size(); ++i)
    EXPECT_EQ((ahead[i].T_w_c.translation() - plain.trajectory[i].T_w_c.translation()).norm(), 0.0)
        << i;

  // Auto (the default; off for System itself), or with points limited where the frame before saw
  // movers (they depend on that frame): no extraction ahead.
  System plain_system(seq.camera, sequential_options());
  EXPECT_FALSE(plain_system.can_extract_ahead());
  SystemOptions dense = options;
  dense.orb.moving_density = 0.5;
  System limited(seq.camera, dense);
  EXPECT_FALSE(limited.can_extract_ahead());
  PreparedImages images = limited.prepare(seq.frames[0].rgb, seq.frames[0].depth);
  limited.extract_features(images);
  EXPECT_EQ(images.features, nullptr);
}

TEST(System, BadFramesAreLostNotCrashes) {
  const auto& seq = test::rendered_sequence(150, false);
  System system(seq.camera, sequential_options());
  // Before initialisation: empty, wrong size, wrong type, black.
  EXPECT_NE(system.process(cv::Mat(), cv::Mat(), 1.0).state, TrackingState::kOk);
  EXPECT_NE(system.process(cv::Mat(10, 10, CV_8UC3), cv::Mat(10, 10, CV_32FC1), 1.01).state,
            TrackingState::kOk);
  const auto& f0 = seq.frames[0];
  cv::Mat depth16;
  f0.depth.convertTo(depth16, CV_16U, 5000.0);
  EXPECT_NE(system.process(f0.rgb, depth16, 1.02).state, TrackingState::kOk);
  const cv::Mat black = cv::Mat::zeros(f0.rgb.size(), CV_8UC3);
  EXPECT_EQ(system.process(black, f0.depth, 1.03).state, TrackingState::kNotInitialized);
  const cv::Mat no_depth = cv::Mat::zeros(f0.depth.size(), CV_32FC1);
  EXPECT_EQ(system.process(f0.rgb, no_depth, 1.04).state, TrackingState::kNotInitialized);
  // Then good frames start the map, and a black frame in the middle is a lost frame.
  for (int i = 0; i < 10; ++i)
    EXPECT_EQ(
        system.process(seq.frames[i].rgb, seq.frames[i].depth, seq.groundtruth[i].timestamp).state,
        TrackingState::kOk);
  EXPECT_EQ(system.process(black, seq.frames[10].depth, seq.groundtruth[10].timestamp).state,
            TrackingState::kLost);
  EXPECT_EQ(
      system.process(seq.frames[11].rgb, seq.frames[11].depth, seq.groundtruth[11].timestamp).state,
      TrackingState::kOk);
}

/// Tracks frames 0-59 and loses frames 60-63 (black colour images).
void track_then_lose(System& system, const test::RenderedSequence& seq) {
  for (int i = 0; i < 60; ++i)
    system.process(seq.frames[i].rgb, seq.frames[i].depth, seq.groundtruth[i].timestamp);
  const cv::Mat black = cv::Mat::zeros(seq.frames[0].rgb.size(), CV_8UC3);
  for (int i = 60; i < 64; ++i)
    EXPECT_EQ(system.process(black, seq.frames[i].depth, seq.groundtruth[i].timestamp).state,
              TrackingState::kLost);
}

/// World frame = first camera: the distance of a frame's pose from the ground truth's.
double position_error(const test::RenderedSequence& seq, int i, const SE3& T_w_c) {
  const SE3 truth = seq.groundtruth[0].T_w_c.inverse() * seq.groundtruth[i].T_w_c;
  return (T_w_c.translation() - truth.translation()).norm();
}

/// track_then_lose, skips 64-74 (the camera moves on) and returns the first frame from 75 on
/// that relocalises (nullopt if none before 90), checking its pose. Frame 75 is 0.53 s after
/// frame 59, the last one tracked: longer than the recovery window.
std::optional<FrameResult> relocalise_after_gap(System& system, const test::RenderedSequence& seq) {
  track_then_lose(system, seq);
  for (int i = 75; i < 90; ++i) {
    FrameResult r =
        system.process(seq.frames[i].rgb, seq.frames[i].depth, seq.groundtruth[i].timestamp);
    if (!r.relocalised) continue;
    EXPECT_TRUE(r.T_w_c.has_value());
    if (r.T_w_c) {
      EXPECT_LT(position_error(seq, i, *r.T_w_c), 0.03);
    }
    return r;
  }
  return std::nullopt;
}

TEST(System, RelocalisesAfterAGapWithTheCameraMoved) {
  const auto& seq = test::rendered_sequence(150, false);
  System system(seq.camera, sequential_options());
  const std::optional<FrameResult> r = relocalise_after_gap(system, seq);
  ASSERT_TRUE(r.has_value());
  ASSERT_TRUE(r->relocalisation.has_value());
  EXPECT_FALSE(r->relocalisation->from_last_pose);
  EXPECT_GT(r->relocalisation->candidates, 0);
}

// Within the recovery window (frame 64 is 0.17 s after frame 59, the last one tracked) the first
// frame after the loss is found again from the pose before it, without a place search.
TEST(System, FindsItsPoseAgainFromThePoseBeforeARecentLoss) {
  const auto& seq = test::rendered_sequence(150, false);
  System system(seq.camera, sequential_options());
  track_then_lose(system, seq);
  const FrameResult r =
      system.process(seq.frames[64].rgb, seq.frames[64].depth, seq.groundtruth[64].timestamp);
  ASSERT_EQ(r.state, TrackingState::kOk);
  EXPECT_TRUE(r.relocalised);
  ASSERT_TRUE(r.relocalisation.has_value());
  EXPECT_TRUE(r.relocalisation->from_last_pose);
  EXPECT_EQ(r.relocalisation->candidates, 0);
  ASSERT_TRUE(r.T_w_c.has_value());
  EXPECT_LT(position_error(seq, 64, *r.T_w_c), 0.03);
}

/// The same boxes for every frame, as a detector would deliver them.
class FixedBoxes final : public DetectionSource {
 public:
  explicit FixedBoxes(std::vector<perception::Detection> boxes) : boxes_(std::move(boxes)) {}
  void submit(std::uint64_t, double, const cv::Mat&, bool) override {}
  std::optional<TimedDetections> collect(std::uint64_t frame_id, bool) override {
    return TimedDetections{frame_id, boxes_, 0.0};
  }
  std::string describe() const override { return "fixed boxes"; }

 private:
  std::vector<perception::Detection> boxes_;
};

// A person's box over most of the view (the features inside stay out of the pose until the person
// is seen to be still): a frame lost after a gap relocalises on the features around it, and
// reports its search (the candidates, the matching's time, the keyframe).
TEST(System, RelocalisesWithAPersonBoxOverMostOfTheView) {
  const auto& seq = test::rendered_sequence(150, false);
  System system(seq.camera, sequential_options());
  perception::Detection person;
  person.box = cv::Rect2f(0.3f * static_cast<float>(seq.camera.width), 0.0f,
                          0.7f * static_cast<float>(seq.camera.width),
                          static_cast<float>(seq.camera.height));
  person.class_id = 0;
  person.class_name = "person";
  person.score = 0.9f;
  system.set_detection_source(std::make_unique<FixedBoxes>(std::vector{person}), true);
  const std::optional<FrameResult> r = relocalise_after_gap(system, seq);
  ASSERT_TRUE(r.has_value());
  ASSERT_TRUE(r->relocalisation.has_value());
  EXPECT_GT(r->relocalisation->candidates, 0);
  EXPECT_GT(r->relocalisation->match_ms, 0.0);
  EXPECT_NE(r->relocalisation->keyframe, map::kNoId);
}

// While frames wait for their own boxes (the cold start), extract_features() leaves the
// extraction to process(), where it overlaps the detector's pass: extracted ahead it would add
// to the frame's wait. Once the first map is built it extracts ahead again.
TEST(System, NoExtractionAheadWhileFramesWaitForTheirBoxes) {
  const auto& seq = test::rendered_sequence(30, false);
  SystemOptions options;
  options.sequential = false;
  options.extract_ahead = "true";
  options.cold_start_keyframes = 2;
  System system(seq.camera, options);
  const auto prepared = [&](std::size_t i) {
    PreparedImages images = system.prepare(seq.frames[i].rgb, seq.frames[i].depth);
    system.extract_features(images);
    return images;
  };
  EXPECT_NE(prepared(0).features, nullptr);  // no detection source: nothing to wait for
  system.set_detection_source(std::make_unique<FixedBoxes>(std::vector<perception::Detection>{}),
                              false);
  int keyframes = 0;
  std::size_t i = 0;
  for (; i < seq.frames.size() && keyframes < 2; ++i) {
    const PreparedImages images = prepared(i);
    EXPECT_EQ(images.features, nullptr) << "frame " << i;
    const FrameResult r = system.process(images, seq.groundtruth[i].timestamp);
    EXPECT_EQ(r.state, TrackingState::kOk) << "frame " << i;
    keyframes += r.keyframe ? 1 : 0;
  }
  ASSERT_EQ(keyframes, 2);
  ASSERT_LT(i, seq.frames.size());
  const PreparedImages after = prepared(i);
  EXPECT_NE(after.features, nullptr);
  EXPECT_EQ(system.process(after, seq.groundtruth[i].timestamp).state, TrackingState::kOk);
  system.finish();
}

TEST(System, RejectsInvalidCameraAndOptions) {
  PinholeCamera bad;
  EXPECT_THROW(System(bad, SystemOptions{}), InputError);
  SystemOptions options;
  options.orb.num_levels = 0;
  EXPECT_THROW(System(synth::SynthOptions{}.camera(), options), InputError);
}

}  // namespace
}  // namespace mcslam::slam
