// `mcslam faults`: the faulty copies it writes, and mcslam running through every fault without a
// crash, with a valid trajectory.
#include "mcslam/app/faults.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "mcslam/io/sequence.hpp"
#include "mcslam/io/trajectory_io.hpp"
#include "mcslam/perception/detection.hpp"
#include "mcslam/slam/config.hpp"
#include "mcslam/synth/sequence.hpp"
#include "support/cli_runner.hpp"
#include "support/temp_dir.hpp"

#ifndef MCSLAM_EXE
#error "MCSLAM_EXE must name the mcslam executable"
#endif

namespace mcslam::app {
namespace {

namespace fs = std::filesystem;
using test::expect_input_error;
using test::quote;
using test::TempDir;

TEST(Faults, ParsesEveryFormAndRejectsBadOnes) {
  const Fault drop = parse_fault("drop-every:5");
  EXPECT_EQ(drop.kind, Fault::Kind::kDropEvery);
  EXPECT_EQ(drop.length, 5);
  const Fault black = parse_fault("black:200:15");
  EXPECT_EQ(black.kind, Fault::Kind::kBlack);
  EXPECT_EQ(black.start, 200);
  EXPECT_EQ(black.length, 15);
  const Fault jump = parse_fault("time-jump:10:2.5");
  EXPECT_DOUBLE_EQ(jump.seconds, 2.5);
  for (const char* text : {"drop-every:5", "drop-burst:1:2", "black:3:4", "saturate:5:6",
                           "zero-depth:7:8", "freeze:9:10", "time-jump:11:0.5", "kidnap:13:14"})
    EXPECT_EQ(to_string(parse_fault(text)), text);
  for (const char* text :
       {"", "blue:1:2", "black:1", "black:1:2:3", "black:x:2", "black:-1:2", "black:1:0",
        "drop-every:1", "time-jump:3:-1", "time-jump:3:nan", "black:1:2.5"})
    expect_input_error([&] { parse_fault(text); }, {"--fault '" + std::string(text) + "'"});
}

TEST(Faults, CopyHasTheFaultsAndRunsWithoutACrash) {
  TempDir dir("faults");
  synth::SynthOptions options;
  options.frames = 60;
  options.depth_noise = true;
  synth::write_sequence(dir.file("seq"), options);
  // One box per frame whose x is the frame's index, so that the copy shows where each went.
  perception::DetectionsFile boxes = perception::read_detections(dir.file("seq/detections.json"));
  ASSERT_EQ(boxes.frames.size(), 60u);
  for (std::size_t i = 0; i < boxes.frames.size(); ++i)
    boxes.frames[i].detections = {{cv::Rect2f(float(i), 10.f, 20.f, 30.f), 56, "chair", 0.9f}};
  perception::write_detections(dir.file("seq/detections.json"), boxes);
  FaultRequest request;
  request.sequence_dir = dir.file("seq");
  request.output_dir = dir.file("faulty");
  for (const char* f : {"drop-every:10", "drop-burst:12:3", "black:20:3", "saturate:24:2",
                        "zero-depth:27:2", "freeze:30:4", "time-jump:40:2", "kidnap:45:4"})
    request.faults.push_back(parse_fault(f));
  const nlohmann::json report = write_faulty_sequence(request);
  EXPECT_EQ(report["frames_in"], 60);
  // Every 10th frame (6) and frames 12-14 are gone.
  EXPECT_EQ(report["frames_out"], 51);
  ASSERT_EQ(report["faults"].size(), 8u);
  EXPECT_EQ(report["faults"][1]["frames_affected"], 3);

  const io::RgbdSequence faulty = io::RgbdSequence::open(request.output_dir);
  ASSERT_EQ(faulty.frames().size(), 51u);
  const io::RgbdSequence source = io::RgbdSequence::open(request.sequence_dir);
  // Frame index k of the source is at position k - (frames dropped before it) in the copy.
  auto copy_of = [&](double source_t) -> const io::FrameEntry& {
    for (const auto& e : faulty.frames())
      if (std::abs(e.rgb_timestamp - source_t) < 1e-5) return e;
    ADD_FAILURE() << "no frame at " << source_t;
    return faulty.frames().front();
  };
  const auto black = io::load_rgbd(copy_of(source.frames()[21].rgb_timestamp), 5000.0);
  EXPECT_EQ(cv::countNonZero(black.rgb.reshape(1)), 0);
  const auto white = io::load_rgbd(copy_of(source.frames()[24].rgb_timestamp), 5000.0);
  EXPECT_EQ(cv::countNonZero(white.rgb.reshape(1) != 255), 0);
  const auto no_depth = io::load_rgbd(copy_of(source.frames()[27].rgb_timestamp), 5000.0);
  EXPECT_EQ(cv::countNonZero(no_depth.depth), 0);
  EXPECT_EQ(copy_of(source.frames()[33].rgb_timestamp).rgb_path,
            copy_of(source.frames()[30].rgb_timestamp).rgb_path);  // frozen
  // After the jump, frames and ground truth are 2 s later; before it they are not.
  EXPECT_NO_FATAL_FAILURE(copy_of(source.frames()[38].rgb_timestamp));
  EXPECT_NO_FATAL_FAILURE(copy_of(source.frames()[41].rgb_timestamp + 2.0));
  const Trajectory gt = io::read_tum_trajectory(dir.file("faulty/groundtruth.txt"));
  const Trajectory gt_source = io::read_tum_trajectory(dir.file("seq/groundtruth.txt"));
  ASSERT_EQ(gt.size(), gt_source.size());
  EXPECT_DOUBLE_EQ(gt.back().timestamp, gt_source.back().timestamp + 2.0);
  // The boxes follow their frames: none on a blank frame, the frozen frame's while it is
  // repeated, shifted with the time jump; one entry per frame of the copy.
  const perception::DetectionsFile copied =
      perception::read_detections(dir.file("faulty/detections.json"));
  ASSERT_EQ(copied.frames.size(), 51u);
  const auto box_x = [&](double t) -> float {
    const perception::FrameDetections* f = copied.find(t);
    if (f == nullptr) {
      ADD_FAILURE() << "no boxes at " << t;
      return -2.f;
    }
    return f->detections.empty() ? -1.f : f->detections.front().box.x;
  };
  EXPECT_EQ(box_x(source.frames()[11].rgb_timestamp), 11.f);
  EXPECT_EQ(box_x(source.frames()[21].rgb_timestamp), -1.f);  // black
  EXPECT_EQ(box_x(source.frames()[24].rgb_timestamp), -1.f);  // saturated
  EXPECT_EQ(box_x(source.frames()[27].rgb_timestamp), 27.f);  // depth only
  EXPECT_EQ(box_x(source.frames()[33].rgb_timestamp), 30.f);  // frozen on frame 30
  EXPECT_EQ(box_x(source.frames()[41].rgb_timestamp + 2.0), 41.f);
  EXPECT_EQ(box_x(source.frames()[46].rgb_timestamp + 2.0), -1.f);  // kidnapped
  for (std::size_t i = 0; i < copied.frames.size(); ++i)
    EXPECT_NEAR(copied.frames[i].timestamp, faulty.frames()[i].rgb_timestamp, 1e-6);
  // The copy carries the source's camera.
  EXPECT_EQ(slam::resolve_run_config(request.output_dir, std::nullopt).camera.fx,
            slam::resolve_run_config(request.sequence_dir, std::nullopt).camera.fx);

  // mcslam goes through all of it: exit 0, and a trajectory with finite poses and strictly
  // increasing timestamps, one row per frame in timings.csv.
  const auto r = test::run_command(MCSLAM_EXE,
                                   "run " + quote(request.output_dir) + " --output " +
                                       quote(dir.file("out")) + " --sequential -q",
                                   dir / "stdout", dir / "stderr");
  ASSERT_EQ(r.exit_code, 0) << r;
  const Trajectory estimate = io::read_tum_trajectory(dir.file("out/trajectory.txt"));
  ASSERT_GT(estimate.size(), 20u);
  for (std::size_t i = 0; i < estimate.size(); ++i) {
    EXPECT_TRUE(estimate[i].T_w_c.translation().allFinite());
    if (i > 0) {
      EXPECT_GT(estimate[i].timestamp, estimate[i - 1].timestamp);
    }
  }
  std::ifstream timings(dir.file("out/timings.csv"));
  int rows = -1;
  for (std::string line; std::getline(timings, line);) ++rows;
  EXPECT_EQ(rows, 51);
}

TEST(Faults, BadRequests) {
  TempDir dir("faults");
  synth::SynthOptions options;
  options.frames = 5;
  options.width = 160;
  options.height = 120;
  options.fx = options.fy = 525.0 / 4.0;
  options.cx = 79.5;
  options.cy = 59.5;
  synth::write_sequence(dir.file("seq"), options);
  FaultRequest request;
  request.sequence_dir = dir.file("seq");
  request.output_dir = dir.file("out");
  request.faults = {parse_fault("black:5:2")};
  expect_input_error([&] { write_faulty_sequence(request); }, {"black:5:2", "only 5 frames"});
  request.faults = {parse_fault("drop-burst:0:5")};
  expect_input_error([&] { write_faulty_sequence(request); }, {"every frame would be dropped"});
  request.sequence_dir = dir.file("none");
  expect_input_error([&] { write_faulty_sequence(request); }, {"none"});
}

}  // namespace
}  // namespace mcslam::app
