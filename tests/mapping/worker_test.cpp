#include "mcslam/mapping/worker.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <thread>

#include "mapping/box_world.hpp"
#include "mcslam/core/timing.hpp"
#include "support/test_camera.hpp"

namespace mcslam::mapping {
namespace {

using test::BoxWorld;
using test::look;

std::vector<SE3> path(int n) {
  std::vector<SE3> poses;
  for (int i = 0; i < n; ++i) poses.push_back(look({2.6 + 0.05 * i, 2.2 + 0.1 * i, 1.2}, 0.0));
  return poses;
}

TEST(MappingWorker, IntegratesQueuedKeyframesLikeTheMapItself) {
  BoxWorld world;
  const PinholeCamera cam = test::make_camera();
  const auto poses = path(4);
  OccupancyMap inline_map;
  MappingWorker worker;
  Stopwatch enqueue_time;
  std::vector<double> enqueue_ms;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    auto kf = world.render(i, poses[i], cam);
    inline_map.insert(kf);
    enqueue_time.restart();
    worker.enqueue(kf);
    enqueue_ms.push_back(enqueue_time.elapsed_ms());
    kf.depth.setTo(0.0f);  // the worker copied it
  }
  // Shared, not copied: the same map.
  MappingWorker shared;
  for (std::size_t i = 0; i < poses.size(); ++i)
    shared.enqueue_shared(world.render(i, poses[i], cam));
  shared.wait();
  EXPECT_EQ(shared.snapshot()->voxels.size(), inline_map.occupied_voxels().size());
  worker.wait();
  EXPECT_EQ(worker.pending(), 0u);
  const auto snapshot = worker.snapshot();
  EXPECT_EQ(snapshot->version, 4u);
  EXPECT_EQ(snapshot->stats.keyframes, 4u);
  EXPECT_EQ(snapshot->voxels.size(), inline_map.occupied_voxels().size());
  EXPECT_EQ(snapshot->stats.occupied_voxels, inline_map.stats().occupied_voxels);
  EXPECT_EQ(snapshot->grid.cells, inline_map.grid().cells);
  // Unchanged: the same snapshot.
  EXPECT_EQ(worker.snapshot().get(), snapshot.get());
  // A floor set: a new grid.
  worker.set_floor(FloorPlane{Eigen::Vector3d::UnitZ(), -world.room_min.z()});
  EXPECT_FALSE(worker.snapshot()->grid.floor_estimated);
  const SampleStats enqueue = compute_stats(enqueue_ms);
  std::printf("[ worker ] enqueue (copying a VGA keyframe): median %.2f ms, max %.2f ms\n",
              enqueue.median, enqueue.max);
}

TEST(MappingWorker, IntegratesAtTheEndWhenWaitedFor) {
  // integration "at_end": the keyframes are stored as they come and integrated by wait().
  BoxWorld world;
  const PinholeCamera cam = test::make_camera();
  const auto poses = path(4);
  OccupancyMap inline_map;
  OccupancyOptions at_end;
  at_end.integration = "at_end";
  MappingWorker worker(at_end);
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const auto kf = world.render(i, poses[i], cam);
    inline_map.insert(kf);
    worker.enqueue(kf);
  }
  while (worker.pending() > 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_EQ(worker.snapshot()->stats.occupied_voxels, 0u);  // stored, not integrated
  EXPECT_EQ(worker.snapshot()->stats.keyframes, 4u);
  worker.wait();
  const auto snapshot = worker.snapshot();
  EXPECT_EQ(snapshot->stats.rebuilds, 1u);
  EXPECT_EQ(snapshot->stats.occupied_voxels, inline_map.stats().occupied_voxels);
  EXPECT_EQ(snapshot->voxels.size(), inline_map.occupied_voxels().size());
  EXPECT_EQ(snapshot->grid.cells, inline_map.grid().cells);
}

TEST(MappingWorker, CorrectionsApplyInOrderAfterTheKeyframesBeforeThem) {
  BoxWorld world;
  const PinholeCamera cam = test::make_camera();
  const auto poses = path(4);
  MappingWorker worker;
  std::unordered_map<KeyframeId, SE3> corrected;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    auto kf = world.render(i, poses[i], cam);
    if (i >= 2) {
      kf.T_w_c.set_translation(kf.T_w_c.translation() + Eigen::Vector3d(0.25, 0.0, 0.0));
      corrected[i] = poses[i];
    }
    worker.enqueue(kf);
  }
  worker.correct(corrected);
  // Readers meanwhile, on another thread.
  std::thread reader([&] {
    for (int i = 0; i < 3; ++i) EXPECT_NE(worker.snapshot(), nullptr);
  });
  worker.wait();
  reader.join();
  const auto s = worker.snapshot();
  EXPECT_EQ(s->stats.rebuilds, 1u);
  EXPECT_EQ(s->version, 5u);
  EXPECT_EQ(worker.grid().cells, s->grid.cells);
  worker.with_map([&](const OccupancyMap& map) {
    const MapQuality q = evaluate_map(map, world.static_surfaces());
    EXPECT_EQ(q.ghosts, 0u);
  });
}

TEST(MappingWorker, FloorCandidatesNeverWaitForTheMapAndApplyInOrder) {
  BoxWorld world;
  const PinholeCamera cam = test::make_camera();
  MappingWorker worker;
  worker.enqueue_shared(world.render(0, path(1)[0], cam));
  worker.wait();
  const FloorPlane floor{Eigen::Vector3d::UnitZ(), -world.room_min.z()};
  std::future<void> call;
  // While another thread holds the map (as an integration does), the candidates are taken at
  // once; a call that waited for the map would still be waiting when the hold ends (10 s).
  worker.with_map([&](const OccupancyMap&) {
    call = std::async(std::launch::async, [&] { worker.set_floor_candidates({floor}); });
    EXPECT_EQ(call.wait_for(std::chrono::seconds(10)), std::future_status::ready);
  });
  call.get();
  worker.wait();
  const auto grid = worker.snapshot()->grid;
  EXPECT_FALSE(grid.floor_estimated) << "the grid stands on the candidate";
}

TEST(MappingWorker, KeepsTheThreadsExceptionAndStops) {
  BoxWorld world;
  const PinholeCamera cam = test::make_camera();
  MappingWorker worker({}, "mcslam-map-test");
  auto bad = world.render(3, path(1)[0], cam);
  bad.depth = cv::Mat::zeros(10, 10, CV_32FC1);  // does not match the camera
  worker.enqueue(bad);
  worker.enqueue(world.render(4, path(1)[0], cam));
  try {
    worker.wait();
    ADD_FAILURE() << "expected the thread's failure";
  } catch (const std::runtime_error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("mcslam-map-test"), std::string::npos) << message;
    EXPECT_NE(message.find("keyframe 3"), std::string::npos) << message;
  }
  EXPECT_TRUE(worker.failed());
  EXPECT_EQ(worker.snapshot()->stats.keyframes, 0u);  // the later keyframe was not integrated
  worker.enqueue(world.render(5, path(1)[0], cam));   // dropped
  EXPECT_EQ(worker.pending(), 0u);
  EXPECT_THROW(worker.finish(), std::runtime_error);
}

TEST(MappingWorker, FinishIntegratesWhatIsQueuedThenDropsTheRest) {
  BoxWorld world;
  const PinholeCamera cam = test::make_camera();
  MappingWorker worker;
  worker.enqueue(world.render(0, path(1)[0], cam));
  worker.finish();
  EXPECT_EQ(worker.snapshot()->stats.keyframes, 1u);
  worker.enqueue(world.render(1, path(2)[1], cam));
  worker.wait();
  EXPECT_EQ(worker.snapshot()->stats.keyframes, 1u);
  EXPECT_EQ(worker.pending(), 0u);
}

}  // namespace
}  // namespace mcslam::mapping
