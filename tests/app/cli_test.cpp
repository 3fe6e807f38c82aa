// Tests of the real `mcslam` binary: outputs of `run`, `eval` and `synth`, and the exit code and
// message for bad input.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "mcslam/synth/sequence.hpp"
#include "support/cli_runner.hpp"

#ifndef MCSLAM_EXE
#error "MCSLAM_EXE must name the mcslam executable"
#endif

namespace {

namespace fs = std::filesystem;

// --- temporary folder, one per process, removed at the end -------------------------------------

std::optional<fs::path>& root_slot() {
  static std::optional<fs::path> root;
  return root;
}

const fs::path& root() {
  auto& slot = root_slot();
  if (!slot) {
    std::random_device rd;
    const auto ticks = std::chrono::steady_clock::now().time_since_epoch().count();
    const fs::path dir =
        fs::temp_directory_path() / ("mcslam_cli_test_" + std::to_string(::getpid()) + "_" +
                                     std::to_string(rd()) + "_" + std::to_string(ticks));
    fs::create_directories(dir);
    slot = dir;
  }
  return *slot;
}

class TempRootEnvironment : public testing::Environment {
 public:
  void TearDown() override {
    if (auto& slot = root_slot()) {
      std::error_code ec;
      fs::remove_all(*slot, ec);
      slot.reset();
    }
  }
};

[[maybe_unused]] testing::Environment* const kTempRootEnvironment =
    testing::AddGlobalTestEnvironment(new TempRootEnvironment);

// --- running the binary ------------------------------------------------------------------------

using mcslam::test::CliResult;
using mcslam::test::contains;
using mcslam::test::quote;
using mcslam::test::read_file;
using mcslam::test::write_file;

/// Runs `mcslam <args>` (args already quoted) and captures its exit code and output.
CliResult run_cli(const std::string& args) {
  static int counter = 0;
  const int n = counter++;
  return mcslam::test::run_command(MCSLAM_EXE, args,
                                   root() / ("stdout_" + std::to_string(n) + ".txt"),
                                   root() / ("stderr_" + std::to_string(n) + ".txt"));
}

/// Bad input: exit code 1 (not 0, not a crash) and stderr containing every given piece.
void expect_input_error(const CliResult& r, const std::vector<std::string>& pieces) {
  EXPECT_FALSE(r.crashed) << r;
  EXPECT_EQ(r.exit_code, 1) << r;
  for (const auto& piece : pieces)
    EXPECT_NE(r.err.find(piece), std::string::npos) << "stderr lacks '" << piece << "'\n" << r;
}

// --- sequences and runs shared by the tests of one process -------------------------------------

const fs::path& main_sequence() {
  static const fs::path dir = [] {
    const fs::path d = root() / "synth_seq";
    mcslam::synth::SynthOptions options;
    options.frames = 40;  // 640x480 default camera
    mcslam::synth::write_sequence(d.string(), options);
    return d;
  }();
  return dir;
}

/// A tiny sequence to copy and break.
const fs::path& small_sequence() {
  static const fs::path dir = [] {
    const fs::path d = root() / "small_seq";
    mcslam::synth::SynthOptions options;
    options.frames = 3;
    options.width = 160;
    options.height = 120;
    options.fx = options.fy = 525.0 / 4.0;
    options.cx = 79.5;
    options.cy = 59.5;
    mcslam::synth::write_sequence(d.string(), options);
    return d;
  }();
  return dir;
}

fs::path copy_of_small_sequence(const std::string& name) {
  const fs::path dst = root() / name;
  fs::copy(small_sequence(), dst, fs::copy_options::recursive);
  return dst;
}

struct MainRun {
  fs::path out;
  CliResult result;
};

/// `mcslam run SEQ --output OUT --sequential --save-map -q` on the main sequence, once per process.
const MainRun& main_run() {
  static const MainRun run = [] {
    MainRun r;
    r.out = root() / "out";
    r.result = run_cli("run " + quote(main_sequence().string()) + " --output " +
                       quote(r.out.string()) + " --sequential --save-map -q");
    return r;
  }();
  return run;
}

std::vector<std::string> lines_of(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

/// First-column values of the non-comment, non-empty lines of a TUM-style file.
std::vector<double> timestamps_of(const fs::path& path) {
  std::vector<double> out;
  for (const auto& line : lines_of(path)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream s(line);
    double t = 0.0;
    s >> t;
    out.push_back(t);
  }
  return out;
}

nlohmann::json read_json(const fs::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// --- run ---------------------------------------------------------------------------------------

TEST(CliRun, WritesAllOutputs) {
  const MainRun& run = main_run();
  ASSERT_EQ(run.result.exit_code, 0) << run.result;
  EXPECT_TRUE(run.result.out.empty()) << "-q prints nothing\n" << run.result;
  for (const char* name :
       {"trajectory.txt", "trajectory_unsmoothed.txt", "trajectory_online.txt", "keyframes.txt",
        "timings.csv", "summary.json", "config.yaml", "map.ply", "map.json"})
    EXPECT_TRUE(fs::is_regular_file(run.out / name)) << name;

  const nlohmann::json summary = read_json(run.out / "summary.json");
  ASSERT_TRUE(summary.contains("frames"));
  EXPECT_EQ(summary["frames"].get<int>(), 40);
  ASSERT_TRUE(summary.contains("tracked_ratio"));
  EXPECT_GE(summary["tracked_ratio"].get<double>(), 0.9);
  ASSERT_TRUE(summary.contains("lost_frames"));
  EXPECT_EQ(summary["lost_frames"].get<int>(), 0);
  EXPECT_TRUE(summary.contains("relocalisations"));
  // Every tracked frame is counted once: the frame that starts the map (its pose set, not
  // estimated) as "off", the others through the filter (on by default).
  ASSERT_TRUE(summary.contains("pose_filter"));
  int filtered = 0;
  for (const char* outcome : {"fused", "downweighted", "held", "restarted"})
    filtered += summary["pose_filter"][outcome].get<int>();
  EXPECT_EQ(filtered + 1, summary["tracked_frames"].get<int>()) << summary["pose_filter"];
  EXPECT_EQ(summary["pose_filter"]["off"].get<int>(), 1);
  EXPECT_GE(summary["pose_filter"]["restarted"].get<int>(), 1) << "the filter starts once";
  ASSERT_TRUE(summary.contains("stages"));
  ASSERT_TRUE(summary["stages"].contains("tracking_total"));
  ASSERT_TRUE(summary["stages"]["tracking_total"].contains("median_ms"));
  EXPECT_GT(summary["stages"]["tracking_total"]["median_ms"].get<double>(), 0.0);
  ASSERT_TRUE(summary.contains("ate_rmse_m")) << "groundtruth.txt exists";
  EXPECT_LT(summary["ate_rmse_m"].get<double>(), 0.02);
  EXPECT_GE(summary["ate_rmse_m"].get<double>(), 0.0);

  // trajectory.txt: a header comment and one line per tracked frame, stamped as in rgb.txt.
  const auto trajectory_lines = lines_of(run.out / "trajectory.txt");
  ASSERT_FALSE(trajectory_lines.empty());
  EXPECT_EQ(trajectory_lines.front().rfind("#", 0), 0u);
  const std::vector<double> stamps = timestamps_of(run.out / "trajectory.txt");
  EXPECT_EQ(static_cast<int>(stamps.size()), summary["tracked_frames"].get<int>());
  const std::vector<double> rgb = timestamps_of(main_sequence() / "rgb.txt");
  ASSERT_EQ(rgb.size(), 40u);
  const std::set<double> rgb_set(rgb.begin(), rgb.end());
  for (double t : stamps) EXPECT_EQ(rgb_set.count(t), 1u) << "trajectory timestamp " << t;
  if (summary["tracked_ratio"].get<double>() == 1.0) {
    EXPECT_EQ(stamps, rgb);
  }

  EXPECT_EQ(timestamps_of(run.out / "trajectory_online.txt"), stamps);
  EXPECT_EQ(timestamps_of(run.out / "trajectory_unsmoothed.txt"), stamps);
  // The positions were smoothed: the noise was estimated, and the unsmoothed ATE is reported.
  const nlohmann::json& smoothing = summary["trajectory_smoothing"];
  EXPECT_TRUE(smoothing["applied"].get<bool>()) << smoothing;
  EXPECT_GT(smoothing["position_noise_m"].get<double>(), 0.0);
  EXPECT_EQ(smoothing["segments"].get<int>(), 1);
  ASSERT_TRUE(smoothing.contains("unsmoothed_ate_rmse_m"));
  EXPECT_LT(smoothing["unsmoothed_ate_rmse_m"].get<double>(), 0.02);
  EXPECT_NE(read_file(run.out / "trajectory.txt"),
            read_file(run.out / "trajectory_unsmoothed.txt"));
  const std::vector<double> keyframes = timestamps_of(run.out / "keyframes.txt");
  EXPECT_GE(keyframes.size(), 1u);
  for (double t : keyframes) EXPECT_EQ(rgb_set.count(t), 1u) << "keyframe timestamp " << t;

  // timings.csv: a header and one row per frame.
  const auto csv = lines_of(run.out / "timings.csv");
  ASSERT_EQ(csv.size(), 41u);
  EXPECT_EQ(csv.front().rfind("frame,timestamp,state", 0), 0u) << csv.front();
  EXPECT_NE(csv.front().find("total_ms"), std::string::npos);
  for (std::size_t i = 1; i < csv.size(); ++i)
    EXPECT_EQ(csv[i].rfind(std::to_string(i - 1) + ",", 0), 0u) << csv[i];
  for (const char* column : {",points,", ",lines,", ",planes,", ",line_inliers,", ",plane_inliers,",
                             ",line_extract_ms,", ",plane_extract_ms,"})
    EXPECT_NE(csv.front().find(column), std::string::npos) << column;

  // Line and plane figures in the summary.
  ASSERT_TRUE(summary.contains("lines_in_map"));
  ASSERT_TRUE(summary.contains("planes_in_map"));
  EXPECT_GT(summary["planes_in_map"].get<int>(), 0);
  ASSERT_TRUE(summary["stages"].contains("line_extract"));
  ASSERT_TRUE(summary["stages"].contains("plane_extract"));
  ASSERT_TRUE(summary["per_frame_counts"].contains("line_inliers"));
}

TEST(CliRun, RealTimeRunAccountsForEveryFrame) {
  // 40 frames at 30 Hz delivered at their timestamps: each one is processed or dropped, and the
  // summary and timings.csv say which, with the latency of each processed frame.
  const fs::path out = root() / "out_realtime";
  const CliResult r = run_cli("run " + quote(main_sequence().string()) + " --output " +
                              quote(out.string()) + " --realtime -q");
  ASSERT_EQ(r.exit_code, 0) << r;
  const nlohmann::json summary = read_json(out / "summary.json");
  ASSERT_TRUE(summary.contains("realtime")) << summary.dump(1);
  const auto& rt = summary["realtime"];
  EXPECT_EQ(rt["frames_offered"].get<int>(), 40);
  EXPECT_EQ(rt["frames_processed"].get<int>() + rt["frames_dropped"].get<int>(), 40);
  EXPECT_EQ(rt["frames_processed"].get<int>(), summary["frames"].get<int>());
  EXPECT_GT(rt["latency_median_ms"].get<double>(), 0.0);
  EXPECT_LE(rt["coverage"].get<double>(), rt["processed_ratio"].get<double>());
  const auto csv = lines_of(out / "timings.csv");
  ASSERT_EQ(csv.size(), static_cast<std::size_t>(rt["frames_processed"].get<int>()) + 1);
  EXPECT_NE(csv.front().find(",dropped_before,latency_ms"), std::string::npos) << csv.front();
  // The images were prepared off the frame loop.
  EXPECT_TRUE(summary["stages"].contains("prepare"));
  EXPECT_FALSE(summary["stages"].contains("undistort"));
  // lines.detector auto: the region detector in both; planes.pixel_step auto: every 3rd pixel in
  // both (config.yaml holds the effective values).
  const auto has_line = [](const std::vector<std::string>& lines, const std::string& text) {
    return std::any_of(lines.begin(), lines.end(),
                       [&](const std::string& l) { return l.find(text) != std::string::npos; });
  };
  EXPECT_TRUE(has_line(lines_of(out / "config.yaml"), "detector: region"));
  EXPECT_TRUE(has_line(lines_of(main_run().out / "config.yaml"), "detector: region"));
  EXPECT_TRUE(has_line(lines_of(out / "config.yaml"), "pixel_step: 3"));
  EXPECT_TRUE(has_line(lines_of(main_run().out / "config.yaml"), "pixel_step: 3"));
  // system.extract_ahead auto: in real time the reader extracts while the loop tracks the frame
  // before, and the loop only finishes the features; offline the frame's own thread extracts
  // and waits for its lines and planes. Set to true, the reader extracts offline too.
  EXPECT_FALSE(summary["stages"].contains("extract_wait")) << summary["stages"].dump(1);
  EXPECT_TRUE(summary["stages"].contains("feature_finish")) << summary["stages"].dump(1);
  EXPECT_TRUE(has_line(lines_of(out / "config.yaml"), "extract_ahead: true"));
  EXPECT_TRUE(has_line(lines_of(main_run().out / "config.yaml"), "extract_ahead: false"));
  EXPECT_TRUE(read_json(main_run().out / "summary.json")["stages"].contains("extract_wait"));
  write_file(root() / "ahead.yaml", "system:\n  extract_ahead: true\n");
  for (const char* mode : {"", " --realtime"}) {
    const fs::path ahead_out = root() / (std::string("out_ahead") + (*mode ? "_rt" : ""));
    const CliResult ahead = run_cli(
        "run " + quote(main_sequence().string()) + " --output " + quote(ahead_out.string()) +
        " -c " + quote((root() / "ahead.yaml").string()) + " --max-frames 15 -q" + mode);
    ASSERT_EQ(ahead.exit_code, 0) << ahead;
    EXPECT_TRUE(has_line(lines_of(ahead_out / "config.yaml"), "extract_ahead: true"));
    const nlohmann::json done = read_json(ahead_out / "summary.json");
    EXPECT_FALSE(done["stages"].contains("extract_wait")) << mode << done["stages"].dump(1);
    EXPECT_TRUE(done["stages"].contains("feature_finish")) << mode << done["stages"].dump(1);
    EXPECT_TRUE(done["stages"].contains("orb_extract")) << mode << done["stages"].dump(1);
    EXPECT_GE(done["tracked_frames"].get<int>(), *mode ? 1 : 15) << mode;
  }
  // Together with --repeat it is refused, with one message.
  const CliResult both =
      run_cli("run " + quote(main_sequence().string()) + " --output " +
              quote((root() / "out_rt_repeat").string()) + " --realtime --repeat 2 -q");
  EXPECT_EQ(both.exit_code, 1) << both;
  EXPECT_NE(both.err.find("--realtime"), std::string::npos) << both;
}

// camera.readout_time: auto on a recorded sequence runs the calibration pass first and reports it.
// The synthetic camera turns too slowly for a confident estimate: the run then starts from the
// configured value and goes on estimating.
TEST(CliRun, ReadoutAutoRunsTheCalibrationPass) {
  const fs::path config = root() / "readout_auto.yaml";
  write_file(config, "camera:\n  readout_time: auto\n");
  const fs::path out = root() / "o_readout_auto";
  const CliResult r =
      run_cli("run " + quote(small_sequence().string()) + " --output " + quote(out.string()) +
              " --config " + quote(config.string()) + " --sequential -q");
  ASSERT_EQ(r.exit_code, 0) << r;
  const nlohmann::json readout = read_json(out / "summary.json")["readout"];
  EXPECT_EQ(readout["mode"], "auto");
  ASSERT_TRUE(readout.contains("calibration")) << readout.dump();
  const nlohmann::json& c = readout["calibration"];
  EXPECT_GE(c["frames"].get<int>(), 1);
  EXPECT_LE(c["frames"].get<int>(), 3);
  EXPECT_FALSE(c["confident"].get<bool>());
  EXPECT_GE(c["wall_ms"].get<double>(), 0.0);
  bool auto_in_yaml = false;
  for (const auto& line : lines_of(out / "config.yaml"))
    auto_in_yaml = auto_in_yaml || line.find("readout_time: auto") != std::string::npos;
  EXPECT_TRUE(auto_in_yaml);
}

TEST(CliRun, SavedMapIsAValidPlyAndJson) {
  const MainRun& run = main_run();
  ASSERT_EQ(run.result.exit_code, 0) << run.result;
  const nlohmann::json summary = read_json(run.out / "summary.json");
  const auto ply = lines_of(run.out / "map.ply");
  ASSERT_GT(ply.size(), 10u);
  EXPECT_EQ(ply[0], "ply");
  EXPECT_EQ(ply[1], "format ascii 1.0");
  std::size_t vertices = 0, edges = 0, faces = 0, header = 0;
  for (; header < ply.size() && ply[header] != "end_header"; ++header) {
    std::istringstream words(ply[header]);
    std::string w, kind;
    std::size_t n = 0;
    if (words >> w >> kind >> n && w == "element")
      (kind == "vertex" ? vertices : kind == "edge" ? edges : faces) = n;
  }
  ASSERT_LT(header, ply.size());
  EXPECT_EQ(ply.size() - header - 1, vertices + edges + faces);
  EXPECT_EQ(edges, summary["lines_in_map"].get<std::size_t>());
  EXPECT_GE(vertices, summary["points_in_map"].get<std::size_t>() + 2 * edges);

  const nlohmann::json map = read_json(run.out / "map.json");
  EXPECT_EQ(map["points"].size(), summary["points_in_map"].get<std::size_t>());
  EXPECT_EQ(map["lines"].size(), summary["lines_in_map"].get<std::size_t>());
  EXPECT_EQ(map["planes"].size(), summary["planes_in_map"].get<std::size_t>());
  EXPECT_EQ(map["keyframes"].size(), summary["keyframes_in_map"].get<std::size_t>());
  ASSERT_FALSE(map["points"].empty());
  EXPECT_FALSE(map["points"][0]["observations"].empty());
}

TEST(CliRun, FeatureSwitches) {
  const fs::path out = root() / "out_points_only";
  const CliResult r = run_cli("run " + quote(main_sequence().string()) + " --output " +
                              quote(out.string()) + " --sequential --features points -q");
  ASSERT_EQ(r.exit_code, 0) << r;
  const nlohmann::json summary = read_json(out / "summary.json");
  EXPECT_EQ(summary["lines_in_map"].get<int>(), 0);
  EXPECT_EQ(summary["planes_in_map"].get<int>(), 0);
  EXPECT_FALSE(summary["features"]["lines"].get<bool>());
  EXPECT_FALSE(summary["stages"].contains("line_extract"));

  const CliResult bad =
      run_cli("run " + quote(main_sequence().string()) + " --output " +
              quote((root() / "out_bad_features").string()) + " --features points,curves -q");
  EXPECT_EQ(bad.exit_code, 1) << bad;
  EXPECT_NE(bad.err.find("curves"), std::string::npos) << bad;
}

TEST(CliRun, SmoothingOffWritesTheUnsmoothedPoses) {
  const fs::path out = root() / "out_unsmoothed";
  fs::create_directories(out);
  const fs::path config = out / "off.yaml";
  mcslam::test::write_file(config, "trajectory:\n  smoothing: false\n");
  const CliResult r =
      run_cli("run " + quote(main_sequence().string()) + " --output " + quote(out.string()) +
              " --config " + quote(config.string()) + " --sequential -q");
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_EQ(read_file(out / "trajectory.txt"), read_file(out / "trajectory_unsmoothed.txt"));
  const nlohmann::json summary = read_json(out / "summary.json");
  EXPECT_FALSE(summary["trajectory_smoothing"]["applied"].get<bool>());
  EXPECT_FALSE(summary["trajectory_smoothing"].contains("unsmoothed_ate_rmse_m"));
  // The sequential run's unsmoothed poses are those of the run with smoothing on.
  const MainRun& run = main_run();
  EXPECT_EQ(read_file(out / "trajectory_unsmoothed.txt"),
            read_file(run.out / "trajectory_unsmoothed.txt"));
}

// A background thread that throws (here the mapper, made to by --inject-failure) ends the run
// with exit 1 and a message naming it, after writing what was tracked until then.
TEST(CliRun, AFailedMapperThreadEndsTheRunWithItsOutputsWritten) {
  for (const char* mode : {"", " --sequential"}) {
    const fs::path out = root() / (std::string("out_mapper_failure") + (*mode ? "_seq" : ""));
    const CliResult r = run_cli("run " + quote(main_sequence().string()) + " --output " +
                                quote(out.string()) + mode + " --inject-failure mapper:2 -q");
    EXPECT_EQ(r.exit_code, 1) << r;
    EXPECT_FALSE(r.crashed) << r;
    EXPECT_TRUE(contains(r.err, "failure injected at keyframe 2")) << r;
    EXPECT_TRUE(contains(r.err, "the outputs of the")) << r;
    const std::vector<double> poses = timestamps_of(out / "trajectory.txt");
    EXPECT_FALSE(poses.empty());
    EXPECT_FALSE(timestamps_of(out / "trajectory_online.txt").empty());
    EXPECT_TRUE(contains(read_file(out / "trajectory.txt"), "# failed after frame"));
    const nlohmann::json summary = read_json(out / "summary.json");
    EXPECT_EQ(summary["state"], "failed");
    EXPECT_TRUE(contains(summary["failure"].get<std::string>(), "mapper")) << summary["failure"];
    EXPECT_EQ(read_json(out / "status.json")["state"], "failed");
  }
  const CliResult bad =
      run_cli("run " + quote(main_sequence().string()) + " --output " +
              quote((root() / "out_bad_inject").string()) + " --inject-failure mapper -q");
  EXPECT_EQ(bad.exit_code, 1) << bad;
  EXPECT_TRUE(contains(bad.err, "expected THREAD:N")) << bad;
}

TEST(CliRun, FirstFrameStartsTheRunThere) {
  // --first-frame 25 of 40: the run covers frames 25..39, as a recording that began there; its
  // first pose is stamped with frame 25's time and the ground truth is scored on those frames.
  const fs::path out = root() / "out_first_frame";
  const CliResult r = run_cli("run " + quote(main_sequence().string()) + " --output " +
                              quote(out.string()) + " --sequential --first-frame 25 -q");
  ASSERT_EQ(r.exit_code, 0) << r;
  const nlohmann::json summary = read_json(out / "summary.json");
  EXPECT_EQ(summary["frames"].get<int>(), 15);
  const std::vector<double> rgb = timestamps_of(main_sequence() / "rgb.txt");
  const std::vector<double> poses = timestamps_of(out / "trajectory.txt");
  ASSERT_FALSE(poses.empty());
  EXPECT_NEAR(poses.front(), rgb[25], 1e-6);
  EXPECT_EQ(summary["eval"]["matched"].get<int>(), static_cast<int>(poses.size()));

  const CliResult past =
      run_cli("run " + quote(main_sequence().string()) + " --output " +
              quote((root() / "out_first_frame_past").string()) + " --first-frame 40 -q");
  EXPECT_EQ(past.exit_code, 1) << past;
  EXPECT_NE(past.err.find("--first-frame 40"), std::string::npos) << past;
}

TEST(CliRun, EffectiveConfigLoadsBackAndSequentialRunIsDeterministic) {
  const MainRun& run = main_run();
  ASSERT_EQ(run.result.exit_code, 0) << run.result;
  const fs::path out2 = root() / "out2";
  const CliResult r =
      run_cli("run " + quote(main_sequence().string()) + " --output " + quote(out2.string()) +
              " --config " + quote((run.out / "config.yaml").string()) + " --sequential -q");
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_EQ(read_file(out2 / "trajectory.txt"), read_file(run.out / "trajectory.txt"));
  EXPECT_EQ(read_file(out2 / "keyframes.txt"), read_file(run.out / "keyframes.txt"));
  // The effective configuration is the same (the first line names where the camera came from).
  auto config1 = lines_of(run.out / "config.yaml");
  auto config2 = lines_of(out2 / "config.yaml");
  ASSERT_FALSE(config1.empty());
  ASSERT_FALSE(config2.empty());
  config1.erase(config1.begin());
  config2.erase(config2.begin());
  EXPECT_EQ(config1, config2);
}

// --- eval --------------------------------------------------------------------------------------

TEST(CliEval, PrintsJsonWithAte) {
  const MainRun& run = main_run();
  ASSERT_EQ(run.result.exit_code, 0) << run.result;
  const CliResult r = run_cli("eval --gt " + quote((main_sequence() / "groundtruth.txt").string()) +
                              " --est " + quote((run.out / "trajectory.txt").string()) + " --json");
  ASSERT_EQ(r.exit_code, 0) << r;
  nlohmann::json report;
  ASSERT_NO_THROW(report = nlohmann::json::parse(r.out)) << r;
  ASSERT_TRUE(report.contains("ate_rmse_m")) << report.dump(2);
  EXPECT_GE(report["ate_rmse_m"].get<double>(), 0.0);
  EXPECT_LT(report["ate_rmse_m"].get<double>(), 0.02);
  const nlohmann::json summary = read_json(run.out / "summary.json");
  EXPECT_NEAR(report["ate_rmse_m"].get<double>(), summary["ate_rmse_m"].get<double>(), 1e-6);
}

/// An estimate 1000 s later than the ground truth.
fs::path shifted_estimate() {
  const fs::path est = root() / "shifted_estimate.txt";
  write_file(est,
             "# timestamp tx ty tz qx qy qz qw\n"
             "1001.0 0 0 0 0 0 0 1\n"
             "1001.1 0.01 0 0 0 0 0 1\n"
             "1001.2 0.02 0 0 0 0 0 1\n");
  return est;
}

TEST(CliEval, EstimateWithoutTimeOverlapIsAnInputError) {
  const fs::path est = shifted_estimate();
  const CliResult r =
      run_cli("eval --gt " + quote((small_sequence() / "groundtruth.txt").string()) + " --est " +
              quote(est.string()));
  expect_input_error(r, {"no estimated pose"});
}

// A time overlap error names the estimate and the ground truth.
TEST(CliEval, EstimateWithoutTimeOverlapNamesTheFile) {
  const fs::path est = shifted_estimate();
  const CliResult r =
      run_cli("eval --gt " + quote((small_sequence() / "groundtruth.txt").string()) + " --est " +
              quote(est.string()));
  expect_input_error(r, {est.string()});
}

// --- bad input to run --------------------------------------------------------------------------

TEST(CliBadInput, MissingSequenceFolder) {
  const fs::path missing = root() / "no_such_sequence";
  const CliResult r =
      run_cli("run " + quote(missing.string()) + " --output " + quote((root() / "o").string()));
  expect_input_error(r, {missing.string(), "not found"});
}

TEST(CliBadInput, MalformedRgbListLine) {
  const fs::path seq = copy_of_small_sequence("bad_rgb_list");
  // The list has 3 comment lines, then one line per frame: break the second frame (line 5).
  auto lines = lines_of(seq / "rgb.txt");
  ASSERT_GE(lines.size(), 5u);
  ASSERT_NE(lines[3].rfind("#", 0), 0u) << "line 4 is expected to be the first entry";
  lines[4] = "1.033333 rgb/1.033333.png trailing-junk";
  std::string text;
  for (const auto& l : lines) text += l + "\n";
  write_file(seq / "rgb.txt", text);
  const CliResult r = run_cli("run " + quote(seq.string()) + " --output " +
                              quote((root() / "o_bad_rgb").string()) + " --sequential -q");
  expect_input_error(r, {"rgb.txt:5"});
}

TEST(CliBadInput, EightBitDepthImage) {
  const fs::path seq = copy_of_small_sequence("bad_depth");
  // The first depth image listed.
  std::string listed;
  for (const auto& line : lines_of(seq / "depth.txt")) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream s(line);
    double t = 0.0;
    s >> t >> listed;
    break;
  }
  ASSERT_FALSE(listed.empty());
  const fs::path depth = seq / listed;
  ASSERT_TRUE(fs::is_regular_file(depth)) << depth;
  ASSERT_TRUE(cv::imwrite(depth.string(), cv::Mat(120, 160, CV_8UC1, cv::Scalar(40))));
  const CliResult r = run_cli("run " + quote(seq.string()) + " --output " +
                              quote((root() / "o_bad_depth").string()) + " --sequential -q");
  expect_input_error(r, {depth.filename().string(), "16-bit"});
}

TEST(CliBadInput, ConfigWithUnknownKey) {
  const fs::path config = root() / "unknown_key.yaml";
  write_file(config, "orb:\n  num_features: 500\nnot_a_setting: 3\n");
  const CliResult r = run_cli("run " + quote(small_sequence().string()) + " --output " +
                              quote((root() / "o_unknown").string()) + " --config " +
                              quote(config.string()) + " -q");
  expect_input_error(r, {config.string(), "not_a_setting"});
}

TEST(CliBadInput, ConfigWithZeroFocalLength) {
  const fs::path config = root() / "zero_fx.yaml";
  write_file(config, "%YAML:1.0\nCamera.fx: 0\n");
  const CliResult r =
      run_cli("run " + quote(small_sequence().string()) + " --output " +
              quote((root() / "o_fx").string()) + " --config " + quote(config.string()) + " -q");
  expect_input_error(r, {config.string(), "fx"});
}

TEST(CliBadInput, ConfigWithNegativeLineCount) {
  const fs::path config = root() / "bad_lines.yaml";
  write_file(config, "lines:\n  max_lines: -1\n");
  const CliResult r =
      run_cli("run " + quote(small_sequence().string()) + " --output " +
              quote((root() / "o_lines").string()) + " --config " + quote(config.string()) + " -q");
  expect_input_error(r, {config.string(), "max_lines"});
}

TEST(CliBadInput, OutputUnderARegularFile) {
  const fs::path file = root() / "a_regular_file";
  write_file(file, "not a folder\n");
  const fs::path out = file / "results";
  const CliResult r = run_cli("run " + quote(small_sequence().string()) + " --output " +
                              quote(out.string()) + " -q");
  expect_input_error(r, {out.string(), "cannot create"});
}

TEST(CliBadInput, SettingsFileDoesNotExist) {
  const fs::path config = root() / "missing_settings.yaml";
  const CliResult r = run_cli("run " + quote(small_sequence().string()) + " --output " +
                              quote((root() / "o_missing_cfg").string()) + " --config " +
                              quote(config.string()) + " -q");
  expect_input_error(r, {config.string(), "cannot open"});
}

TEST(CliUsage, UnknownSubcommandAndMissingOptionsFail) {
  for (const std::string& args :
       {std::string("frobnicate"), std::string(""),
        "run " + quote(small_sequence().string()),  // no --output
        std::string("eval --gt only.txt"), std::string("synth"),
        "run " + quote(small_sequence().string()) + " --output " +
            quote((root() / "o_usage").string()) + " --sequential --threaded"}) {
    const CliResult r = run_cli(args);
    EXPECT_FALSE(r.crashed) << args << "\n" << r;
    EXPECT_NE(r.exit_code, 0) << args << "\n" << r;
  }
}

// --- synth -------------------------------------------------------------------------------------

TEST(CliSynth, WritesASequenceThatRunReads) {
  const fs::path seq = root() / "cli_synth";
  const CliResult s =
      run_cli("synth --output " + quote(seq.string()) + " --frames 3 --width 160 --height 120 -q");
  ASSERT_EQ(s.exit_code, 0) << s;
  for (const char* name : {"rgb.txt", "depth.txt", "groundtruth.txt", "camera.yaml"})
    EXPECT_TRUE(fs::is_regular_file(seq / name)) << name;
  EXPECT_EQ(timestamps_of(seq / "rgb.txt").size(), 3u);
  EXPECT_EQ(timestamps_of(seq / "depth.txt").size(), 3u);
  EXPECT_EQ(timestamps_of(seq / "groundtruth.txt").size(), 3u);
  const std::string camera = read_file(seq / "camera.yaml");
  EXPECT_NE(camera.find("width: 160"), std::string::npos) << camera;
  EXPECT_NE(camera.find("height: 120"), std::string::npos) << camera;

  const fs::path out = root() / "o_cli_synth";
  const CliResult r = run_cli("run " + quote(seq.string()) + " --output " + quote(out.string()) +
                              " --sequential -q");
  ASSERT_EQ(r.exit_code, 0) << r;
  const nlohmann::json summary = read_json(out / "summary.json");
  EXPECT_EQ(summary["frames"].get<int>(), 3);
  EXPECT_EQ(timestamps_of(out / "trajectory.txt").size(),
            static_cast<std::size_t>(summary["tracked_frames"].get<int>()));
}

}  // namespace

// --- objects: detections, overlays, errors -----------------------------------------------------

namespace {

TEST(CliRunObjects, DetectionsFileGivesObjectsJsonAndOverlays) {
  const fs::path out = root() / "out_objects";
  const fs::path detections = main_sequence() / "detections.json";
  ASSERT_TRUE(fs::is_regular_file(detections)) << "synth writes the oracle boxes";
  const CliResult r = run_cli("run " + quote(main_sequence().string()) + " --output " +
                              quote(out.string()) + " --sequential --max-frames 15 --detections " +
                              quote(detections.string()) + " --save-overlays -q");
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_EQ(r.err.find("geometry only"), std::string::npos) << r;
  const nlohmann::json objects = read_json(out / "objects.json");
  ASSERT_EQ(objects["frames"].size(), 15u);
  bool any_object = false;
  for (const auto& f : objects["frames"])
    for (const auto& o : f["objects"]) {
      any_object = true;
      EXPECT_EQ(o["state"].get<std::string>(), "static") << "the room's objects do not move";
      EXPECT_EQ(o["box"].size(), 4u);
    }
  EXPECT_TRUE(any_object);
  const nlohmann::json summary = read_json(out / "summary.json");
  EXPECT_EQ(summary["dynamics"]["frames_with_boxes"].get<int>(), 15);
  EXPECT_NE(summary["dynamics"]["source"].get<std::string>().find("detections file"),
            std::string::npos);
  EXPECT_NE(lines_of(out / "timings.csv").front().find("dynamic_points"), std::string::npos);
  const cv::Mat overlay = cv::imread((out / "overlays" / "000010.jpg").string());
  EXPECT_EQ(overlay.cols, 640);
  EXPECT_EQ(overlay.rows, 480);
}

TEST(CliRunObjects, WithoutBoxesWarnsOnceAndRuns) {
  const fs::path out = root() / "out_no_boxes";
  const CliResult r = run_cli("run " + quote(main_sequence().string()) + " --output " +
                              quote(out.string()) + " --sequential --max-frames 3 -q");
  ASSERT_EQ(r.exit_code, 0) << r;
  const auto first = r.err.find("geometry only");
  ASSERT_NE(first, std::string::npos) << r;
  EXPECT_EQ(r.err.find("geometry only", first + 1), std::string::npos) << r;
  EXPECT_FALSE(fs::exists(out / "objects.json"));
}

TEST(CliRunObjects, BadBoxSourcesAreInputErrors) {
  const std::string seq = quote(main_sequence().string());
  const fs::path det = main_sequence() / "detections.json";
  const std::string out = " --output " + quote((root() / "out_bad_boxes").string()) + " -q";
  expect_input_error(run_cli("run " + seq + out + " --detections " + quote(det.string()) +
                             " --model " + quote(det.string())),
                     {"exclude each other"});
  const fs::path garbage = root() / "garbage_detections.json";
  write_file(garbage, "{ not json");
  expect_input_error(run_cli("run " + seq + out + " --detections " + quote(garbage.string())),
                     {garbage.string(), "not valid JSON"});
  const fs::path small = root() / "small_detections.json";
  write_file(small,
             "{\"format\": \"mcslam-detections\", \"version\": 1, \"image_width\": 320, "
             "\"image_height\": 240, \"frames\": []}");
  expect_input_error(run_cli("run " + seq + out + " --detections " + quote(small.string())),
                     {small.string(), "320x240"});
  expect_input_error(run_cli("run " + seq + out + " --model " + quote(det.string())),
                     {det.string()});
  const fs::path missing = root() / "no_such_model.onnx";
  expect_input_error(run_cli("run " + seq + out + " --model " + quote(missing.string())),
                     {missing.string()});
}

}  // namespace
