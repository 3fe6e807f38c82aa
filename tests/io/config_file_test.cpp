#include "mcslam/io/config_file.hpp"

#include <gtest/gtest.h>

#include "io/test_support.hpp"
#include "mcslam/core/error.hpp"

namespace mcslam::io {
namespace {

using iotest::expect_input_error;
using iotest::TempDir;

using Keys = std::vector<std::string>;

constexpr const char* kOrbSlam2Settings = R"(%YAML:1.0

#--------------------------------------------------------------------------------------------
# Camera Parameters. Adjust them!
#--------------------------------------------------------------------------------------------

# Camera calibration and distortion parameters (OpenCV)
Camera.fx: 517.306408
Camera.fy: 516.469215
Camera.cx: 318.643040
Camera.cy: 255.313989

Camera.k1: 0.262383
Camera.k2: -0.953104
Camera.p1: -0.005358
Camera.p2: 0.002628
Camera.k3: 1.163314

Camera.width: 640
Camera.height: 480

# Camera frames per second
Camera.fps: 30.0

# IR projector baseline times fx (aprox.)
Camera.bf: 40.0

# Color order of the images (0: BGR, 1: RGB. It is ignored if images are grayscale)
Camera.RGB: 1

ThDepth: 40.0
DepthMapFactor: 5000.0
ORBextractor.scaleFactor: 1.2
ORBextractor.minThFAST: 7
Viewer.KeyFrameSize: 0.05
Viewer.ViewpointZ: -1.8

Tbc: !!opencv-matrix
   rows: 2
   cols: 3
   dt: f
   data: [ 1., 0., 0.5,
           0., 1.e-3, -2 ]
)";

TEST(ConfigFile, OrbSlam2FileWithYamlDirectiveAndMatrix) {
  TempDir dir;
  const std::string path = dir.write("TUM1.yaml", kOrbSlam2Settings);
  ConfigFile config = ConfigFile::load(path);
  EXPECT_EQ(config.path(), path);
  EXPECT_TRUE(config.has("Camera.fx"));
  EXPECT_FALSE(config.has("Camera"));

  double fx = 0.0, factor = 0.0, fps = 0.0;
  EXPECT_TRUE(config.read("Camera.fx", fx));
  EXPECT_DOUBLE_EQ(fx, 517.306408);
  EXPECT_TRUE(config.read("DepthMapFactor", factor));
  EXPECT_DOUBLE_EQ(factor, 5000.0);
  int width = 0, fps_int = 0;
  EXPECT_TRUE(config.read("Camera.width", width));
  EXPECT_EQ(width, 640);
  EXPECT_TRUE(config.read("Camera.fps", fps_int));  // "30.0" is an integral value
  EXPECT_EQ(fps_int, 30);
  EXPECT_TRUE(config.read("Camera.fps", fps));
  bool rgb = false;
  EXPECT_TRUE(config.read("Camera.RGB", rgb));
  EXPECT_TRUE(rgb);

  std::vector<double> tbc;
  EXPECT_TRUE(config.read("Tbc", tbc));
  EXPECT_EQ(tbc, (std::vector<double>{1.0, 0.0, 0.5, 0.0, 1e-3, -2.0}));

  double missing = 42.0;
  EXPECT_FALSE(config.read("Camera.missing", missing));
  EXPECT_EQ(missing, 42.0);

  config.mark_used("Viewer");  // every Viewer.* key
  config.mark_used("ORBextractor.minThFAST");
  config.mark_used("NotThere");
  const Keys unused = config.unused_keys();
  EXPECT_EQ(unused, (Keys{"Camera.bf", "Camera.cx", "Camera.cy", "Camera.fy", "Camera.height",
                          "Camera.k1", "Camera.k2", "Camera.k3", "Camera.p1", "Camera.p2",
                          "ORBextractor.scaleFactor", "ThDepth"}));
  EXPECT_EQ(config.keys().size(), 21u);
}

TEST(ConfigFile, NestedMapsFlattenWithDots) {
  ConfigFile config = ConfigFile::from_string(
      "camera:\n"
      "  fx: 500\n"
      "  intrinsics: {cx: 1e-3, cy: .5}\n"
      "  name: kinect\n"
      "tracking:\n"
      "  enabled: true\n"
      "  weights: [1, 2.5, -3e2]\n"
      "  empty:\n"
      "Viewer-extra: 1\n",
      "settings.yaml");
  EXPECT_EQ(config.keys(),
            (Keys{"Viewer-extra", "camera.fx", "camera.intrinsics.cx", "camera.intrinsics.cy",
                  "camera.name", "tracking.empty", "tracking.enabled", "tracking.weights"}));
  double fx = 0.0, cx = 0.0, cy = 0.0;
  EXPECT_TRUE(config.read("camera.fx", fx));
  EXPECT_TRUE(config.read("camera.intrinsics.cx", cx));
  EXPECT_TRUE(config.read("camera.intrinsics.cy", cy));
  EXPECT_EQ(fx, 500.0);
  EXPECT_EQ(cx, 1e-3);
  EXPECT_EQ(cy, 0.5);
  std::string name = "x", empty = "x";
  EXPECT_TRUE(config.read("camera.name", name));
  EXPECT_EQ(name, "kinect");
  EXPECT_TRUE(config.read("tracking.empty", empty));
  EXPECT_EQ(empty, "");
  bool enabled = false;
  EXPECT_TRUE(config.read("tracking.enabled", enabled));
  EXPECT_TRUE(enabled);
  std::vector<double> weights;
  EXPECT_TRUE(config.read("tracking.weights", weights));
  EXPECT_EQ(weights, (std::vector<double>{1.0, 2.5, -300.0}));
  config.mark_used("Viewer");  // must not mark "Viewer-extra"
  EXPECT_EQ(config.unused_keys(), Keys{"Viewer-extra"});
}

TEST(ConfigFile, BooleansAcceptZeroAndOne) {
  ConfigFile config = ConfigFile::from_string("a: 0\nb: 1\nc: false\nd: True\ne: yes\n");
  bool a = true, b = false, c = true, d = false, e = false;
  EXPECT_TRUE(config.read("a", a));
  EXPECT_TRUE(config.read("b", b));
  EXPECT_TRUE(config.read("c", c));
  EXPECT_TRUE(config.read("d", d));
  EXPECT_FALSE(a);
  EXPECT_TRUE(b);
  EXPECT_FALSE(c);
  EXPECT_TRUE(d);
  expect_input_error([&] { config.read("e", e); }, {"key 'e'", "expected a boolean", "'yes'"});
}

TEST(ConfigFile, WrongTypesNameFileKeyAndValue) {
  ConfigFile config = ConfigFile::from_string(
      "Camera.fx: abc\n"
      "Camera.width: 1.5\n"
      "big: 3000000000\n"
      "list: [1, x]\n"
      "nested: [[1, 2]]\n"
      "map:\n  a: {}\n"
      "scalar: 5\n"
      "nan: nan\n",
      "cam.yaml");
  double d = 0.0;
  int i = 0;
  std::string s;
  std::vector<double> v;
  expect_input_error([&] { config.read("Camera.fx", d); },
                     {"cam.yaml:1", "key 'Camera.fx': expected a number, got 'abc'"});
  expect_input_error([&] { config.read("Camera.width", i); },
                     {"cam.yaml:2", "key 'Camera.width': expected an integer, got '1.5'"});
  expect_input_error([&] { config.read("big", i); }, {"key 'big'", "int range"});
  expect_input_error([&] { config.read("list", v); },
                     {"cam.yaml:4", "key 'list'", "list of numbers", "'x'"});
  expect_input_error([&] { config.read("nested", v); }, {"key 'nested'", "list of numbers"});
  expect_input_error([&] { config.read("list", d); },
                     {"key 'list': expected a number, got a list"});
  expect_input_error([&] { config.read("map.a", s); },
                     {"key 'map.a': expected a string, got a map"});
  expect_input_error([&] { config.read("scalar", v); },
                     {"key 'scalar': expected a list of numbers, got '5'"});
  expect_input_error([&] { config.read("nan", d); }, {"key 'nan'", "finite"});
  EXPECT_EQ(config.unused_keys().size(), config.keys().size());  // failed reads mark nothing
}

TEST(ConfigFile, SyntaxErrorsNameFileAndLine) {
  TempDir dir;
  const std::string path = dir.write("bad.yaml", "%YAML:1.0\na: 1\nb: [1, 2\nc: 3\n");
  try {
    ConfigFile::load(path);
    ADD_FAILURE() << "expected InputError";
  } catch (const InputError& e) {
    // The unclosed flow sequence is reported where it opens; the directive line counts.
    EXPECT_EQ(std::string(e.what()),
              path + ":3: YAML syntax error: end of flow sequence ']' not found");
  }
  expect_input_error([] { ConfigFile::from_string("a: 1\n  b: 2\n", "x.yaml"); },
                     {"x.yaml:2: YAML syntax error: bad indentation"});
}

TEST(ConfigFile, InputsThatHungYamlCppAreSyntaxErrors) {
  // yaml-cpp 0.7 never returned on these (found by fuzz/fuzz_settings); mcslam's own parser
  // rejects them at the offending line.
  const std::string comma = "YAML syntax error: a node cannot start with ','";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {",", "x.yaml:1: " + comma},
      {",]", "x.yaml:1: " + comma},
      {"  ,}", "x.yaml:1: " + comma},
      {"# settings\n\n,a: 1\n", "x.yaml:3: " + comma},
      {"---\n, x\n", "x.yaml:2: " + comma},
      {"a: 1\n--- ,]\n", "x.yaml:2: YAML syntax error: expected one YAML document, got more"},
      {"   a:b: [0.26]\n, -0\n", "x.yaml:2: YAML syntax error: bad indentation"},
      {"%Y 1\n,\n", "x.yaml:2: " + comma},
      {"!t ,\n", "x.yaml:1: " + comma},
      {"\"c\"\n!oata:0.0k2, 1.16]\n", "x.yaml:2: YAML syntax error: unexpected text"},
      {"a:\n  - ,\n", "x.yaml:2: " + comma},
      {"&x ,\n", "x.yaml:1: YAML syntax error: anchors and aliases are not supported"},
      {"%Y: [&.52, -0.95\n ,,\n", "x.yaml:2: " + comma},
      {std::string("a: 1\n\0,\n", 8), "x.yaml:2: YAML syntax error: control character 0x00"},
      {"a: \x01\n", "x.yaml:1: YAML syntax error: control character 0x01"},
  };
  for (const auto& c : cases)  // (clang 14 cannot capture structured bindings)
    expect_input_error([&] { ConfigFile::from_string(c.first, "x.yaml"); }, {c.second});
  // Commas elsewhere are fine: in values, quotes, and flow collections over several lines.
  ConfigFile ok = ConfigFile::from_string(
      "a: [1, 2\n   , 3]\nb: ',x'\nc: x, y\nd: \"q\n, r\"\ne: it's # ', x\n", "ok.yaml");
  std::vector<double> a;
  EXPECT_TRUE(ok.read("a", a));
  EXPECT_EQ(a, (std::vector<double>{1, 2, 3}));
  std::string b, c, d, e;
  EXPECT_TRUE(ok.read("b", b));
  EXPECT_EQ(b, ",x");
  EXPECT_TRUE(ok.read("c", c));
  EXPECT_EQ(c, "x, y");
  EXPECT_TRUE(ok.read("d", d));
  EXPECT_EQ(d, "q , r");
  EXPECT_TRUE(ok.read("e", e));
  EXPECT_EQ(e, "it's");
}

TEST(ConfigFile, LoadErrors) {
  TempDir dir;
  expect_input_error([&] { ConfigFile::load(dir.file("none.yaml")); },
                     {"none.yaml", "cannot open"});
  expect_input_error([] { ConfigFile::from_string("- 1\n- 2\n", "seq.yaml"); },
                     {"seq.yaml", "top level must be a map"});
  expect_input_error([] { ConfigFile::from_string("just text\n", "s.yaml"); },
                     {"s.yaml", "top level must be a map"});
  expect_input_error([] { ConfigFile::from_string("a: 1\nb: 2\na: 3\n", "dup.yaml"); },
                     {"dup.yaml:3", "duplicate key 'a'"});
  expect_input_error([] { ConfigFile::from_string("a.b: 1\na:\n  b: 2\n", "dup.yaml"); },
                     {"dup.yaml:3: duplicate key 'a.b'"});
  expect_input_error([] { ConfigFile::from_string("a: 1\n---\nb: 2\n", "two.yaml"); },
                     {"two.yaml:2: YAML syntax error: expected one YAML document, got more"});
  expect_input_error(
      [] {
        ConfigFile::from_string(
            "M: !!opencv-matrix\n  rows: 2\n  cols: 2\n  dt: d\n  data: [1, 2, 3]\n", "m.yaml");
      },
      {"m.yaml", "key 'M'", "malformed OpenCV matrix"});
}

TEST(ConfigFile, OtherHeadersAndEmptyFiles) {
  ConfigFile yaml12 = ConfigFile::from_string("%YAML 1.2\n---\nFile.version: \"1.0\"\nx: 2\n");
  std::string version;
  EXPECT_TRUE(yaml12.read("File.version", version));
  EXPECT_EQ(version, "1.0");
  ConfigFile opencv = ConfigFile::from_string("%YAML:1.0\n---\nx: 2\n");
  int x = 0;
  EXPECT_TRUE(opencv.read("x", x));
  EXPECT_EQ(x, 2);
  EXPECT_TRUE(ConfigFile::from_string("").keys().empty());
  EXPECT_TRUE(ConfigFile::from_string("# only a comment\n").keys().empty());
  // A matrix map without the tag is still recognised by its fields.
  ConfigFile untagged =
      ConfigFile::from_string("K:\n  rows: 1\n  cols: 2\n  dt: d\n  data: [3, 4]\n");
  EXPECT_EQ(untagged.keys(), Keys{"K"});
  std::vector<double> k;
  EXPECT_TRUE(untagged.read("K", k));
  EXPECT_EQ(k, (std::vector<double>{3.0, 4.0}));
  // At the top level such fields are settings like any others.
  EXPECT_EQ(ConfigFile::from_string("rows: 1\ncols: 2\ndt: d\ndata: [3, 4]\n").keys(),
            (Keys{"cols", "data", "dt", "rows"}));
  // A byte order mark is skipped.
  EXPECT_EQ(ConfigFile::from_string("\xEF\xBB\xBFx: 1\n").keys(), Keys{"x"});
}

}  // namespace
}  // namespace mcslam::io
