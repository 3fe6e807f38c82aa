// The bad-input matrix: each broken input, given to the real `mcslam` binary, ends with exit code
// 1, one "mcslam: error:" line naming the file and the problem, no crash, and no trajectory.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "mcslam/synth/sequence.hpp"
#include "support/cli_runner.hpp"
#include "support/temp_dir.hpp"
#include "support/tiny_onnx.hpp"

#ifndef MCSLAM_EXE
#error "MCSLAM_EXE must name the mcslam executable"
#endif

namespace {

namespace fs = std::filesystem;
using mcslam::test::quote;
using mcslam::test::read_file;
using mcslam::test::TempDir;
using mcslam::test::write_file;

/// A case's folder: `seq` is a good 3-frame 160x120 sequence to break, `out` the output folder.
struct CaseDir {
  fs::path dir, seq, out;
  std::string file(const std::string& relative) const { return (dir / relative).string(); }
  std::string seq_file(const std::string& relative) const { return (seq / relative).string(); }
  /// The sequence's n-th listed image of a list ("rgb.txt" or "depth.txt").
  fs::path listed(const std::string& list, int n) const {
    std::ifstream in(seq / list);
    int k = 0;
    for (std::string line; std::getline(in, line);) {
      if (line.empty() || line[0] == '#') continue;
      if (k++ == n) return seq / line.substr(line.find(' ') + 1);
    }
    return {};
  }
  /// `run` on the sequence, writing to `out`, with extra (quoted) arguments.
  std::string run(const std::string& extra = "") const {
    return "run " + quote(seq.string()) + " --output " + quote(out.string()) + " -q " + extra;
  }
};

struct Case {
  std::string name;
  /// Breaks something and returns the command-line arguments.
  std::function<std::string(const CaseDir&)> make;
  /// Pieces the error line must hold; "{seq}" and "{dir}" stand for the case's folders.
  std::vector<std::string> pieces;
};

std::ostream& operator<<(std::ostream& os, const Case& c) { return os << c.name; }

/// A good 3-frame 160x120 synthetic sequence (rendered in a few tens of milliseconds).
void write_good_sequence(const fs::path& dir) {
  mcslam::synth::SynthOptions options;
  options.frames = 3;
  options.width = 160;
  options.height = 120;
  options.fx = options.fy = 525.0 / 4.0;
  options.cx = 79.5;
  options.cy = 59.5;
  mcslam::synth::write_sequence(dir.string(), options);
}

void replace_in_file(const fs::path& path, const std::string& from, const std::string& to) {
  std::string text = read_file(path);
  const auto at = text.find(from);
  if (at == std::string::npos) throw std::runtime_error(path.string() + " lacks " + from);
  text.replace(at, from.size(), to);
  write_file(path, text);
}

/// The list's data lines (comments dropped).
std::vector<std::string> data_lines(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);)
    if (!line.empty() && line[0] != '#') lines.push_back(line);
  return lines;
}

void write_lines(const fs::path& path, const std::vector<std::string>& lines) {
  std::string text = "# broken by a test\n";
  for (const auto& l : lines) text += l + "\n";
  write_file(path, text);
}

std::string config(const CaseDir& s, const std::string& yaml) {
  write_file(s.dir / "settings.yaml", yaml);
  return s.run("--config " + quote(s.file("settings.yaml")));
}

const std::vector<Case>& cases() {
  static const std::vector<Case> all = {
      // --- the sequence folder and its lists ---
      {"MissingSequenceFolder",
       [](const CaseDir& s) {
         fs::remove_all(s.seq);
         return s.run();
       },
       {"{seq}: sequence directory not found"}},
      {"MissingRgbList",
       [](const CaseDir& s) {
         fs::remove(s.seq / "rgb.txt");
         return s.run();
       },
       {"{seq}/rgb.txt: list file not found"}},
      {"EmptyRgbList",
       [](const CaseDir& s) {
         write_file(s.seq / "rgb.txt", "");
         return s.run();
       },
       {"{seq}/rgb.txt", "no entries"}},
      {"RgbListOfCommentsOnly",
       [](const CaseDir& s) {
         write_file(s.seq / "rgb.txt", "# color images\n# timestamp filename\n");
         return s.run();
       },
       {"{seq}/rgb.txt", "no entries"}},
      {"LineWithOneField",
       [](const CaseDir& s) {
         auto lines = data_lines(s.seq / "rgb.txt");
         lines[1] = lines[1].substr(0, lines[1].find(' '));
         write_lines(s.seq / "rgb.txt", lines);
         return s.run();
       },
       {"{seq}/rgb.txt:3: expected 2 columns 'timestamp path', got 1"}},
      {"LineWithThreeFields",
       [](const CaseDir& s) {
         auto lines = data_lines(s.seq / "rgb.txt");
         lines[0] += " extra";
         write_lines(s.seq / "rgb.txt", lines);
         return s.run();
       },
       {"{seq}/rgb.txt:2: expected 2 columns 'timestamp path', got 3"}},
      {"TimestampNotANumber",
       [](const CaseDir& s) {
         auto lines = data_lines(s.seq / "depth.txt");
         lines[2] = "1.2x3" + lines[2].substr(lines[2].find(' '));
         write_lines(s.seq / "depth.txt", lines);
         return s.run();
       },
       {"{seq}/depth.txt:4:", "timestamp"}},
      {"TimestampsOutOfOrder",
       [](const CaseDir& s) {
         auto lines = data_lines(s.seq / "rgb.txt");
         std::swap(lines[0], lines[2]);
         write_lines(s.seq / "rgb.txt", lines);
         return s.run();
       },
       {"{seq}/rgb.txt:3:", "increase"}},
      {"TimestampDuplicated",
       [](const CaseDir& s) {
         auto lines = data_lines(s.seq / "rgb.txt");
         lines.insert(lines.begin() + 1, lines[1]);
         write_lines(s.seq / "rgb.txt", lines);
         return s.run();
       },
       {"{seq}/rgb.txt:4:", "increase"}},
      {"NegativeTimestamp",
       [](const CaseDir& s) {
         auto lines = data_lines(s.seq / "rgb.txt");
         lines[0] = "-1" + lines[0].substr(lines[0].find(' '));
         write_lines(s.seq / "rgb.txt", lines);
         return s.run();
       },
       {"{seq}/rgb.txt:2:", "timestamp"}},
      {"EveryListedImageMissing",
       [](const CaseDir& s) {
         fs::remove_all(s.seq / "rgb");
         return s.run();
       },
       {"{seq}/rgb.txt", "none of the 3 listed files exists"}},
      {"MissingDepthList",
       [](const CaseDir& s) {
         fs::remove(s.seq / "depth.txt");
         return s.run();
       },
       {"{seq}/depth.txt: list file not found"}},
      {"NoRgbAndDepthPairAssociates",
       [](const CaseDir& s) {
         auto lines = data_lines(s.seq / "depth.txt");
         for (auto& l : lines) {
           const double t = std::stod(l.substr(0, l.find(' ')));
           l = std::to_string(t + 5.0) + l.substr(l.find(' '));
         }
         write_lines(s.seq / "depth.txt", lines);
         return s.run();
       },
       {"{seq}: no RGB and depth timestamps lie within 0.02 s of each other"}},
      {"MissingAssociationsFile",
       [](const CaseDir& s) { return s.run("--associations " + quote(s.file("assoc.txt"))); },
       {"{dir}/assoc.txt: associations file not found"}},
      // --- images ---
      {"RgbPngIsGarbage",
       [](const CaseDir& s) {
         write_file(s.listed("rgb.txt", 1), "this is not a PNG");
         return s.run();
       },
       {"{seq}/rgb/", ".png: cannot read image (missing, truncated or not an image)"}},
      {"RgbPngTruncated",
       [](const CaseDir& s) {
         const fs::path p = s.listed("rgb.txt", 1);
         const std::string bytes = read_file(p);
         write_file(p, bytes.substr(0, bytes.size() / 2));
         return s.run();
       },
       {"{seq}/rgb/", ".png: cannot read image (missing, truncated or not an image)"}},
      {"RgbJpegTruncated",
       [](const CaseDir& s) {
         // The colour list names JPEG files; the second one is cut in half.
         auto lines = data_lines(s.seq / "rgb.txt");
         for (std::size_t i = 0; i < lines.size(); ++i) {
           const fs::path png = s.listed("rgb.txt", static_cast<int>(i));
           const fs::path jpg = fs::path(png).replace_extension(".jpg");
           cv::imwrite(jpg.string(), cv::imread(png.string()));
           lines[i].replace(lines[i].size() - 4, 4, ".jpg");
         }
         write_lines(s.seq / "rgb.txt", lines);
         const fs::path cut = fs::path(s.seq / lines[1].substr(lines[1].find(' ') + 1));
         const std::string bytes = read_file(cut);
         write_file(cut, bytes.substr(0, bytes.size() / 2));
         return s.run();
       },
       {"{seq}/rgb/", ".jpg: truncated JPEG (no end-of-image marker)"}},
      {"DepthIsEightBit",
       [](const CaseDir& s) {
         const fs::path p = s.listed("depth.txt", 0);
         cv::imwrite(p.string(), cv::Mat(120, 160, CV_8UC1, cv::Scalar(40)));
         return s.run();
       },
       {"{seq}/depth/", ".png: depth must be a 16-bit single-channel PNG, got 8-bit 1-channel"}},
      {"DepthOfAnotherSize",
       [](const CaseDir& s) {
         const fs::path p = s.listed("depth.txt", 0);
         cv::imwrite(p.string(), cv::Mat(60, 80, CV_16UC1, cv::Scalar(5000)));
         return s.run();
       },
       {"{seq}/depth/", ".png: depth size 80x60 differs from the RGB size 160x120"}},
      {"ImagesOfAnotherSizeThanTheCamera",
       [](const CaseDir& s) {
         replace_in_file(s.seq / "camera.yaml", "width: 160", "width: 320");
         return s.run();
       },
       {"{seq}/rgb/", ".png: image is 160x120 but the camera is 320x120"}},
      // --- settings ---
      {"SettingsFileMissing",
       [](const CaseDir& s) { return s.run("--config " + quote(s.file("no.yaml"))); },
       {"{dir}/no.yaml"}},
      {"SettingsYamlSyntax",
       [](const CaseDir& s) { return config(s, "camera: [1, 2\n"); },
       {"{dir}/settings.yaml"}},
      {"SettingsUnknownKey",
       [](const CaseDir& s) { return config(s, "camera:\n  fxx: 100\n"); },
       {"{dir}/settings.yaml", "camera.fxx"}},
      {"SettingsFocalLengthZero",
       [](const CaseDir& s) { return config(s, "camera:\n  fx: 0\n"); },
       {"{dir}/settings.yaml", "fx"}},
      {"SettingsNegativeDepthFactor",
       [](const CaseDir& s) { return config(s, "camera:\n  depth_factor: -5000\n"); },
       {"{dir}/settings.yaml: camera: depth factor must be positive"}},
      {"SettingsNumberIsText",
       [](const CaseDir& s) { return config(s, "camera:\n  fy: abc\n"); },
       {"{dir}/settings.yaml:2:", "camera.fy", "expected a number"}},
      {"SettingsAbsurdFeatureCount",
       [](const CaseDir& s) {
         return config(s, "orb:\n  num_features: -100\n  scale_factor: 0.5\n");
       },
       {"{dir}/settings.yaml", "orb.num_features"}},
      {"CameraFileWithoutItsFocalLength",
       [](const CaseDir& s) {
         write_file(s.seq / "camera.yaml", "camera:\n  cx: 79.5\n  cy: 59.5\n");
         return s.run();
       },
       {"{seq}/camera.yaml", "fx"}},
      // --- detector, boxes, ground truth, output ---
      {"ModelIsNotOnnx",
       [](const CaseDir& s) {
         write_file(s.dir / "model.onnx", "not a protobuf \x01\x02\xff");
         return s.run("--model " + quote(s.file("model.onnx")));
       },
       {"{dir}/model.onnx", "not an ONNX model"}},
      {"ModelHasTheWrongOutputShape",
       [](const CaseDir& s) {
         write_file(s.dir / "model.onnx", mcslam::test::tiny_onnx(64, {1, 2048, 6}));
         return s.run("--model " + quote(s.file("model.onnx")));
       },
       {"{dir}/model.onnx", "output shape 1x2048x6"}},
      {"ModelMissing",
       [](const CaseDir& s) { return s.run("--model " + quote(s.file("none.onnx"))); },
       {"{dir}/none.onnx", "not found"}},
      {"DetectionsFileNotJson",
       [](const CaseDir& s) {
         write_file(s.dir / "boxes.json", "{\"format\": ");
         return s.run("--detections " + quote(s.file("boxes.json")));
       },
       {"{dir}/boxes.json"}},
      {"GroundTruthLineMalformed",
       [](const CaseDir& s) {
         write_file(s.seq / "groundtruth.txt", "# gt\n1.0 0 0 0 0 0 0\n");
         return s.run();
       },
       {"{seq}/groundtruth.txt:2:"}},
      {"GroundTruthWithoutTimeOverlap",
       [](const CaseDir& s) {
         write_file(s.dir / "gt.txt", "100 0 0 0 0 0 0 1\n101 0 0 0 0 0 0 1\n");
         return "eval --gt " + quote(s.file("gt.txt")) + " --est " +
                quote(s.seq_file("groundtruth.txt"));
       },
       {"{seq}/groundtruth.txt", "{dir}/gt.txt"}},
      {"OutputFolderUnderAFile",
       [](const CaseDir& s) {
         write_file(s.dir / "file", "x");
         return "run " + quote(s.seq.string()) + " --output " + quote(s.file("file/out")) + " -q";
       },
       {"{dir}/file"}},
      {"ViewerPortNotANumber",
       [](const CaseDir& s) { return s.run("--viewer 80x"); },
       {"--viewer", "0 to 65535", "'80x'"}},
      {"ViewerPortOutOfRange",
       [](const CaseDir& s) { return s.run("--viewer 65536"); },
       {"--viewer", "0 to 65535"}},
      {"ViewerBindNotAnAddress",
       [](const CaseDir& s) { return s.run("--viewer 0 --viewer-bind robot.local"); },
       {"--viewer-bind", "'robot.local' is not an IP address"}},
      {"ViewerBindWithoutViewer",
       [](const CaseDir& s) { return s.run("--viewer-bind 0.0.0.0"); },
       {"--viewer-bind", "only with --viewer"}},
      {"ViewerPortInUse",
       [](const CaseDir& s) {
         // A socket listening for the rest of the test process (left open on purpose).
         const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
         sockaddr_in address{};
         address.sin_family = AF_INET;
         address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
         ::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address));
         ::listen(fd, 1);
         socklen_t length = sizeof(address);
         ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length);
         return s.run("--viewer " + std::to_string(ntohs(address.sin_port)));
       },
       {"--viewer", "cannot listen on 127.0.0.1:", "in use"}},
  };
  return all;
}

class BadInput : public testing::TestWithParam<Case> {};

TEST_P(BadInput, OneClearErrorAndExitCodeOne) {
  const Case& c = GetParam();
  TempDir dir("bad_input");
  CaseDir s;
  s.dir = dir.path();
  s.seq = dir / "seq";
  s.out = dir / "out";
  write_good_sequence(s.seq);
  const std::string args = c.make(s);
  const auto r = mcslam::test::run_command(MCSLAM_EXE, args, dir / "stdout", dir / "stderr");
  EXPECT_FALSE(r.crashed) << r;
  EXPECT_EQ(r.exit_code, 1) << args << "\n" << r;
  // One error line, the last one (warnings may come before it), naming the file and the problem.
  const auto error_at = r.err.find("mcslam: error: ");
  ASSERT_NE(error_at, std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("mcslam: error", error_at + 1), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find('\n', error_at), r.err.size() - 1) << r.err;
  std::cout << "  " << c.name << " -> exit " << r.exit_code << ": " << r.err.substr(error_at);
  for (std::string piece : c.pieces) {
    for (const auto& [key, value] :
         {std::pair<std::string, std::string>{"{seq}", s.seq.string()}, {"{dir}", s.dir.string()}})
      if (const auto at = piece.find(key); at != std::string::npos)
        piece.replace(at, key.size(), value);
    EXPECT_NE(r.err.find(piece), std::string::npos) << "lacks '" << piece << "':\n" << r.err;
  }
  EXPECT_FALSE(fs::exists(s.out / "trajectory.txt"));
}

INSTANTIATE_TEST_SUITE_P(Matrix, BadInput, testing::ValuesIn(cases()),
                         [](const testing::TestParamInfo<Case>& info) { return info.param.name; });

}  // namespace
