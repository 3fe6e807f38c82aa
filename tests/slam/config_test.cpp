#include "mcslam/slam/config.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "mcslam/core/error.hpp"

namespace mcslam::slam {
namespace {

namespace fs = std::filesystem;

class TempDir {
 public:
  TempDir()
      : path_(fs::temp_directory_path() / ("mcslam_config_test_" + std::to_string(::getpid()))) {
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  fs::path write(const std::string& name, const std::string& text) const {
    std::ofstream(path_ / name) << text;
    return path_ / name;
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Config, ReadsOrbSlam2SettingsFile) {
  const std::string text =
      "%YAML:1.0\n"
      "Camera.fx: 535.4\nCamera.fy: 539.2\nCamera.cx: 320.1\nCamera.cy: 247.6\n"
      "Camera.k1: 0.0\nCamera.k2: 0.0\nCamera.p1: 0.0\nCamera.p2: 0.0\n"
      "Camera.width: 640\nCamera.height: 480\nCamera.fps: 30.0\nCamera.bf: 40.0\nCamera.RGB: 1\n"
      "ThDepth: 40.0\nDepthMapFactor: 5000.0\n"
      "ORBextractor.nFeatures: 1200\nORBextractor.scaleFactor: 1.2\nORBextractor.nLevels: 8\n"
      "ORBextractor.iniThFAST: 20\nORBextractor.minThFAST: 7\n"
      "Viewer.KeyFrameSize: 0.05\nViewer.PointSize: 2\n";
  io::ConfigFile file = io::ConfigFile::from_string(text, "TUM3.yaml");
  PinholeCamera camera;
  SystemOptions options;
  apply_config(file, camera, options);
  EXPECT_DOUBLE_EQ(camera.fx, 535.4);
  EXPECT_DOUBLE_EQ(camera.cy, 247.6);
  EXPECT_EQ(camera.width, 640);
  EXPECT_DOUBLE_EQ(camera.depth_factor, 5000.0);
  EXPECT_EQ(options.orb.num_features, 1200);
  EXPECT_EQ(options.tracker.max_frames_between_keyframes, 30);
  // ThDepth 40 is ORB-SLAM2's one close-depth threshold: both of mcslam's take it.
  EXPECT_DOUBLE_EQ(options.tracker.close_depth_factor, 40.0);
  EXPECT_DOUBLE_EQ(options.tracker.keyframe_close_depth_factor, 40.0);
}

TEST(Config, TheRetiredBundleAdjustmentThreadsKeyOfAnEarlierRunStillLoads) {
  // config.yaml of runs before bundle adjustment left Ceres has mapper.ba.num_threads.
  io::ConfigFile file = io::ConfigFile::from_string(
      "camera: {fx: 500, fy: 500, cx: 320, cy: 240, width: 640, height: 480}\n"
      "mapper:\n  ba:\n    robust_iterations: 4\n    num_threads: 1\n",
      "config.yaml");
  PinholeCamera camera;
  SystemOptions options;
  EXPECT_EQ(message_of([&] { apply_config(file, camera, options); }), "");
  EXPECT_EQ(options.mapper.ba.robust_iterations, 4);
}

TEST(Config, UnknownKeysAndBadValuesAreErrorsNamingTheFile) {
  PinholeCamera camera;
  SystemOptions options;
  io::ConfigFile typo = io::ConfigFile::from_string("orb:\n  num_featurs: 10\n", "my.yaml");
  const std::string m1 = message_of([&] { apply_config(typo, camera, options); });
  EXPECT_NE(m1.find("my.yaml"), std::string::npos) << m1;
  EXPECT_NE(m1.find("orb.num_featurs"), std::string::npos) << m1;

  io::ConfigFile zero_fx = io::ConfigFile::from_string(
      "camera: {fx: 0, fy: 500, cx: 320, cy: 240, width: 640, height: 480}\n", "cam.yaml");
  const std::string m2 = message_of([&] { apply_config(zero_fx, camera, options); });
  EXPECT_NE(m2.find("cam.yaml"), std::string::npos) << m2;
  EXPECT_NE(m2.find("fx"), std::string::npos) << m2;

  io::ConfigFile negative = io::ConfigFile::from_string(
      "camera: {fx: 500, fy: 500, cx: 320, cy: 240, width: 640, height: 480, "
      "depth_factor: -5000}\n",
      "neg.yaml");
  EXPECT_NE(message_of([&] { apply_config(negative, camera, options); }).find("depth"),
            std::string::npos);

  io::ConfigFile bad_option = io::ConfigFile::from_string("tracker: {max_depth: -1}\n", "opt.yaml");
  PinholeCamera good;
  good.fx = good.fy = 500;
  good.cx = 320;
  good.cy = 240;
  good.width = 640;
  good.height = 480;
  EXPECT_NE(message_of([&] { apply_config(bad_option, good, options); }).find("max_depth"),
            std::string::npos);

  // The detector's scale: 0 (the model's own input) or a factor a network can run at.
  for (const char* value : {"-0.35", "0.01", "5"}) {
    SystemOptions fresh;
    io::ConfigFile scale = io::ConfigFile::from_string(
        std::string("system: {detector_scale: ") + value + "}\n", "scale.yaml");
    const std::string m = message_of([&] { apply_config(scale, good, fresh); });
    EXPECT_NE(m.find("system.detector_scale"), std::string::npos) << value << ": " << m;
  }
  // Each bad tracker setting: the message names it.
  for (const auto& [text, key] : std::vector<std::pair<std::string, std::string>>{
           {"tracker: {established_age: -1}\n", "tracker.established_age"},
           {"tracker: {established_gate: 0.5}\n", "tracker.established_gate"},
           {"tracker: {recovery_window: -0.5}\n", "tracker.recovery_window"},
           {"tracker: {recovery_window: x}\n", "tracker.recovery_window"},
           {"tracker: {angular_velocity_sigma: 0}\n", "tracker.angular_velocity_sigma"},
           {"tracker: {refine_min_angular_velocity: -1}\n", "tracker.refine_min_angular_velocity"},
           {"tracker: {refine_rolling_shutter: often}\n", "tracker.refine_rolling_shutter"},
           {"tracker: {keyframe_interval: -0.5}\n", "tracker.keyframe_interval"},
           {"mapper: {ba: {robust_iterations: 0}}\n", "mapper.ba.robust_iterations"},
           {"mapper: {disparity_residual: sometimes}\n", "mapper.disparity_residual"},
           {"system: {extract_ahead: maybe}\n", "system.extract_ahead"},
           {"system: {wait_for_keyframe_points: 2}\n", "system.wait_for_keyframe_points"}}) {
    SystemOptions fresh;
    io::ConfigFile bad = io::ConfigFile::from_string(text, "tracker.yaml");
    const std::string m = message_of([&] { apply_config(bad, good, fresh); });
    EXPECT_NE(m.find(key), std::string::npos) << text << ": " << m;
  }
  SystemOptions own;
  io::ConfigFile own_size =
      io::ConfigFile::from_string("system: {detector_scale: 0}\n", "own.yaml");
  apply_config(own_size, good, own);
  EXPECT_EQ(own.detector_scale, 0.0);
  // system.extract_ahead: auto (the default), or true or false as YAML writes them.
  EXPECT_EQ(own.extract_ahead, "auto");
  for (const char* value : {"true", "false"}) {
    SystemOptions set;
    io::ConfigFile ahead = io::ConfigFile::from_string(
        std::string("system: {extract_ahead: ") + value + "}\n", "ahead.yaml");
    apply_config(ahead, good, set);
    EXPECT_EQ(set.extract_ahead, value);
  }
}

TEST(Config, CameraFromFolderNameCameraYamlAndSettings) {
  TempDir dir;
  fs::create_directories(dir.path() / "rgbd_dataset_freiburg1_xyz");
  const RunConfig fr1 =
      resolve_run_config((dir.path() / "rgbd_dataset_freiburg1_xyz").string(), std::nullopt);
  EXPECT_NEAR(fr1.camera.fx, 517.306408, 1e-9);
  EXPECT_TRUE(fr1.camera.has_distortion());

  fs::create_directories(dir.path() / "my_sequence");
  EXPECT_THROW(resolve_run_config((dir.path() / "my_sequence").string(), std::nullopt), InputError);
  dir.write("my_sequence/camera.yaml",
            "camera:\n  fx: 500\n  fy: 501\n  cx: 319.5\n  cy: 239.5\n  width: 640\n  height: "
            "480\n  depth_factor: 5000\n  bf: 40\n");
  const RunConfig own = resolve_run_config((dir.path() / "my_sequence").string(), std::nullopt);
  EXPECT_DOUBLE_EQ(own.camera.fy, 501.0);

  const auto settings =
      dir.write("override.yaml", "camera:\n  fx: 480\norb:\n  num_features: 800\n");
  const RunConfig over =
      resolve_run_config((dir.path() / "my_sequence").string(), settings.string());
  EXPECT_DOUBLE_EQ(over.camera.fx, 480.0);
  EXPECT_DOUBLE_EQ(over.camera.fy, 501.0);
  EXPECT_EQ(over.options.orb.num_features, 800);
}

TEST(Config, CameraOfASourcePresetEmbeddedSettingsCameraInfoAndSettingsFile) {
  TempDir dir;
  const std::string bag = (dir.path() / "rgbd_dataset_freiburg3_walking.bag").string();
  // The file name chooses the preset, --camera-preset replaces it.
  EXPECT_NEAR(resolve_run_config(bag, std::nullopt, {}, std::nullopt).camera.fx, 535.4, 1e-9);
  EXPECT_NEAR(resolve_run_config(bag, std::nullopt, {}, "tum_fr1").camera.fx, 517.306408, 1e-9);
  EXPECT_NE(message_of([&] {
              resolve_run_config(bag, std::nullopt, {}, "kinect9");
            }).find("--camera-preset: unknown preset 'kinect9'"),
            std::string::npos);

  // Embedded settings, then CameraInfo's intrinsics, then the settings file.
  io::CameraHints hints;
  hints.settings_yaml =
      "camera:\n  fx: 500\n  fy: 500\n  cx: 160\n  cy: 120\n  width: 320\n"
      "  height: 240\n  readout_time: 0.01\n";
  hints.settings_name = "x.bag:/mcslam/camera_settings";
  const std::string plain = (dir.path() / "x.bag").string();
  const RunConfig embedded = resolve_run_config(plain, std::nullopt, hints, std::nullopt);
  EXPECT_DOUBLE_EQ(embedded.camera.fx, 500.0);
  EXPECT_DOUBLE_EQ(embedded.camera.readout_time, 0.01);
  hints.intrinsics = io::CameraHints::Intrinsics{610.0, 611.0, 321.0, 241.0, 640, 480, {0.1}};
  hints.intrinsics_name = "x.bag:/camera/color/camera_info";
  const RunConfig info = resolve_run_config(plain, std::nullopt, hints, std::nullopt);
  EXPECT_DOUBLE_EQ(info.camera.fy, 611.0);
  EXPECT_EQ(info.camera.width, 640);
  EXPECT_DOUBLE_EQ(info.camera.distortion[0], 0.1);
  EXPECT_DOUBLE_EQ(info.camera.readout_time, 0.01);  // kept from the embedded settings
  const auto settings = dir.write("fx.yaml", "camera:\n  fx: 600\n");
  EXPECT_DOUBLE_EQ(resolve_run_config(plain, settings.string(), hints, std::nullopt).camera.fx,
                   600.0);

  // Nothing to go by: one error naming the source.
  EXPECT_NE(message_of([&] {
              resolve_run_config(plain, std::nullopt, {}, std::nullopt);
            }).find(plain + ": cannot tell the camera"),
            std::string::npos);
}

TEST(Config, EffectiveConfigLoadsBackUnchanged) {
  RunConfig config;
  config.camera.fx = 525;
  config.camera.fy = 526;
  config.camera.cx = 319.5;
  config.camera.cy = 239.5;
  config.camera.width = 640;
  config.camera.height = 480;
  config.options.orb.num_features = 1234;
  config.options.tracker.depth_weight = 0.25;
  config.options.mapper.ba_keyframes = 17;
  config.options.mapper.disparity_residual = true;
  config.options.sequential = true;
  config.options.tracker.dynamics.frame_gap = 3;
  config.options.tracker.dynamics.constrained_classes = {"chair", "dining table"};
  config.camera_source = "test";
  io::ConfigFile file = io::ConfigFile::from_string(to_yaml(config), "config.yaml");
  PinholeCamera camera;
  SystemOptions options;
  apply_config(file, camera, options);  // throws on any key it does not know
  EXPECT_DOUBLE_EQ(camera.fy, 526.0);
  EXPECT_EQ(options.orb.num_features, 1234);
  EXPECT_DOUBLE_EQ(options.tracker.depth_weight, 0.25);
  EXPECT_EQ(options.mapper.ba_keyframes, 17);
  EXPECT_TRUE(options.mapper.disparity_residual);
  EXPECT_TRUE(options.sequential);
  EXPECT_EQ(options.tracker.dynamics.frame_gap, 3);
  EXPECT_EQ(options.tracker.dynamics.constrained_classes,
            (std::vector<std::string>{"chair", "dining table"}));
}

TEST(Config, DynamicsSettingsAreCheckedAndNamed) {
  io::ConfigFile file = io::ConfigFile::from_string(
      "dynamics:\n  outlier_ratio: 1.5\n  constrained_classes: chair,  couch \n", "bad.yaml");
  PinholeCamera camera;
  camera.fx = camera.fy = 500;
  camera.cx = 320;
  camera.cy = 240;
  camera.width = 640;
  camera.height = 480;
  SystemOptions options;
  try {
    apply_config(file, camera, options);
    ADD_FAILURE() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.yaml"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("dynamics.outlier_ratio"), std::string::npos) << e.what();
  }
  EXPECT_EQ(options.tracker.dynamics.constrained_classes,
            (std::vector<std::string>{"chair", "couch"}));
}

}  // namespace
}  // namespace mcslam::slam
