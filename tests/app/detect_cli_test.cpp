// Tests of `mcslam detect` through the real binary: outputs on fr1_rpy images, and the exit code
// and message for bad input. Tests that need the models or the images skip without them.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "mcslam/perception/detection.hpp"
#include "support/cli_runner.hpp"
#include "support/temp_dir.hpp"

#ifndef MCSLAM_EXE
#error "MCSLAM_EXE must name the mcslam executable"
#endif
#ifndef MCSLAM_SHARED_MODELS
#error "MCSLAM_SHARED_MODELS must name the folder of detector models"
#endif

namespace {

namespace fs = std::filesystem;

const std::string kYoloV8 = std::string(MCSLAM_SHARED_MODELS) + "/yolov8n_320.onnx";
const std::string kRpy = std::string(MCSLAM_SHARED_DATA) + "/tum/rgbd_dataset_freiburg1_rpy";
const std::vector<std::string> kFrames = {"1305031229.528748", "1305031241.493736",
                                          "1305031252.831021"};
std::string frame_path(const std::string& stem) { return kRpy + "/rgb/" + stem + ".jpg"; }

#define REQUIRE_FILE(path) \
  if (!fs::exists(path)) GTEST_SKIP() << (path) << " is absent"

using mcslam::test::CliResult;
using mcslam::test::quote;
using mcslam::test::read_file;
using mcslam::test::write_file;

class TempDir : public mcslam::test::TempDir {
 public:
  TempDir() : mcslam::test::TempDir("mcslam_detect_cli_test") {}
};

/// Runs `mcslam detect <args>` (args already quoted), capturing the exit code and output.
CliResult detect_cli(const TempDir& dir, const std::string& args) {
  return mcslam::test::run_command(MCSLAM_EXE, "detect " + args, dir / "stdout.txt",
                                   dir / "stderr.txt");
}

void expect_input_error(const CliResult& r, const std::vector<std::string>& pieces) {
  EXPECT_FALSE(r.crashed) << r;
  EXPECT_EQ(r.exit_code, 1) << r;
  EXPECT_NE(r.err.find("mcslam: error: "), std::string::npos) << r;
  for (const auto& piece : pieces)
    EXPECT_NE(r.err.find(piece), std::string::npos) << "stderr lacks '" << piece << "'\n" << r;
}

TEST(DetectCli, OneImage) {
  REQUIRE_FILE(kYoloV8);
  const std::string image = frame_path(kFrames[1]);
  REQUIRE_FILE(image);
  TempDir dir;
  const fs::path out = dir / "out";
  const CliResult r = detect_cli(
      dir, quote(image) + " --model " + quote(kYoloV8) + " --output " + quote(out.string()));
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_NE(r.out.find("detections: "), std::string::npos) << r;
  EXPECT_NE(r.out.find("keyboard"), std::string::npos) << r;

  const mcslam::perception::DetectionsFile file =
      mcslam::perception::read_detections((out / "detections.json").string());
  ASSERT_EQ(file.frames.size(), 1u);
  EXPECT_DOUBLE_EQ(file.frames[0].timestamp, 0.0);
  EXPECT_EQ(file.image_width, 640);
  EXPECT_EQ(file.image_height, 480);
  EXPECT_EQ(file.source, "yolov8n_320.onnx");
  bool keyboard = false;
  for (const auto& d : file.frames[0].detections) {
    EXPECT_GE(d.score, 0.35f);
    keyboard = keyboard || (d.class_name == "keyboard" && d.class_id == 66);
  }
  EXPECT_TRUE(keyboard);

  // At another network input: the summary names it, the keyboard is still found.
  const CliResult small =
      detect_cli(dir, quote(image) + " --model " + quote(kYoloV8) + " --output " +
                          quote((dir / "small").string()) + " --input-size 224x192");
  ASSERT_EQ(small.exit_code, 0) << small;
  EXPECT_NE(small.out.find("yolov8 224x192"), std::string::npos) << small;
  EXPECT_NE(small.out.find("keyboard"), std::string::npos) << small;

  const cv::Mat annotated = cv::imread((out / "annotated" / (kFrames[1] + ".jpg")).string());
  ASSERT_FALSE(annotated.empty());
  EXPECT_EQ(annotated.cols, 640);
  EXPECT_EQ(annotated.rows, 480);
}

TEST(DetectCli, SequenceWithoutDepthListAndMaxFrames) {
  REQUIRE_FILE(kYoloV8);
  for (const auto& stem : kFrames) REQUIRE_FILE(frame_path(stem));
  TempDir dir;
  const fs::path seq = dir / "seq";
  fs::create_directories(seq);
  std::string list = "# color images\n# timestamp filename\n";
  for (const auto& stem : kFrames) list += stem + " " + frame_path(stem) + "\n";
  write_file(seq / "rgb.txt", list);
  const fs::path out = dir / "out";
  const CliResult r =
      detect_cli(dir, quote(seq.string()) + " -m " + quote(kYoloV8) + " -o " + quote(out.string()) +
                          " --max-frames 2 --confidence 0.4 -q");
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_TRUE(r.out.empty()) << r;  // -q
  const auto file = mcslam::perception::read_detections((out / "detections.json").string());
  ASSERT_EQ(file.frames.size(), 2u);
  EXPECT_NEAR(file.frames[0].timestamp, 1305031229.528748, 1e-6);
  EXPECT_NEAR(file.frames[1].timestamp, 1305031241.493736, 1e-6);
  for (const auto& frame : file.frames)
    for (const auto& d : frame.detections) EXPECT_GE(d.score, 0.4f);
  EXPECT_TRUE(fs::exists(out / "annotated" / (kFrames[0] + ".jpg")));
  EXPECT_TRUE(fs::exists(out / "annotated" / (kFrames[1] + ".jpg")));
  EXPECT_FALSE(fs::exists(out / "annotated" / (kFrames[2] + ".jpg")));
}

TEST(DetectCli, MissingImage) {
  TempDir dir;
  const std::string image = (dir / "absent.png").string();
  expect_input_error(detect_cli(dir, quote(image) + " --model " + quote(kYoloV8) + " --output " +
                                         quote((dir / "out").string())),
                     {image});
  EXPECT_FALSE(fs::exists(dir / "out"));  // nothing written for bad input
}

TEST(DetectCli, UnreadableImageIsNamed) {
  REQUIRE_FILE(kYoloV8);
  TempDir dir;
  const std::string image = (dir / "broken.jpg").string();
  write_file(image, "not a jpeg");
  expect_input_error(detect_cli(dir, quote(image) + " --model " + quote(kYoloV8) + " --output " +
                                         quote((dir / "out").string())),
                     {image, "cannot read image"});
}

TEST(DetectCli, BadModelAndOptions) {
  const std::string image = frame_path(kFrames[0]);
  REQUIRE_FILE(image);
  TempDir dir;
  const std::string model = (dir / "garbage.onnx").string();
  write_file(model, "garbage");
  const std::string out = quote((dir / "out").string());
  expect_input_error(detect_cli(dir, quote(image) + " --model " + quote(model) + " -o " + out),
                     {model, "not an ONNX model"});
  expect_input_error(detect_cli(dir, quote(image) + " --model " + quote(model) + " -o " + out +
                                         " --confidence 1.5"),
                     {"detector.confidence"});
  expect_input_error(detect_cli(dir, quote(image) + " --model " + quote(model) + " -o " + out +
                                         " --input-size 230x192"),
                     {"multiples of 32", "230x192"});
  const CliResult not_a_size = detect_cli(
      dir, quote(image) + " --model " + quote(model) + " -o " + out + " --input-size 224");
  EXPECT_NE(not_a_size.exit_code, 0) << not_a_size;
  EXPECT_FALSE(not_a_size.crashed) << not_a_size;
  EXPECT_NE(not_a_size.err.find("WxH"), std::string::npos) << not_a_size;
  // A required option missing is a usage error (CLI11), not an input error.
  const CliResult usage = detect_cli(dir, quote(image) + " -o " + out);
  EXPECT_NE(usage.exit_code, 0) << usage;
  EXPECT_FALSE(usage.crashed) << usage;
}

TEST(DetectCli, OutputFolderThatIsAFile) {
  REQUIRE_FILE(kYoloV8);
  const std::string image = frame_path(kFrames[0]);
  REQUIRE_FILE(image);
  TempDir dir;
  const fs::path blocker = dir / "file";
  write_file(blocker, "x");
  expect_input_error(detect_cli(dir, quote(image) + " --model " + quote(kYoloV8) + " --output " +
                                         quote(blocker.string())),
                     {blocker.string()});
}

}  // namespace
