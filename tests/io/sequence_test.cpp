#include "mcslam/io/sequence.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "io/test_support.hpp"
#include "mcslam/core/error.hpp"

namespace mcslam::io {
namespace {

using iotest::expect_input_error;
using iotest::TempDir;

std::string stamp(double t) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.6f", t);
  return buffer;
}

cv::Mat tiny_rgb(int cols = 8, int rows = 6) {
  cv::Mat rgb(rows, cols, CV_8UC3);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) rgb.at<cv::Vec3b>(r, c) = cv::Vec3b(10 * c, 20 * r, 200);
  return rgb;
}

cv::Mat tiny_depth(int cols = 8, int rows = 6) {
  cv::Mat depth(rows, cols, CV_16UC1);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c)
      depth.at<std::uint16_t>(r, c) = static_cast<std::uint16_t>(5000 + 100 * r + c);
  return depth;
}

// A TUM folder whose lists name rgb/<t>.png and depth/<t>.png for the given timestamps; the
// image files are written too.
struct TumFolder {
  TempDir dir;

  // With real_images false, the listed files are empty placeholders (enough for open()).
  TumFolder(const std::vector<double>& rgb_times, const std::vector<double>& depth_times,
            bool real_images = true)
      : real_images_(real_images) {
    std::string rgb_list = "# color images\n# timestamp filename\n";
    for (double t : rgb_times) {
      const std::string rel = "rgb/" + stamp(t) + ".png";
      rgb_list += stamp(t) + " " + rel + "\n";
      write_image(rel, tiny_rgb());
    }
    std::string depth_list = "# depth maps\n# timestamp filename\n";
    for (double t : depth_times) {
      const std::string rel = "depth/" + stamp(t) + ".png";
      depth_list += stamp(t) + " " + rel + "\n";
      write_image(rel, tiny_depth());
    }
    dir.write("rgb.txt", rgb_list);
    dir.write("depth.txt", depth_list);
  }

  void write_image(const std::string& rel, const cv::Mat& image) const {
    dir.write(rel, "");  // creates the folder
    if (real_images_) {
      ASSERT_TRUE(cv::imwrite(dir.file(rel), image));
    }
  }

  bool real_images_ = true;
};

TEST(RgbdSequence, AssociatesWithinLimit) {
  TumFolder f({1.000, 1.033, 1.066, 1.100}, {1.005, 1.030, 1.090, 1.200});
  const RgbdSequence seq = RgbdSequence::open(f.dir.str());
  const auto& frames = seq.frames();
  ASSERT_EQ(frames.size(), 3u);  // 1.066 has no depth within 0.02 s (1.090 is 0.024 away)
  EXPECT_DOUBLE_EQ(frames[0].rgb_timestamp, 1.000);
  EXPECT_DOUBLE_EQ(frames[0].depth_timestamp, 1.005);
  EXPECT_DOUBLE_EQ(frames[1].rgb_timestamp, 1.033);
  EXPECT_DOUBLE_EQ(frames[1].depth_timestamp, 1.030);
  EXPECT_DOUBLE_EQ(frames[2].rgb_timestamp, 1.100);
  EXPECT_DOUBLE_EQ(frames[2].depth_timestamp, 1.090);
  EXPECT_EQ(frames[0].rgb_path, f.dir.file("rgb/1.000000.png"));
  EXPECT_EQ(frames[2].depth_path, f.dir.file("depth/1.090000.png"));
  EXPECT_TRUE(seq.warnings().empty());
}

TEST(RgbdSequence, GreedyBySmallestDifferenceEachEntryOnce) {
  // Candidates: r0-d0 0.006, r0-d1 0.015, r1-d0 0.002, r1-d1 0.007. Greedy takes r1-d0 first,
  // which leaves r0-d1: the pairs cross, as with TUM's associate.py.
  TumFolder f({1.000, 1.008}, {1.006, 1.015});
  const auto frames = RgbdSequence::open(f.dir.str()).frames();
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_DOUBLE_EQ(frames[0].rgb_timestamp, 1.000);
  EXPECT_DOUBLE_EQ(frames[0].depth_timestamp, 1.015);
  EXPECT_DOUBLE_EQ(frames[1].rgb_timestamp, 1.008);
  EXPECT_DOUBLE_EQ(frames[1].depth_timestamp, 1.006);
}

TEST(RgbdSequence, DepthUsedAtMostOnce) {
  TumFolder f({1.000, 1.010, 1.500}, {1.004, 1.502});
  const auto frames = RgbdSequence::open(f.dir.str()).frames();
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_DOUBLE_EQ(frames[0].rgb_timestamp, 1.000);
  EXPECT_DOUBLE_EQ(frames[0].depth_timestamp, 1.004);
  EXPECT_DOUBLE_EQ(frames[1].rgb_timestamp, 1.500);
}

TEST(RgbdSequence, TimeDifferenceLimitIsExclusiveAndConfigurable) {
  {
    TumFolder f({10.0, 20.0}, {10.0199, 20.0201});
    const auto frames = RgbdSequence::open(f.dir.str()).frames();
    ASSERT_EQ(frames.size(), 1u);
    EXPECT_DOUBLE_EQ(frames[0].depth_timestamp, 10.0199);
  }
  {
    TumFolder f({10.0}, {10.0201});
    expect_input_error([&] { RgbdSequence::open(f.dir.str()); }, {"no RGB and depth"});
    SequenceOptions wide;
    wide.max_time_difference = 0.05;
    EXPECT_EQ(RgbdSequence::open(f.dir.str(), wide).frames().size(), 1u);
  }
}

// TUM associate.py, literally: all pairs closer than max_difference, taken greedily by
// increasing difference, each timestamp once; sorted by RGB timestamp.
std::vector<std::pair<double, double>> brute_force_associate(const std::vector<double>& rgb,
                                                             const std::vector<double>& depth,
                                                             double max_difference) {
  std::vector<std::tuple<double, double, double>> candidates;
  for (double a : rgb)
    for (double b : depth)
      if (std::abs(a - b) < max_difference) candidates.emplace_back(std::abs(a - b), a, b);
  std::sort(candidates.begin(), candidates.end());
  std::set<double> rgb_left(rgb.begin(), rgb.end()), depth_left(depth.begin(), depth.end());
  std::vector<std::pair<double, double>> matches;
  for (const auto& [difference, a, b] : candidates) {
    if (rgb_left.count(a) == 0 || depth_left.count(b) == 0) continue;
    rgb_left.erase(a);
    depth_left.erase(b);
    matches.emplace_back(a, b);
  }
  std::sort(matches.begin(), matches.end());
  return matches;
}

TEST(RgbdSequence, AssociationMatchesBruteForceOnJitteredStreams) {
  // Deterministic pseudo-random jitter, offsets and dropped frames.
  std::uint64_t state = 12345;
  auto uniform = [&state] {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(state >> 11) / 9007199254740992.0;  // [0, 1)
  };
  std::vector<double> rgb, depth;
  for (int i = 0; i < 400; ++i) {
    if (uniform() > 0.1) rgb.push_back(std::stod(stamp(50.0 + i / 30.0 + 0.004 * uniform())));
    if (uniform() > 0.1)
      depth.push_back(std::stod(stamp(50.0 + i / 30.0 + 0.05 * (uniform() - 0.5))));
  }
  std::sort(depth.begin(), depth.end());
  depth.erase(std::unique(depth.begin(), depth.end()), depth.end());
  TumFolder f(rgb, depth, /*real_images=*/false);
  for (double max_difference : {0.02, 0.01, 0.04}) {
    SequenceOptions options;
    options.max_time_difference = max_difference;
    const auto frames = RgbdSequence::open(f.dir.str(), options).frames();
    const auto expected = brute_force_associate(rgb, depth, max_difference);
    ASSERT_EQ(frames.size(), expected.size()) << max_difference;
    EXPECT_GT(frames.size(), 100u);
    for (std::size_t i = 0; i < frames.size(); ++i) {
      EXPECT_EQ(frames[i].rgb_timestamp, expected[i].first) << i;
      EXPECT_EQ(frames[i].depth_timestamp, expected[i].second) << i;
    }
  }
}

TEST(RgbdSequence, InvalidOptions) {
  TumFolder f({1.0}, {1.0});
  SequenceOptions options;
  options.max_time_difference = 0.0;
  EXPECT_TRUE(options.check().has_value());
  EXPECT_THROW(RgbdSequence::open(f.dir.str(), options), InputError);
  EXPECT_FALSE(SequenceOptions{}.check().has_value());
}

TEST(RgbdSequence, CommentsBlankLinesAndCrlf) {
  TumFolder f({1.0, 2.0}, {1.0, 2.0});
  f.dir.write("rgb.txt",
              "# header\r\n\r\n   \r\n1.000000 rgb/1.000000.png\r\n  # indented comment\r\n"
              "2.000000\trgb/2.000000.png\r\n");
  const RgbdSequence seq = RgbdSequence::open(f.dir.str());
  ASSERT_EQ(seq.frames().size(), 2u);
  EXPECT_EQ(seq.frames()[1].rgb_path, f.dir.file("rgb/2.000000.png"));
}

TEST(RgbdSequence, NameDirectoryAndGroundtruth) {
  TumFolder f({1.0}, {1.0});
  const std::string dir = f.dir.file("rgbd_dataset_freiburg1_xyz");
  std::filesystem::create_directory(dir);
  for (const char* item : {"rgb", "depth", "rgb.txt", "depth.txt"})
    std::filesystem::rename(f.dir.file(item), dir + "/" + item);
  RgbdSequence seq = RgbdSequence::open(dir + "/");
  EXPECT_EQ(seq.directory(), dir);
  EXPECT_EQ(seq.name(), "rgbd_dataset_freiburg1_xyz");
  EXPECT_FALSE(seq.groundtruth_path().has_value());
  f.dir.write("rgbd_dataset_freiburg1_xyz/groundtruth.txt", "# nothing\n");
  seq = RgbdSequence::open(dir);
  ASSERT_TRUE(seq.groundtruth_path().has_value());
  EXPECT_EQ(*seq.groundtruth_path(), dir + "/groundtruth.txt");
}

struct BadList {
  const char* content;
  std::vector<std::string> parts;
};

TEST(RgbdSequence, MalformedListsNameFileAndLine) {
  const std::vector<BadList> cases = {
      {"# c\n1.0 rgb/1.000000.png\nabc rgb/2.000000.png\n", {"rgb.txt:3", "malformed", "'abc'"}},
      {"1.0x rgb/1.000000.png\n", {"rgb.txt:1", "malformed", "1.0x"}},
      {"1.0 rgb/1.000000.png extra\n", {"rgb.txt:1", "expected 2 columns", "got 3"}},
      {"\n1.0\n", {"rgb.txt:2", "expected 2 columns", "got 1"}},
      {"nan rgb/1.000000.png\n", {"rgb.txt:1", "non-finite"}},
      {"inf rgb/1.000000.png\n", {"rgb.txt:1", "non-finite"}},
      {"-1.0 rgb/1.000000.png\n", {"rgb.txt:1", "negative"}},
      {"2.0 rgb/2.000000.png\n# c\n1.0 rgb/1.000000.png\n",
       {"rgb.txt:3", "out-of-order", "1.0", "2.0"}},
      {"1.0 rgb/1.000000.png\n1.000 rgb/1.000000.png\n",
       {"rgb.txt:2", "duplicated", "1.000", "1.0"}},
      {"# only comments\n\n", {"rgb.txt", "no entries"}},
      {"", {"rgb.txt", "no entries"}},
  };
  for (const BadList& c : cases) {
    SCOPED_TRACE(c.content);
    TumFolder f({1.0, 2.0}, {1.0, 2.0});
    f.dir.write("rgb.txt", c.content);
    expect_input_error([&] { RgbdSequence::open(f.dir.str()); }, c.parts);
  }
}

TEST(RgbdSequence, MalformedDepthListNamesDepthFile) {
  TumFolder f({1.0, 2.0}, {1.0, 2.0});
  f.dir.write("depth.txt", "1.0 depth/1.000000.png\n0.5 depth/2.000000.png\n");
  expect_input_error([&] { RgbdSequence::open(f.dir.str()); },
                     {"depth.txt:2", "out-of-order", "0.5", "1.0"});
}

TEST(RgbdSequence, MissingListsAndDirectory) {
  {
    TumFolder f({1.0}, {1.0});
    std::filesystem::remove(f.dir.file("rgb.txt"));
    expect_input_error([&] { RgbdSequence::open(f.dir.str()); }, {"rgb.txt", "not found"});
  }
  {
    TumFolder f({1.0}, {1.0});
    std::filesystem::remove(f.dir.file("depth.txt"));
    expect_input_error([&] { RgbdSequence::open(f.dir.str()); }, {"depth.txt", "not found"});
  }
  TempDir dir;
  expect_input_error([&] { RgbdSequence::open(dir.file("nowhere")); }, {"nowhere", "not found"});
}

TEST(RgbdSequence, MissingListedFilesSkippedWithOneWarning) {
  TumFolder f({1.0, 2.0, 3.0, 4.0, 5.0}, {1.0, 2.0, 3.0, 4.0, 5.0});
  std::filesystem::remove(f.dir.file("depth/2.000000.png"));
  std::filesystem::remove(f.dir.file("depth/4.000000.png"));
  std::filesystem::remove(f.dir.file("depth/5.000000.png"));
  const RgbdSequence seq = RgbdSequence::open(f.dir.str());
  ASSERT_EQ(seq.frames().size(), 2u);
  EXPECT_DOUBLE_EQ(seq.frames()[0].depth_timestamp, 1.0);
  EXPECT_DOUBLE_EQ(seq.frames()[1].depth_timestamp, 3.0);
  ASSERT_EQ(seq.warnings().size(), 1u);
  const std::string& w = seq.warnings()[0];
  EXPECT_NE(w.find("depth.txt"), std::string::npos) << w;
  EXPECT_NE(w.find("3 listed files do not exist"), std::string::npos) << w;
  EXPECT_NE(w.find("first: depth/2.000000.png"), std::string::npos) << w;
}

TEST(RgbdSequence, AllListedFilesMissingIsAnError) {
  TumFolder f({1.0}, {1.0});
  std::filesystem::remove(f.dir.file("rgb/1.000000.png"));
  expect_input_error([&] { RgbdSequence::open(f.dir.str()); }, {"rgb.txt", "rgb/1.000000.png"});
}

TEST(RgbdSequence, AssociationsFile) {
  TumFolder f({1.0, 2.0, 3.0}, {1.01, 2.01, 3.01});
  f.dir.write("assoc.txt",
              "# t_rgb rgb t_depth depth\n"
              "1.000000 rgb/1.000000.png 1.010000 depth/1.010000.png\n"
              "\n"
              "3.000000 rgb/3.000000.png 3.010000 depth/3.010000.png\n");
  SequenceOptions options;
  options.associations_file = "assoc.txt";  // found in the sequence directory
  const RgbdSequence seq = RgbdSequence::open(f.dir.str(), options);
  ASSERT_EQ(seq.frames().size(), 2u);
  EXPECT_DOUBLE_EQ(seq.frames()[1].rgb_timestamp, 3.0);
  EXPECT_DOUBLE_EQ(seq.frames()[1].depth_timestamp, 3.01);
  EXPECT_EQ(seq.frames()[1].depth_path, f.dir.file("depth/3.010000.png"));

  options.associations_file = f.dir.file("assoc.txt");  // absolute path
  EXPECT_EQ(RgbdSequence::open(f.dir.str(), options).frames().size(), 2u);
}

TEST(RgbdSequence, AssociationsFileValidation) {
  const std::vector<BadList> cases = {
      {"1.0 rgb/1.000000.png 1.01\n", {"assoc.txt:1", "expected 4 columns", "got 3"}},
      {"1.0 rgb/1.000000.png x depth/1.010000.png\n", {"assoc.txt:1", "malformed", "'x'"}},
      {"2.0 rgb/2.000000.png 2.01 depth/2.010000.png\n1.0 rgb/1.000000.png 1.01 "
       "depth/1.010000.png\n",
       {"assoc.txt:2", "out-of-order", "1.0", "2.0"}},
      {"# nothing\n", {"assoc.txt", "no entries"}},
  };
  for (const BadList& c : cases) {
    SCOPED_TRACE(c.content);
    TumFolder f({1.0, 2.0}, {1.01, 2.01});
    f.dir.write("assoc.txt", c.content);
    SequenceOptions options;
    options.associations_file = "assoc.txt";
    expect_input_error([&] { RgbdSequence::open(f.dir.str(), options); }, c.parts);
  }
  TumFolder f({1.0}, {1.0});
  SequenceOptions options;
  options.associations_file = "missing_assoc.txt";
  expect_input_error([&] { RgbdSequence::open(f.dir.str(), options); },
                     {"missing_assoc.txt", "not found"});
}

TEST(RgbdSequence, AssociationsFileMissingFilesWarn) {
  TumFolder f({1.0, 2.0}, {1.01, 2.01});
  f.dir.write("assoc.txt",
              "1.0 rgb/1.000000.png 1.01 depth/1.010000.png\n"
              "2.0 rgb/2.000000.png 2.01 depth/gone.png\n");
  SequenceOptions options;
  options.associations_file = "assoc.txt";
  const RgbdSequence seq = RgbdSequence::open(f.dir.str(), options);
  EXPECT_EQ(seq.frames().size(), 1u);
  ASSERT_EQ(seq.warnings().size(), 1u);
  EXPECT_NE(seq.warnings()[0].find("1 listed file does not exist (first: depth/gone.png)"),
            std::string::npos)
      << seq.warnings()[0];
}

TEST(LoadRgbd, LoadsPngAndJpgAndScalesDepthExactly) {
  TempDir dir;
  const cv::Mat rgb = tiny_rgb();
  cv::Mat depth(6, 8, CV_16UC1, cv::Scalar(0));
  depth.at<std::uint16_t>(0, 1) = 1;
  depth.at<std::uint16_t>(0, 2) = 5000;
  depth.at<std::uint16_t>(0, 3) = 12345;
  depth.at<std::uint16_t>(5, 7) = 65535;
  ASSERT_TRUE(cv::imwrite(dir.file("c.png"), rgb));
  ASSERT_TRUE(cv::imwrite(dir.file("c.jpg"), rgb));
  ASSERT_TRUE(cv::imwrite(dir.file("d.png"), depth));

  FrameEntry frame{1.0, dir.file("c.png"), 1.0, dir.file("d.png")};
  RgbdImages images = load_rgbd(frame, 5000.0);
  ASSERT_EQ(images.rgb.type(), CV_8UC3);
  EXPECT_EQ(cv::norm(images.rgb, rgb, cv::NORM_INF), 0.0);
  ASSERT_EQ(images.depth.type(), CV_32FC1);
  ASSERT_EQ(images.depth.size(), cv::Size(8, 6));
  EXPECT_EQ(images.depth.at<float>(0, 0), 0.0f);
  EXPECT_EQ(images.depth.at<float>(0, 1), static_cast<float>(1.0 / 5000.0));
  EXPECT_EQ(images.depth.at<float>(0, 2), 1.0f);
  EXPECT_EQ(images.depth.at<float>(0, 3), static_cast<float>(12345.0 / 5000.0));
  EXPECT_EQ(images.depth.at<float>(5, 7), static_cast<float>(65535.0 / 5000.0));

  frame.rgb_path = dir.file("c.jpg");
  images = load_rgbd(frame, 1000.0);
  EXPECT_EQ(images.rgb.type(), CV_8UC3);
  EXPECT_EQ(images.rgb.size(), cv::Size(8, 6));
  EXPECT_LT(cv::norm(images.rgb, rgb, cv::NORM_L1) / (8 * 6 * 3), 20.0);  // lossy
  EXPECT_EQ(images.depth.at<float>(0, 2), 5.0f);
}

TEST(LoadRgbd, Errors) {
  TempDir dir;
  ASSERT_TRUE(cv::imwrite(dir.file("c.png"), tiny_rgb()));
  ASSERT_TRUE(cv::imwrite(dir.file("d.png"), tiny_depth()));
  ASSERT_TRUE(cv::imwrite(dir.file("d8.png"), cv::Mat(6, 8, CV_8UC1, cv::Scalar(7))));
  ASSERT_TRUE(cv::imwrite(dir.file("d3.png"), tiny_rgb()));
  ASSERT_TRUE(cv::imwrite(dir.file("d16x3.png"), cv::Mat(6, 8, CV_16UC3, cv::Scalar(7, 8, 9))));
  ASSERT_TRUE(cv::imwrite(dir.file("big.png"), tiny_depth(10, 6)));
  dir.write("garbage.png", "\x89PNG\r\n\x1a\n this is not really a png file at all");
  {  // a truncated copy of a valid PNG
    std::ifstream in(dir.file("c.png"), std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    dir.write("truncated.png", bytes.substr(0, bytes.size() / 2));
  }
  const std::string unreadable = "cannot read image (missing, truncated or not an image)";
  auto load = [&](const std::string& rgb, const std::string& depth) {
    load_rgbd(FrameEntry{1.0, dir.file(rgb), 1.0, dir.file(depth)}, 5000.0);
  };
  expect_input_error([&] { load("none.png", "d.png"); }, {"none.png", unreadable});
  expect_input_error([&] { load("c.png", "none.png"); }, {"none.png", unreadable});
  expect_input_error([&] { load("garbage.png", "d.png"); }, {"garbage.png", unreadable});
  expect_input_error([&] { load("c.png", "garbage.png"); }, {"garbage.png", unreadable});
  expect_input_error([&] { load("truncated.png", "d.png"); }, {"truncated.png", unreadable});
  expect_input_error([&] { load("c.png", "d8.png"); },
                     {"d8.png", "depth must be a 16-bit single-channel PNG, got 8-bit 1-channel"});
  expect_input_error([&] { load("c.png", "d3.png"); },
                     {"d3.png", "depth must be a 16-bit single-channel PNG, got 8-bit 3-channel"});
  expect_input_error([&] { load("c.png", "d16x3.png"); }, {"d16x3.png", "got 16-bit 3-channel"});
  expect_input_error([&] { load("c.png", "big.png"); }, {"big.png", "10x6", "8x6", "c.png"});
  expect_input_error(
      [&] {
        load_rgbd(FrameEntry{1.0, dir.file("c.png"), 1.0, dir.file("d.png")}, 0.0);
      },
      {"depth factor"});
}

TEST(LoadRgbd, TruncatedJpegIsAnErrorNotAGreyImage) {
  TempDir dir;
  cv::Mat rgb(48, 64, CV_8UC3);
  cv::randu(rgb, cv::Scalar::all(0), cv::Scalar::all(255));
  ASSERT_TRUE(cv::imwrite(dir.file("c.jpg"), rgb));
  ASSERT_TRUE(cv::imwrite(dir.file("d.png"), tiny_depth(64, 48)));
  std::ifstream in(dir.file("c.jpg"), std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // libjpeg would decode these with the missing rows grey.
  dir.write("half.jpg", bytes.substr(0, bytes.size() / 2));
  dir.write("cut.jpg", bytes.substr(0, bytes.size() - 2));  // only the end marker missing
  // Bytes after the end marker (some cameras pad files) are fine.
  dir.write("padded.jpg", bytes + std::string(100, '\0'));
  auto load = [&](const std::string& rgb_file) {
    return load_rgbd(FrameEntry{1.0, dir.file(rgb_file), 1.0, dir.file("d.png")}, 5000.0);
  };
  EXPECT_EQ(load("c.jpg").rgb.size(), cv::Size(64, 48));
  EXPECT_EQ(load("padded.jpg").rgb.size(), cv::Size(64, 48));
  for (const char* name : {"half.jpg", "cut.jpg"})
    expect_input_error([&] { load(name); }, {name, "truncated JPEG (no end-of-image marker)"});
}

}  // namespace
}  // namespace mcslam::io
