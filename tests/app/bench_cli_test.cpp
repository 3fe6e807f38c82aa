// `mcslam bench` end to end on small synthetic sequences: every configuration run in its own
// process, a failing run reported while the others go on, the tables and the report written, and
// one clear error for bad input; runs at once (--jobs), tables collected from the run folders
// (--collect), and the Slurm executor driven through fake sbatch, sacct and squeue scripts (the
// real cluster is bench_slurm.sh).
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "mcslam/synth/sequence.hpp"
#include "support/cli_runner.hpp"
#include "support/temp_dir.hpp"

#ifndef MCSLAM_EXE
#error "MCSLAM_EXE must name the mcslam executable"
#endif

namespace {

namespace fs = std::filesystem;
using mcslam::test::contains;
using mcslam::test::quote;
using mcslam::test::read_file;
using mcslam::test::TempDir;

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

/// Two small rooms rendered by `mcslam synth` (30 frames, 320x240), in dir/data.
void make_small_data(const TempDir& dir) {
  for (const char* seed : {"1", "7"}) {
    const auto r = mcslam::test::run_command(
        MCSLAM_EXE,
        "synth --frames 30 --width 320 --height 240 -q --seed " + std::string(seed) + " --output " +
            quote(dir.file(std::string("data/room_") + seed)),
        dir.path());
    ASSERT_EQ(r.exit_code, 0) << r;
  }
}

/// `env VARS mcslam bench ARGS`: the bench with a PATH (and Slurm variables) of the test's.
mcslam::test::CliResult bench_with(const TempDir& dir, const std::string& vars,
                                   const std::string& args) {
  return mcslam::test::run_command("/usr/bin/env",
                                   vars + " " + quote(MCSLAM_EXE) + " bench " + args, dir.path());
}

void fake_command(const TempDir& dir, const std::string& name, const std::string& body) {
  const std::string path = dir.write("bin/" + name, "#!/bin/sh\n" + body);
  chmod(path.c_str(), 0755);
}

/// The rows of the first table of each sequence (configuration to tracked share).
std::vector<std::string> accuracy_rows(const std::string& markdown) {
  std::vector<std::string> rows;
  std::istringstream in(markdown);
  bool inside = false;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("| configuration | ATE RMSE (m) |", 0) == 0) {
      inside = true;
    } else if (inside && line.rfind("|---", 0) != 0) {
      if (line.rfind("| ", 0) != 0) {
        inside = false;
        continue;
      }
      std::size_t bar = 0;
      for (int i = 0; i < 7 && bar != std::string::npos; ++i) bar = line.find('|', bar + 1);
      rows.push_back(line.substr(0, bar));
    }
  }
  return rows;
}

TEST(BenchCli, RunsAtOnceAndCollectGivesTheSameTables) {
  TempDir dir("bench_cli");
  make_small_data(dir);
  const std::string out = dir.file("out");
  auto r = bench(dir, quote(dir.file("data")) +
                          " --runs 1 --modes sequential --configs points,planes --jobs 2 -q "
                          "--output " +
                          quote(out));
  ASSERT_EQ(r.exit_code, 0) << r;
  const std::string md = read_file(fs::path(out) / "results.md");
  EXPECT_TRUE(contains(md, "2 runs at once on this machine")) << md;
  const std::string plan = read_file(fs::path(out) / "plan.tsv");
  EXPECT_EQ(std::count(plan.begin(), plan.end(), '\n'), 5 + 4);  // comments, header, 4 runs
  EXPECT_TRUE(fs::exists(fs::path(out) / "runs/room_7/planes/sequential-1.task.json"));

  r = bench(dir, "--collect " + quote(out) + " -q");
  ASSERT_EQ(r.exit_code, 0) << r;
  const std::string collected = read_file(fs::path(out) / "results.md");
  EXPECT_EQ(accuracy_rows(collected), accuracy_rows(md));
  EXPECT_EQ(accuracy_rows(md).size(), 4u);
  EXPECT_TRUE(contains(collected, "## Failed runs\n\nNone.")) << collected;

  // A plan edited into nonsense: one error naming the file and line; nothing is lost.
  std::string edited = plan;
  edited.replace(edited.find("\tsequential\t1\t"), 14, "\tsequentially\t1\t");
  mcslam::test::write_file(fs::path(out) / "plan.tsv", edited);
  r = bench(dir, "--collect " + quote(out));
  EXPECT_EQ(r.exit_code, 1) << r;
  EXPECT_TRUE(contains(r.err, "mcslam: error: " + out + "/plan.tsv:6: mode 'sequentially' is not"))
      << r.err;
  EXPECT_EQ(read_file(fs::path(out) / "results.md"), collected);
  EXPECT_TRUE(fs::exists(fs::path(out) / "runs/room_1/points/sequential-1/trajectory.txt"));

  r = bench(dir, quote(dir.file("data")) + " --collect " + quote(out));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_TRUE(contains(r.err, "take a bench folder and no DATA_ROOT")) << r.err;
  r = bench(dir, "--collect " + quote(dir.file("data")));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_TRUE(contains(r.err, "bench.json: no such file")) << r.err;
}

TEST(BenchCli, SlurmExecutorThroughFakeSlurmCommands) {
  TempDir dir("bench_cli");
  make_small_data(dir);
  fake_command(dir, "sbatch",
               "echo \"$@\" >> \"$(dirname \"$0\")/sbatch-calls.txt\"\n"
               "n=$(wc -l < \"$(dirname \"$0\")/sbatch-calls.txt\")\necho $((40 + n))\n");
  fake_command(dir, "sacct", "echo 'Slurm accounting storage is disabled' >&2; exit 1\n");
  fake_command(dir, "squeue", "exit 1\n");
  const std::string path = "PATH=" + dir.file("bin") + ":/usr/bin:/bin";
  const std::string out = dir.file("out");
  // The data given relative to the current folder: the plan holds absolute paths, since the
  // tasks do not start there.
  auto r = bench_with(dir, "--chdir=" + quote(dir.str()) + " " + path,
                      "data --runs 1 --modes sequential --configs points --executor slurm "
                      "--partition short --time-limit 5 --output " +
                          quote(out));
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_TRUE(contains(read_file(fs::path(out) / "plan.tsv"),
                       "\nroom_1\tpoints\tsequential\t1\trun\t" + dir.file("data/room_1") + "\t"));
  EXPECT_TRUE(contains(r.out, "submitted 2 of 2 runs as Slurm job array 41")) << r.out;
  EXPECT_TRUE(contains(r.out, "and job 42 to collect them after it (afterany)"));
  EXPECT_TRUE(contains(r.out, "squeue --jobs=41,42"));
  EXPECT_TRUE(contains(r.out, "sacct --jobs=41"));
  const std::string script = read_file(fs::path(out) / "slurm/runs-1.sbatch");
  EXPECT_TRUE(contains(script, "#SBATCH --array=0-1\n#SBATCH --output=\"" + out +
                                   "/slurm/task-%A_%a.out\"\n#SBATCH --partition=short\n"
                                   "#SBATCH --time=5\n"))
      << script;

  // The array's tasks, as Slurm would run them: the first finishes, the second is killed at
  // its time limit before it ends.
  r = bench_with(dir, "SLURM_ARRAY_JOB_ID=41 SLURM_ARRAY_TASK_ID=0",
                 "--run-task " + quote(out) + " 0");
  ASSERT_EQ(r.exit_code, 0) << r;
  dir.write("out/slurm/task-41_1.out",
            "slurmstepd-n1: error: *** JOB 44 ON n1 CANCELLED AT 2026-11-27T10:00:00 DUE TO TIME "
            "LIMIT ***\n");
  r = bench_with(dir, path, "--collect " + quote(out) + " -q");
  EXPECT_EQ(r.exit_code, 2) << r;
  std::string md = read_file(fs::path(out) / "results.md");
  EXPECT_TRUE(contains(md,
                       "| room_7 | points | sequential | 1 | no result: Slurm ended the task at "
                       "its time limit; Slurm: TIMEOUT (job 41_1, from its output); log: "
                       "slurm/task-41_1.out |"))
      << md;
  EXPECT_TRUE(contains(md, "Slurm job array 41"));
  EXPECT_EQ(accuracy_rows(md).size(), 2u);
  EXPECT_TRUE(contains(accuracy_rows(md)[0], "| points | 0.0")) << md;  // room_1's run is kept

  // Only the failed run is submitted again, with the bench's Slurm options.
  r = bench_with(dir, path, "--resubmit-failed " + quote(out));
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_TRUE(contains(r.out, "submitted 1 of 2 runs as Slurm job array 43")) << r.out;
  const std::string again = read_file(fs::path(out) / "slurm/runs-2.sbatch");
  EXPECT_TRUE(contains(again, "#SBATCH --array=1\n")) << again;
  EXPECT_TRUE(contains(again, "#SBATCH --partition=short\n"));
  r = bench_with(dir, path, "--run-task " + quote(out) + " 1");
  ASSERT_EQ(r.exit_code, 0) << r;
  r = bench_with(dir, path, "--collect " + quote(out) + " -q");
  EXPECT_EQ(r.exit_code, 0) << r;
  EXPECT_TRUE(contains(read_file(fs::path(out) / "results.md"), "## Failed runs\n\nNone."));
  r = bench_with(dir, path, "--resubmit-failed " + quote(out));
  EXPECT_EQ(r.exit_code, 0) << r;
  EXPECT_TRUE(contains(r.out, "nothing to resubmit: every run has a result")) << r.out;

  r = bench_with(dir, path, "--run-task " + quote(out) + " 2");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_TRUE(contains(r.err, out + "/plan.tsv: has no run 2 (its 2 runs are 0 to 1)")) << r.err;
}

TEST(BenchCli, SlurmBadInputGetsOneClearError) {
  TempDir dir("bench_cli");
  make_small_data(dir);
  fake_command(dir, "sbatch",
               "echo 'sbatch: error: invalid partition specified: nope' >&2\nexit 1\n");
  const std::string data = quote(dir.file("data"));
  const std::string out = dir.file("out");
  const std::string fake = "PATH=" + dir.file("bin") + ":/usr/bin:/bin";
  const std::string none = "PATH=" + dir.file("nothing");
  const std::vector<std::tuple<std::string, std::string, std::string>> cases = {
      {none, data + " --executor slurm --output " + quote(out), "no sbatch on PATH"},
      {fake, data + " --executor slurm --output out",
       "--output out: with --executor slurm the bench folder must be an absolute path"},
      {fake, data + " --executor slurm --output " + quote(out + " %x"),
       "must not hold white space, quotes"},
      {fake, data + " --executor slurm --partition nope --output " + quote(out),
       "sbatch rejected " + out +
           "/slurm/runs-1.sbatch: sbatch: error: invalid partition "
           "specified: nope; nothing was submitted"},
      {fake, data + " --executor slurm --jobs 2 --output " + quote(out),
       "--jobs: only with --executor local"},
      {fake, data + " --partition short --output " + quote(out), "only with --executor slurm"},
      {fake, data + " --executor slurm --sbatch-arg=mem --output " + quote(out),
       "--sbatch-arg: 'mem' is not one sbatch option"},
      {none, "--resubmit-failed " + quote(out), "no sbatch on PATH"},
      {fake, "--resubmit-failed out", "give the bench folder as an absolute path"},
      {fake, "--run-task " + quote(out) + " x", "--run-task: 'x' is not a run number"},
  };
  for (const auto& [vars, args, message] : cases) {
    const auto r = bench_with(dir, vars, args);
    EXPECT_EQ(r.exit_code, 1) << args << "\n" << r;
    EXPECT_TRUE(contains(r.err, message)) << args << "\n" << r.err;
    EXPECT_FALSE(fs::exists(dir / "out" / "slurm" / "jobs.tsv")) << args;
  }
  EXPECT_FALSE(fs::exists(dir / "out" / "results.md"));
  const auto r = bench_with(dir, fake, data + " --executor cloud --output " + quote(out));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_TRUE(contains(r.err, "--executor")) << r.err;
}

}  // namespace
