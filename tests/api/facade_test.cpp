// The library facade: settings, errors that name the problem, the data-file lookup, and a
// synthetic sequence run through mcslam::System giving the poses `mcslam run --sequential` gives.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "mcslam/mcslam.hpp"
#include "support/temp_dir.hpp"

namespace fs = std::filesystem;

namespace {

/// Runs `command` with the shell; true when it exits 0.
bool run(const std::string& command) { return std::system(command.c_str()) == 0; }

template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const mcslam::InputError& e) {
    return e.what();
  }
  return "(no InputError)";
}

class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    ::setenv(name, value.c_str(), 1);
  }
  ~ScopedEnv() {
    if (old_) {
      ::setenv(name_, old_->c_str(), 1);
    } else {
      ::unsetenv(name_);
    }
  }

 private:
  const char* name_;
  std::optional<std::string> old_;
};

}  // namespace

TEST(Facade, DataFilesComeFromTheEnvironmentThenBesideTheBinaryNeverTheSourceTree) {
  mcslam::test::TempDir dir;
  {
    ScopedEnv env("MCSLAM_DATA_DIR", dir.path().string());
    const auto candidates = mcslam::data_file_candidates("orb_vocabulary.bin");
    ASSERT_FALSE(candidates.empty());
    EXPECT_EQ(candidates.front(), (dir.path() / "orb_vocabulary.bin").string());
    // Not there: the first existing candidate is the build tree's copy (share/mcslam above
    // this test's binary), as an installed program finds <prefix>/share/mcslam.
    const std::string found = mcslam::find_data_file("orb_vocabulary.bin");
    EXPECT_TRUE(fs::is_regular_file(found)) << found;
    EXPECT_NE(found.find("share/mcslam/orb_vocabulary.bin"), std::string::npos) << found;
    EXPECT_EQ(found.find("/data/orb_vocabulary.bin"), std::string::npos) << found;
  }
  {
    ScopedEnv env("MCSLAM_DATA_DIR", (dir.path() / "missing").string());
    ScopedEnv voc("MCSLAM_VOCABULARY", (dir.path() / "voc.bin").string());
    EXPECT_EQ(mcslam::Settings().vocabulary(), (dir.path() / "voc.bin").string());
  }
}

TEST(Facade, BadInputIsOneErrorNamingTheProblem) {
  EXPECT_NE(
      error_of([] { mcslam::Settings::preset("kinect9"); }).find("unknown camera preset 'kinect9'"),
      std::string::npos);
  EXPECT_NE(error_of([] { mcslam::Sequence::open("/nonexistent/seq"); }).find("/nonexistent/seq"),
            std::string::npos);
  EXPECT_NE(error_of([] {
              mcslam::Settings().load_file("/nonexistent/s.yaml");
            }).find("/nonexistent/s.yaml"),
            std::string::npos);
  EXPECT_NE(error_of([] {
              mcslam::Settings().load_yaml("orb.no_such_key: 1\n", "mine.yaml");
            }).find("mine.yaml"),
            std::string::npos);
  EXPECT_NE(error_of([] { mcslam::System system{mcslam::Settings()}; }).find("no camera"),
            std::string::npos);
  mcslam::Settings settings = mcslam::Settings::preset("tum_fr1");
  settings.set_detector("/nonexistent/model.onnx");
  EXPECT_NE(error_of([&] { mcslam::System system(settings); }).find("/nonexistent/model.onnx"),
            std::string::npos);
}

TEST(Facade, ImagesOfTheWrongSizeOrTypeThrow) {
  mcslam::Settings settings = mcslam::Settings::preset("tum_fr1");
  settings.set_vocabulary("");
  mcslam::System system(settings);
  const cv::Mat rgb(480, 640, CV_8UC3, cv::Scalar::all(0));
  const cv::Mat depth(480, 640, CV_32FC1, cv::Scalar::all(0));
  EXPECT_NE(error_of([&] {
              system.process(cv::Mat(240, 320, CV_8UC3), depth, 0.0);
            }).find("the colour image is 320x240 but the camera is 640x480"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              system.process(rgb, cv::Mat(480, 640, CV_64FC1), 0.0);
            }).find("the depth image is CV_64FC1"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              system.process(cv::Mat(480, 640, CV_16UC3), depth, 0.0);
            }).find("the colour image is CV_16UC3"),
            std::string::npos);
  // Black images are content, not an error: the frame is simply not tracked.
  EXPECT_EQ(system.process(rgb, depth, 0.0).state, mcslam::State::kNotInitialized);
}

TEST(Facade, SyntheticSequenceGivesTheCliPoses) {
  mcslam::test::TempDir dir;
  const fs::path seq = dir.path() / "synth", out = dir.path() / "run";
  ASSERT_TRUE(run(std::string(MCSLAM_EXE) + " synth --output " + seq.string() +
                  " --frames 30 -q > /dev/null"));
  ASSERT_TRUE(run(std::string(MCSLAM_EXE) + " run " + seq.string() + " --output " + out.string() +
                  " --sequential -q > /dev/null 2>&1"));
  const mcslam::Trajectory cli = mcslam::read_trajectory((out / "trajectory.txt").string());

  const mcslam::Sequence sequence = mcslam::Sequence::open(seq.string());
  mcslam::Settings settings = mcslam::Settings::for_sequence(seq.string());
  settings.set_sequential(true);
  mcslam::System system(settings);
  int keyframes = 0;
  for (std::size_t k = 0; k < sequence.size(); ++k) {
    const auto f = sequence.load(k, settings.camera().depth_factor);
    // Every other frame's depth in raw units: converted as a depth PNG is.
    cv::Mat depth = f.depth;
    if (k % 2 == 1) f.depth.convertTo(depth, CV_16UC1, settings.camera().depth_factor);
    const mcslam::FrameReport r = system.process(f.rgb, depth, f.timestamp, f.depth_timestamp);
    keyframes += r.keyframe;
  }
  system.finish();
  const mcslam::Trajectory api = system.trajectory();
  ASSERT_EQ(api.size(), cli.size());
  ASSERT_GE(api.size(), 25u);
  for (std::size_t i = 0; i < api.size(); ++i) {
    EXPECT_NEAR(api[i].timestamp, cli[i].timestamp, 1e-6);
    EXPECT_LT((api[i].T_w_c.translation() - cli[i].T_w_c.translation()).norm(), 1e-6) << i;
  }
  EXPECT_GE(keyframes, 1);
  const mcslam::MapSnapshot map = system.map();
  EXPECT_GT(map.points.size(), 100u);
  EXPECT_GE(static_cast<std::size_t>(keyframes), map.keyframes.size());  // some may be culled
  EXPECT_GE(map.keyframes.size(), 1u);

  const auto gt = sequence.groundtruth();
  ASSERT_TRUE(gt.has_value());
  const mcslam::Evaluation e = mcslam::evaluate(*gt, api);
  EXPECT_EQ(e.matched, api.size());
  EXPECT_LT(e.ate_rmse_m, 0.05);
  EXPECT_NE(e.json.find("ate_rmse_m"), std::string::npos);

  const fs::path session = dir.path() / "map.session";
  system.save_session(session.string());
  EXPECT_GT(fs::file_size(session), 1000u);
}
