// `mcslam bench` end to end on small synthetic sequences: every configuration run in its own
// process, a failing run reported while the others go on, the tables and the report written, and
// one clear error for bad input.
#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "mcslam/synth/sequence.hpp"
#include "support/cli_runner.hpp"
#include "support/temp_dir.hpp"

#ifndef MCSLAM_EXE
#error "MCSLAM_EXE must name the mcslam executable"
#endif

namespace {

namespace fs = std::filesystem;
using mcslam::test::quote;
using mcslam::test::read_file;
using mcslam::test::TempDir;

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

mcslam::test::CliResult bench(const TempDir& dir, const std::string& args) {
  return mcslam::test::run_command(MCSLAM_EXE, "bench " + args, dir / "stdout.txt",
                                   dir / "stderr.txt");
}

/// A short dynamic synthetic room (with its oracle boxes) and a copy whose 10th colour image is
/// corrupt, so that its runs fail part-way; returns the corrupt file's name.
std::string make_data(const TempDir& dir) {
  mcslam::synth::SynthOptions options;
  options.frames = 45;
  options.depth_noise = true;
  options.dynamic.enabled = true;
  options.dynamic.start_time = 0.2;
  mcslam::synth::write_sequence(dir.file("data/bench_dyn"), options);
  fs::copy(dir / "data/bench_dyn", dir / "data/bench_corrupt", fs::copy_options::recursive);
  std::vector<fs::path> images;
  for (const auto& e : fs::directory_iterator(dir / "data/bench_corrupt/rgb"))
    images.push_back(e.path());
  std::sort(images.begin(), images.end());
  mcslam::test::write_file(images.at(10), "this is not a PNG");
  return images.at(10).filename().string();
}

TEST(BenchCli, RunsEveryConfigurationReportsFailuresAndWritesTablesAndReport) {
  TempDir dir("bench_cli");
  const std::string corrupt = make_data(dir);
  const std::string out = dir.file("out");
  const auto r = bench(dir, quote(dir.file("data")) + " --runs 1 --modes sequential --configs " +
                                "points,full --overlays 4 --output " + quote(out));
  // Some runs failed: exit 2, after every run was made.
  ASSERT_EQ(r.exit_code, 2) << r;
  EXPECT_FALSE(r.crashed);
  EXPECT_TRUE(
      contains(r.err, "[1/4] bench_corrupt · points · sequential 1/1 ... FAILED: exit code 1"))
      << r.err;
  EXPECT_TRUE(
      contains(r.err, "[4/4] bench_dyn · +moving constraints (full) · sequential 1/1 ... ATE"))
      << r.err;
  EXPECT_TRUE(contains(r.err, "2 of 4 runs succeeded"));

  // The tables: printed and saved.
  const std::string md = read_file(fs::path(out) / "results.md");
  EXPECT_TRUE(contains(r.out, md.substr(0, 200)));
  EXPECT_TRUE(contains(md,
                       "## bench_dyn\n\nsynthetic · 45 frames · boxes: detections.json in the "
                       "sequence"))
      << md;
  EXPECT_TRUE(contains(md, "| points | 0.0")) << md;
  EXPECT_TRUE(contains(md, "| +moving constraints (full) | 0.0")) << md;
  EXPECT_TRUE(
      contains(md, "| bench_corrupt | points | sequential | 1 | exit code 1: mcslam: error: "))
      << md;
  EXPECT_TRUE(contains(md, corrupt)) << md;  // the error names the corrupt file

  const std::string csv = read_file(fs::path(out) / "runs.csv");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 5);
  const auto results = nlohmann::json::parse(read_file(fs::path(out) / "results.json"));
  ASSERT_EQ(results["sequences"].size(), 2u);
  const auto& dyn = results["sequences"][1];
  EXPECT_EQ(dyn["name"], "bench_dyn");
  EXPECT_LT(dyn["results"][1]["ate_rmse_m"]["median"].get<double>(), 0.05);
  EXPECT_FALSE(dyn["results"][1]["runs"][0]["stages_ms"].empty());

  // Each run's own outputs; the first run of each configuration keeps its map, the last
  // configuration its annotated frames.
  const fs::path full_run = fs::path(out) / "runs/bench_dyn/full/sequential-1";
  EXPECT_TRUE(fs::exists(full_run / "trajectory.txt"));
  EXPECT_TRUE(fs::exists(full_run / "map.json"));
  EXPECT_TRUE(fs::exists(full_run / "overlays"));
  EXPECT_FALSE(fs::exists(fs::path(out) / "runs/bench_dyn/points/sequential-1/overlays"));
  EXPECT_TRUE(fs::exists(fs::path(out) / "runs/bench_corrupt/points/sequential-1.log"));

  const fs::path assets = fs::path(MCSLAM_EXE).parent_path() / "report" / "report.js";
  if (!fs::exists(assets)) {
    EXPECT_TRUE(contains(r.err, "report.html not written")) << r.err;
    GTEST_SKIP() << "report scripts not built (" << assets << "): report.html not checked";
  }
  const std::string html = read_file(fs::path(out) / "report.html");
  const std::string open = "<script id=\"mcslam-data\" type=\"application/json\">";
  const auto begin = html.find(open);
  ASSERT_NE(begin, std::string::npos);
  const auto end = html.find("</script>", begin);
  const auto data =
      nlohmann::json::parse(html.substr(begin + open.size(), end - begin - open.size()));
  EXPECT_EQ(data["format"], "mcslam-bench-report");
  EXPECT_EQ(data["configs"].size(), 2u);
  EXPECT_EQ(data["failed_runs"].size(), 2u);
  const auto& seq = data["sequences"][1];
  EXPECT_FALSE(seq["groundtruth"]["t"].empty());
  const auto& trajectory = seq["results"][1]["trajectory"];
  EXPECT_EQ(trajectory["t"].size(), trajectory["ate_error_m"].size());
  EXPECT_GT(trajectory["t"].size(), 30u);
  EXPECT_EQ(seq["map"]["config"], "full");
  EXPECT_GT(seq["map"]["points"].size(), 300u);
  EXPECT_EQ(seq["overlays"].size(), 4u);
  EXPECT_TRUE(seq["results"][0]["trajectory"].is_object());
  EXPECT_TRUE(data["sequences"][0]["results"][0]["trajectory"].is_null());  // the failed runs
}

TEST(BenchCli, ListsTheSequencesFound) {
  TempDir dir("bench_cli");
  dir.write("data/a/rgbd_dataset_freiburg3_walking_xyz/rgb.txt", "");
  dir.write("data/a/rgbd_dataset_freiburg3_walking_xyz/depth.txt", "");
  dir.write("data/rgbd_bonn_crowd/rgb.txt", "");
  dir.write("data/rgbd_bonn_crowd/depth.txt", "");
  const auto r = bench(dir, quote(dir.file("data")) + " --list");
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_TRUE(contains(r.out, "rgbd_bonn_crowd  Bonn  boxes: none"));
  EXPECT_TRUE(contains(r.out, "rgbd_dataset_freiburg3_walking_xyz  TUM  boxes: none"));
}

TEST(BenchCli, BadInputGetsOneClearError) {
  TempDir dir("bench_cli");
  dir.write("data/s/rgb.txt", "");
  dir.write("data/s/depth.txt", "");
  fs::create_directories(dir / "empty");
  const std::string data = quote(dir.file("data"));
  const std::string out = " --output " + quote(dir.file("out"));
  const std::vector<std::pair<std::string, std::string>> cases = {
      {quote(dir.file("missing")) + out, dir.file("missing") + ": no such folder"},
      {quote(dir.file("empty")) + out, "no TUM-layout sequence"},
      {data + out + " --runs 0", "--runs: must be at least 1"},
      {data + out + " --configs points,orb", "--configs: unknown configuration 'orb'"},
      {data + out + " --modes fast", "--modes: unknown mode 'fast'"},
      {data + out + " --sequences walking", "--sequences: no sequence found matches 'walking'"},
      {data + out + " --model " + quote(dir.file("none.onnx")),
       dir.file("none.onnx") + ": no such model file"},
      {data + out + " --confidence 1.5", "--confidence: must be in (0, 1)"},
      {data, "--output is required"},
  };
  for (const auto& [args, message] : cases) {
    const auto r = bench(dir, args);
    EXPECT_EQ(r.exit_code, 1) << args << "\n" << r;
    EXPECT_FALSE(r.crashed) << args;
    EXPECT_TRUE(contains(r.err, "mcslam: error: ")) << args << "\n" << r.err;
    EXPECT_TRUE(contains(r.err, message)) << args << "\n" << r.err;
    EXPECT_FALSE(fs::exists(dir / "out" / "results.md")) << args;
  }
}

}  // namespace
