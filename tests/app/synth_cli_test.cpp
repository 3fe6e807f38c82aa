// `mcslam synth --dynamic --people N --undetected-people K`: the crowd end to end through the
// real binary, and one clear error line for each bad value.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "mcslam/synth/sequence.hpp"
#include "support/cli_runner.hpp"

#ifndef MCSLAM_EXE
#error "MCSLAM_EXE must name the mcslam executable"
#endif

namespace {

namespace fs = std::filesystem;
using mcslam::test::CliResult;
using mcslam::test::quote;

class SynthCli : public testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("mcslam_synth_cli_test_" + std::to_string(getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }

  /// Runs `mcslam synth --output <root>/<name> <args> -q`.
  CliResult synth(const std::string& name, const std::string& args) {
    return mcslam::test::run_command(
        MCSLAM_EXE, "synth --output " + quote((root_ / name).string()) + " " + args + " -q", root_);
  }

  fs::path root_;
};

constexpr const char* kSmall = "--frames 4 --width 160 --height 120";

TEST_F(SynthCli, CrowdWithAMissedPersonWritesLabelsAndFlags) {
  const CliResult r =
      synth("crowd", std::string(kSmall) + " --dynamic --people 4 --undetected-people 1");
  ASSERT_EQ(r.exit_code, 0) << r;
  const fs::path dir = root_ / "crowd";
  std::ifstream in(dir / "objects.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  int people = 0, missed = 0;
  for (const auto& o : j.at("objects")) {
    if (o.at("class") != "person") continue;
    ++people;
    missed += !o.at("detected").get<bool>();
  }
  EXPECT_EQ(people, 4);
  EXPECT_EQ(missed, 1);
  EXPECT_FALSE(j.at("objects").back().at("detected").get<bool>()) << "the last person";
  // One 16-bit label image per frame, listed in labels.txt.
  std::ifstream list(dir / "labels.txt");
  int frames = 0;
  for (std::string line; std::getline(list, line);) {
    if (line.empty() || line[0] == '#') continue;
    const std::string file = line.substr(line.find(' ') + 1);
    EXPECT_EQ(mcslam::synth::read_label_image((dir / file).string()).size(), cv::Size(160, 120));
    ++frames;
  }
  EXPECT_EQ(frames, 4);
}

TEST_F(SynthCli, BadPeopleCountsAreOneErrorLine) {
  struct Case {
    std::string args, expected;
  };
  const std::vector<Case> cases = {
      {"--dynamic --people 7", "dynamic.people"},
      {"--dynamic --people -1", "dynamic.people"},
      {"--dynamic --people 2 --undetected-people 3", "dynamic.undetected_people"},
      {"--dynamic --undetected-people 2", "dynamic.undetected_people"},
      {"--dynamic --people 3 --undetected-people -1", "dynamic.undetected_people"},
      {"--dynamic --people 2 --no-person", "--no-person"},
  };
  for (const Case& c : cases) {
    const CliResult r = synth("bad", std::string(kSmall) + " " + c.args);
    EXPECT_EQ(r.exit_code, 1) << c.args << "\n" << r;
    EXPECT_EQ(mcslam::test::count_lines(r.err), 1) << c.args << "\n" << r;
    EXPECT_NE(r.err.find("mcslam: error: "), std::string::npos) << r;
    EXPECT_NE(r.err.find(c.expected), std::string::npos) << c.args << "\n" << r;
    EXPECT_FALSE(fs::exists(root_ / "bad" / "rgb.txt")) << c.args << ": nothing written";
  }
  // --no-person with --people 0 agrees.
  const CliResult ok = synth("none", std::string(kSmall) + " --dynamic --people 0 --no-person");
  EXPECT_EQ(ok.exit_code, 0) << ok;
}

}  // namespace
