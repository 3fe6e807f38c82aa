// SLAM on the start of TUM freiburg1_rpy (../shared/data); skipped when the data is absent.
#include <gtest/gtest.h>

#include <filesystem>

#include "mcslam/eval/metrics.hpp"
#include "mcslam/io/sequence.hpp"
#include "mcslam/io/trajectory_io.hpp"
#include "mcslam/slam/config.hpp"
#include "mcslam/slam/system.hpp"

namespace mcslam::slam {
namespace {

TEST(RealData, Freiburg1RpyStartTracksEveryFrame) {
  const std::string dir = std::string(MCSLAM_SHARED_DATA) + "/tum/rgbd_dataset_freiburg1_rpy";
  if (!std::filesystem::exists(dir + "/rgb.txt")) GTEST_SKIP() << dir << " is not here";
  const io::RgbdSequence sequence = io::RgbdSequence::open(dir);
  RunConfig config = resolve_run_config(dir, std::nullopt);
  config.options.sequential = true;
  System system(config.camera, config.options);
  const int frames = 150;
  int tracked = 0;
  for (int i = 0; i < frames; ++i) {
    const auto& entry = sequence.frames()[static_cast<std::size_t>(i)];
    const io::RgbdImages images = io::load_rgbd(entry, config.camera.depth_factor);
    const FrameResult r =
        system.process(images.rgb, images.depth, entry.rgb_timestamp, entry.depth_timestamp);
    tracked += r.state == TrackingState::kOk ? 1 : 0;
  }
  system.finish();
  EXPECT_EQ(tracked, frames);
  const auto report =
      eval::evaluate(io::read_tum_trajectory(*sequence.groundtruth_path()), system.trajectory());
  std::cout << eval::to_text(report);
  // A sanity bound (the benchmark measures accuracy): far below a lost or drifting track.
  EXPECT_LT(report.ate.translation.rmse, 0.05);
}

}  // namespace
}  // namespace mcslam::slam
