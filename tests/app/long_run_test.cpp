// Long runs of the real `mcslam` binary: a sequence repeated as one stream (the soak mode), a run
// stopped by SIGINT (results for the frames so far), and a run killed by SIGKILL (what is left on
// disk is complete files or clearly partial ones, never a torn trajectory).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "mcslam/core/error.hpp"
#include "mcslam/io/trajectory_io.hpp"
#include "mcslam/synth/sequence.hpp"
#include "support/cli_runner.hpp"
#include "support/temp_dir.hpp"

#ifndef MCSLAM_EXE
#error "MCSLAM_EXE must name the mcslam executable"
#endif

namespace {

namespace fs = std::filesystem;
using mcslam::test::read_file;

nlohmann::json read_json(const fs::path& path) { return nlohmann::json::parse(read_file(path)); }

/// A small synthetic sequence (the default room and camera path) in `dir`.
fs::path make_sequence(const mcslam::test::TempDir& dir, int frames) {
  const fs::path d = dir / "seq";
  mcslam::synth::SynthOptions options;
  options.frames = frames;
  options.width = 320;
  options.height = 240;
  options.fx = options.fy = 525.0 / 2.0;
  options.cx = 159.5;
  options.cy = 119.5;
  mcslam::synth::write_sequence(d.string(), options);
  return d;
}

/// `mcslam run` started in the background, stdout and stderr to files in `log_dir`.
class BackgroundRun {
 public:
  BackgroundRun(const std::vector<std::string>& args, const fs::path& log_dir) {
    std::vector<std::string> argv_strings = {MCSLAM_EXE};
    argv_strings.insert(argv_strings.end(), args.begin(), args.end());
    const std::string out = (log_dir / "stdout.txt").string();
    const std::string err = (log_dir / "stderr.txt").string();
    pid_ = ::fork();
    if (pid_ == 0) {
      const int out_fd = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      const int err_fd = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (out_fd >= 0) ::dup2(out_fd, STDOUT_FILENO);
      if (err_fd >= 0) ::dup2(err_fd, STDERR_FILENO);
      std::vector<char*> argv;
      for (auto& s : argv_strings) argv.push_back(s.data());
      argv.push_back(nullptr);
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
  }
  ~BackgroundRun() {
    if (pid_ > 0 && !waited_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  void signal(int sig) const { ::kill(pid_, sig); }
  /// The wait status of the process.
  int wait() {
    int status = 0;
    ::waitpid(pid_, &status, 0);
    waited_ = true;
    return status;
  }
  bool started() const { return pid_ > 0; }

 private:
  pid_t pid_ = -1;
  bool waited_ = false;
};

/// Waits (up to `timeout_s`) until status.json in `out` reports at least `frames` frames done.
bool wait_for_progress(const fs::path& out, int frames, double timeout_s) {
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::milliseconds(int(timeout_s * 1000));
  while (std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (!fs::exists(out / "status.json")) continue;
    const nlohmann::json status = read_json(out / "status.json");  // never torn: atomic
    if (status["state"] == "running" && status["frames_done"].get<int>() >= frames) return true;
  }
  return false;
}

TEST(LongRun, RepeatPlaysTheSequenceAsOneStreamWithPerPassFigures) {
  mcslam::test::TempDir dir("mcslam_long_run");
  const fs::path seq = make_sequence(dir, 30);
  const fs::path out = dir / "out";
  const auto r =
      mcslam::test::run_command(MCSLAM_EXE,
                                "run " + mcslam::test::quote(seq.string()) + " --output " +
                                    mcslam::test::quote(out.string()) + " --repeat 3 --sequential",
                                dir / "stdout.txt", dir / "stderr.txt");
  ASSERT_EQ(r.exit_code, 0) << r;
  const nlohmann::json summary = read_json(out / "summary.json");
  EXPECT_EQ(summary["state"], "complete");
  EXPECT_EQ(summary["frames"], 90);
  EXPECT_EQ(summary["repeat"], 3);
  ASSERT_EQ(summary["passes"].size(), 3u);
  EXPECT_EQ(read_json(out / "status.json")["state"], "complete");
  for (const auto& pass : summary["passes"]) {
    EXPECT_EQ(pass["frames"], 30);
    EXPECT_GT(pass["rss_end_mib"].get<double>(), 0.0);
    ASSERT_TRUE(pass.contains("ate_rmse_m")) << pass;
    // Each pass is scored against its own copy of the ground truth.
    EXPECT_LT(pass["ate_rmse_m"].get<double>(), 0.05) << pass;
  }
  // The whole stream against the repeated ground truth: one consistent map over three passes.
  EXPECT_LT(summary["ate_rmse_m"].get<double>(), 0.05);
  EXPECT_EQ(summary["eval"]["matched"], summary["tracked_frames"]);
  // Revisiting the same room adds few keyframes: passes 2 and 3 insert fewer than pass 1.
  const int first_keyframes = summary["passes"][0]["keyframes_inserted"].get<int>();
  EXPECT_LT(summary["passes"][1]["keyframes_inserted"].get<int>(), first_keyframes);
  EXPECT_LT(summary["passes"][2]["keyframes_inserted"].get<int>(), first_keyframes);

  // One trajectory with strictly increasing timestamps across the passes.
  const mcslam::Trajectory trajectory =
      mcslam::io::read_tum_trajectory((out / "trajectory.txt").string());
  EXPECT_EQ(static_cast<int>(trajectory.size()), summary["tracked_frames"].get<int>());
  // timings.csv: a row per frame of the stream, with resident memory.
  std::ifstream csv(out / "timings.csv");
  std::string header;
  std::getline(csv, header);
  EXPECT_NE(header.find(",total_ms,rss_mib"), std::string::npos) << header;
  int rows = 0;
  for (std::string line; std::getline(csv, line);) ++rows;
  EXPECT_EQ(rows, 90);
  EXPECT_NE(r.out.find("pass  frames"), std::string::npos) << r;
}

TEST(LongRun, RepeatMustBePositive) {
  mcslam::test::TempDir dir("mcslam_long_run");
  const auto r = mcslam::test::run_command(
      MCSLAM_EXE, "run " + dir.str() + " --output " + dir.file("out") + " --repeat 0",
      dir / "stdout.txt", dir / "stderr.txt");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_FALSE(r.crashed) << r;
  EXPECT_NE(r.err.find("--repeat"), std::string::npos) << r;
}

TEST(LongRun, SigintStopsTheRunAndWritesTheResultsSoFar) {
  mcslam::test::TempDir dir("mcslam_long_run");
  const fs::path seq = make_sequence(dir, 30);
  const fs::path out = dir / "out";
  BackgroundRun run({"run", seq.string(), "--output", out.string(), "--repeat", "200"}, dir.path());
  ASSERT_TRUE(run.started());
  ASSERT_TRUE(wait_for_progress(out, 1, 120.0)) << read_file(dir / "stderr.txt");
  run.signal(SIGINT);
  const int status = run.wait();
  ASSERT_TRUE(WIFEXITED(status)) << "killed by signal " << WTERMSIG(status);
  EXPECT_EQ(WEXITSTATUS(status), 130) << read_file(dir / "stderr.txt");

  const nlohmann::json summary = read_json(out / "summary.json");
  EXPECT_EQ(summary["state"], "interrupted");
  const int frames = summary["frames"].get<int>();
  EXPECT_GT(frames, 0);
  EXPECT_LT(frames, 6000);
  // The pass the run stopped in is reported as far as it went.
  int pass_frames = 0;
  for (const auto& pass : summary["passes"]) pass_frames += pass["frames"].get<int>();
  EXPECT_EQ(pass_frames, frames);
  const nlohmann::json final_status = read_json(out / "status.json");
  EXPECT_EQ(final_status["state"], "interrupted");
  EXPECT_EQ(final_status["frames_done"], frames);
  // The trajectory of the frames done, marked as such.
  const std::string text = read_file(out / "trajectory.txt");
  EXPECT_EQ(text.rfind("# interrupted after frame " + std::to_string(frames), 0), 0u) << text;
  const mcslam::Trajectory trajectory =
      mcslam::io::read_tum_trajectory((out / "trajectory.txt").string());
  EXPECT_EQ(static_cast<int>(trajectory.size()), summary["tracked_frames"].get<int>());
  EXPECT_NE(read_file(dir / "stderr.txt").find("stopping after this frame"), std::string::npos);
}

TEST(LongRun, SigkillLeavesAClearlyPartialRunAndNoTornFile) {
  mcslam::test::TempDir dir("mcslam_long_run");
  const fs::path seq = make_sequence(dir, 30);
  const fs::path out = dir / "out";
  BackgroundRun run({"run", seq.string(), "--output", out.string(), "--repeat", "200"}, dir.path());
  ASSERT_TRUE(run.started());
  // The first checkpoint comes after about 2 s of frames.
  ASSERT_TRUE(wait_for_progress(out, 1, 120.0)) << read_file(dir / "stderr.txt");
  run.signal(SIGKILL);
  const int status = run.wait();
  ASSERT_TRUE(WIFSIGNALED(status));

  const nlohmann::json last_status = read_json(out / "status.json");
  EXPECT_EQ(last_status["state"], "running");
  const int frames_done = last_status["frames_done"].get<int>();
  EXPECT_GT(frames_done, 0);
  // The checkpoint's online trajectory: a valid TUM file that says it is partial.
  const std::string text = read_file(out / "trajectory_online.txt");
  EXPECT_EQ(text.rfind("# partial: the run was at frame ", 0), 0u) << text.substr(0, 200);
  const mcslam::Trajectory partial =
      mcslam::io::read_tum_trajectory((out / "trajectory_online.txt").string());
  EXPECT_GT(partial.size(), 0u);
  EXPECT_LE(static_cast<int>(partial.size()), frames_done + 1);
  // No final result was written; what exists is complete.
  EXPECT_FALSE(fs::exists(out / "summary.json"));
  EXPECT_FALSE(fs::exists(out / "trajectory.txt"));
  EXPECT_NO_THROW(read_json(out / "status.json"));
  EXPECT_FALSE(read_file(out / "config.yaml").empty());
}

}  // namespace
