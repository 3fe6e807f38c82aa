// `mcslam vocabulary`: a vocabulary trained from a rendered sequence through the real binary,
// loadable and deterministic, and one clear error line for each bad input.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "mcslam/place/vocabulary.hpp"
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

class VocabularyCli : public testing::Test {
 protected:
  /// A rendered room, 24 frames at 320 x 240 (once per test).
  void SetUp() override {
    mcslam::synth::write_sequence(seq_.string(), mcslam::test::small_room(24));
  }

  CliResult vocabulary(const std::string& args) {
    return mcslam::test::run_command(MCSLAM_EXE, "vocabulary " + args, dir_.path());
  }

  mcslam::test::TempDir dir_{"mcslam_vocabulary_cli_test"};
  fs::path seq_ = dir_ / "room";
};

TEST_F(VocabularyCli, TrainsALoadableDeterministicVocabulary) {
  const std::string out = dir_.file("voc.bin");
  const std::string args = quote(seq_.string()) + " --every 2 --branching 6 --depth 3 -o ";
  const CliResult r = vocabulary(args + quote(out));
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_NE(r.out.find("12 images"), std::string::npos) << r.out;
  const auto voc = mcslam::place::Vocabulary::load(out);
  EXPECT_EQ(voc.branching(), 6);
  EXPECT_EQ(voc.depth(), 3);
  EXPECT_GT(voc.words(), 100);
  EXPECT_LE(voc.words(), 216);
  const std::string again = dir_.file("again.bin");
  ASSERT_EQ(vocabulary(args + quote(again) + " -q").exit_code, 0);
  EXPECT_EQ(mcslam::place::Vocabulary::load(again).id(), voc.id());
}

TEST_F(VocabularyCli, BadInputIsOneErrorLine) {
  const std::string out = quote(dir_.file("voc.bin"));
  const auto expect_error = [&](const std::string& args, const std::string& named) {
    const CliResult r = vocabulary(args);
    EXPECT_EQ(r.exit_code, 1) << args << "\n" << r;
    EXPECT_FALSE(r.crashed);
    EXPECT_EQ(mcslam::test::count_lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find(named), std::string::npos) << r.err;
  };
  expect_error(quote(dir_.file("missing")) + " -o " + out, "missing");
  expect_error(quote(seq_.string()) + " --every 0 -o " + out, "--every");
  expect_error(quote(seq_.string()) + " --branching 1 -o " + out, "branching");
  expect_error(quote(seq_.string()) + " -o " + quote(dir_.file("no/such/dir/voc.bin")), "voc.bin");
  // A corrupt image among the training images.
  std::string first;
  {
    std::ifstream list(seq_ / "rgb.txt");
    for (std::string line; std::getline(list, line);)
      if (!line.empty() && line[0] != '#') {
        first = line.substr(line.find(' ') + 1);
        break;
      }
  }
  ASSERT_FALSE(first.empty());
  std::ofstream(seq_ / first, std::ios::binary | std::ios::trunc) << "not a png";
  expect_error(quote(seq_.string()) + " -o " + out, first);
  EXPECT_FALSE(fs::exists(dir_.file("voc.bin")));
}

}  // namespace
