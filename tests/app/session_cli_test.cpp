// `mcslam run --save-session / --load-session / --localize` through the real binary: a map saved
// and localised in again (every frame tracked, the map unchanged), and one clear error line for
// each bad session file.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "mcslam/synth/sequence.hpp"
#include "support/cli_runner.hpp"
#include "support/small_room.hpp"
#include "support/temp_dir.hpp"

#ifndef MCSLAM_EXE
#error "MCSLAM_EXE must name the mcslam executable"
#endif

namespace {

namespace fs = std::filesystem;
using mcslam::test::CliResult;
using mcslam::test::quote;

class SessionCli : public testing::Test {
 protected:
  /// A rendered room, 90 frames at 320 x 240, and a first run that saves its map (once for all
  /// the tests of this suite).
  static void SetUpTestSuite() {
    dir_ = new mcslam::test::TempDir("mcslam_session_cli_test");
    mcslam::synth::write_sequence((*dir_ / "room").string(), mcslam::test::small_room(90));
    first_ = run("--output " + quote(dir_->file("first")) + " --save-session " + quote(session()));
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static std::string session() { return dir_->file("room.session"); }
  static CliResult run(const std::string& args) {
    return mcslam::test::run_command(
        MCSLAM_EXE, "run " + quote((*dir_ / "room").string()) + " --sequential -q " + args,
        dir_->path());
  }
  static nlohmann::json summary(const std::string& output) {
    std::ifstream in(*dir_ / output / "summary.json");
    return nlohmann::json::parse(in);
  }
  /// A copy of the saved session with `edit` applied to its bytes.
  static std::string edited(const std::string& name, void (*edit)(std::string&)) {
    std::string bytes = mcslam::test::read_file(session());
    edit(bytes);
    const std::string path = dir_->file(name);
    mcslam::test::write_file(path, bytes);
    return path;
  }
  /// Exit 1 with one error line naming the file.
  static void expect_one_error(const CliResult& r, const std::string& path,
                               const std::string& what) {
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_FALSE(r.crashed);
    EXPECT_EQ(mcslam::test::count_lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find(path), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(what), std::string::npos) << r.err;
  }

  static mcslam::test::TempDir* dir_;
  static CliResult first_;
};
mcslam::test::TempDir* SessionCli::dir_ = nullptr;
CliResult SessionCli::first_;

TEST_F(SessionCli, LocalisesInASavedMapWithoutChangingIt) {
  ASSERT_EQ(first_.exit_code, 0) << first_.err;
  ASSERT_TRUE(fs::exists(session()));
  const CliResult r = run("--output " + quote(dir_->file("localize")) + " --load-session " +
                          quote(session()) + " --localize");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json first = summary("first"), again = summary("localize");
  EXPECT_GE(again["tracked_ratio"].get<double>(), 0.99);
  EXPECT_LT(again["ate_rmse_m"].get<double>(), 0.015);
  EXPECT_EQ(again["keyframes_in_map"], first["keyframes_in_map"]);
  EXPECT_EQ(again["points_in_map"], first["points_in_map"]);
  EXPECT_EQ(again["keyframes_inserted"], 0);
  EXPECT_TRUE(again["session"]["localize"].get<bool>());
  // The first frame is found in the map through the keyframe database.
  ASSERT_GE(again["relocalisation"]["succeeded"].get<int>(), 1);
  EXPECT_GE(again["relocalisation"]["attempts"].get<int>(),
            again["relocalisation"]["succeeded"].get<int>());
  EXPECT_TRUE(again["relocalisation"]["events"][0]["by_database"].get<bool>());
  // A loaded session has no pose before a loss to start from.
  EXPECT_FALSE(again["relocalisation"]["events"][0]["from_last_pose"].get<bool>());
  EXPECT_EQ(again["relocalisation"]["from_last_pose"].get<int>(), 0);
  // The dense map came with the session (its keyframes rebuilt it) and the localised views
  // extended it (integrated, not stored): 90 frames at 30 Hz, one view every 0.5 s.
  const nlohmann::json& dense_first = first["occupancy"];
  const nlohmann::json& dense = again["occupancy"];
  ASSERT_GT(dense_first["keyframes"].get<int>(), 0);
  EXPECT_EQ(dense["keyframes"], dense_first["keyframes"]);
  EXPECT_GE(dense["integrated"].get<int>(), dense_first["keyframes"].get<int>() + 4);
  EXPECT_TRUE(fs::exists(*dir_ / "localize" / "grid.pgm"));
  const int occupied_first = dense_first["grid"]["cells"]["occupied"].get<int>();
  const int occupied = dense["grid"]["cells"]["occupied"].get<int>();
  EXPECT_GT(occupied_first, 0);
  EXPECT_NEAR(occupied, occupied_first, 0.2 * occupied_first);
}

TEST_F(SessionCli, ASessionWithoutTheDenseMapIsRefusedWithWhatToDo) {
  // Version 2 files (before the dense map was saved): one error that says what to do.
  const std::string path = edited("version2.session", [](std::string& b) { b[8] = 2; });
  const CliResult r =
      run("--output " + quote(dir_->file("v2")) + " --load-session " + quote(path) + " --localize");
  expect_one_error(r, "version2.session", "before sessions kept the dense map");
}

TEST_F(SessionCli, MapsOnInALoadedSession) {
  const CliResult r =
      run("--output " + quote(dir_->file("continue")) + " --load-session " + quote(session()));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json s = summary("continue");
  EXPECT_GE(s["tracked_ratio"].get<double>(), 0.99);
  EXPECT_FALSE(s["session"]["localize"].get<bool>());
}

TEST_F(SessionCli, BadSessionFilesAreOneErrorEach) {
  const auto load = [&](const std::string& path) {
    return run("--output " + quote(dir_->file("bad")) + " --load-session " + quote(path) +
               " --localize");
  };
  expect_one_error(load(edited("flipped.session", [](std::string& b) { b[b.size() / 2] ^= 0x10; })),
                   "flipped.session", "checksum");
  expect_one_error(
      load(edited("truncated.session", [](std::string& b) { b.resize(b.size() / 3); })),
      "truncated.session", "");
  expect_one_error(load(edited("empty.session", [](std::string& b) { b.clear(); })),
                   "empty.session", "");
  expect_one_error(load(dir_->file("missing.session")), "missing.session", "");
  // --localize without a map to localise in.
  const CliResult r = run("--output " + quote(dir_->file("bad")) + " --localize");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("--load-session"), std::string::npos) << r.err;
}

}  // namespace
