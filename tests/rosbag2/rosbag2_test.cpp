// The ROS 2 recording reader and writer on recordings this test writes itself: every storage
// variant, big-endian CDR, and the corrupt and wrong inputs the check must report.
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <system_error>

#include "mcslam/core/error.hpp"
#include "mcslam/rosbag2/cdr.hpp"
#include "mcslam/rosbag2/recording.hpp"
#include "mcslam/rosbag2/source.hpp"
#include "rosbag2/messages.hpp"
#include "rosbag2/storage.hpp"

namespace fs = std::filesystem;
using namespace mcslam;
using namespace mcslam::rosbag2;

namespace {

/// This process's scratch folder, removed with the recordings in it when the process ends.
struct TempDir {
  fs::path path = fs::temp_directory_path() / ("mcslam-rosbag2-test-" + std::to_string(::getpid()));
  TempDir() {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ignored;
    fs::remove_all(path, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
};

const fs::path& temp_dir() {
  static const TempDir dir;
  return dir.path;
}

std::string fresh(const std::string& name) {
  const fs::path p = temp_dir() / name;
  fs::remove_all(p);
  return p.string();
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

/// Writes /text (String "message N") and an Image topic.
std::string write_strings(const std::string& name, const WriterOptions& o, int n = 20) {
  const std::string dir = fresh(name);
  RecordingWriter w(dir, o);
  const auto text = w.add_topic("/text", "std_msgs/msg/String", "string data");
  const auto image = w.add_topic("/image", "sensor_msgs/msg/Image");
  for (int i = 0; i < n; ++i) {
    w.write(text, 1000000000LL + i * 1000, detail::encode_string("message " + std::to_string(i)));
    io::ImagePixels px;
    px.encoding = "mono8";
    px.width = 64;
    px.height = 48;
    px.step = 64;
    px.data.assign(64 * 48, static_cast<std::uint8_t>(i));
    detail::Header h;
    h.stamp = {1, static_cast<std::uint32_t>(i * 1000)};
    w.write(image, 1000000000LL + i * 1000 + 1, detail::encode_image(h, px));
  }
  w.close();
  return dir;
}

std::vector<std::string> read_strings(const std::string& path) {
  const auto r = Recording::open(path);
  const auto t = r->find_topic("/text");
  EXPECT_TRUE(t);
  std::vector<bool> wanted(r->topics().size(), false);
  wanted[*t] = true;
  std::vector<std::string> out;
  std::vector<MessageRef> refs;
  r->read(wanted, [&](const MessageRef& ref, const Payload& p) {
    out.push_back(detail::decode_string(p.data, p.size));
    refs.push_back(ref);
  });
  // fetch() gives the same bytes again.
  for (std::size_t i = 0; i < refs.size(); ++i) {
    const Payload p = r->fetch(refs[i]);
    EXPECT_EQ(detail::decode_string(p.data, p.size), out[i]);
  }
  return out;
}

std::string storage_file(const std::string& dir) {
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".mcap" || e.path().extension() == ".db3") return e.path().string();
  return "";
}

std::vector<char> bytes_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

void write_bytes(const std::string& path, const std::vector<char>& b) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(b.data(), static_cast<std::streamsize>(b.size()));
}

/// Finds `needle` in the file's bytes (after `from`).
std::size_t find(const std::vector<char>& b, const std::string& needle, std::size_t from = 0) {
  const auto it = std::search(b.begin() + static_cast<std::ptrdiff_t>(from), b.end(),
                              needle.begin(), needle.end());
  return it == b.end() ? std::string::npos : static_cast<std::size_t>(it - b.begin());
}

}  // namespace

TEST(Cdr, LittleAndBigEndianWithAlignment) {
  // Header {sec, nanosec, frame_id "abc"}, then a uint8 and a double aligned to 8 from the
  // byte after the encapsulation header.
  const auto build = [](bool big) {
    std::vector<std::uint8_t> b = {0x00, static_cast<std::uint8_t>(big ? 0x00 : 0x01), 0, 0};
    const auto put = [&](const void* v, std::size_t n) {
      while ((b.size() - 4) % n) b.push_back(0);
      const auto* p = static_cast<const std::uint8_t*>(v);
      for (std::size_t i = 0; i < n; ++i) b.push_back(p[big ? n - 1 - i : i]);
    };
    const std::int32_t sec = 1305031229;
    const std::uint32_t nsec = 528748000, len = 4;
    put(&sec, 4);
    put(&nsec, 4);
    put(&len, 4);
    b.insert(b.end(), {'a', 'b', 'c', 0});
    b.push_back(7);
    const double d = -2.5;
    put(&d, 8);
    return b;
  };
  for (const bool big : {false, true}) {
    const auto b = build(big);
    CdrReader r(b.data(), b.size());
    EXPECT_EQ(r.little_endian(), !big);
    EXPECT_EQ(r.i32("sec"), 1305031229);
    EXPECT_EQ(r.u32("nsec"), 528748000u);
    EXPECT_EQ(r.string("frame"), "abc");
    EXPECT_EQ(r.u8("u8"), 7);
    EXPECT_EQ(r.f64("d"), -2.5);
    EXPECT_EQ(r.remaining(), 0u);
    EXPECT_EQ(b.size(), 4u + 12 + 4 + 1 + 7 + 8);  // 7 bytes padding before the double
  }
}

TEST(Cdr, BigEndianImageDecodes) {
  // A big-endian sensor_msgs/msg/Image written by hand.
  std::vector<std::uint8_t> b = {0x00, 0x00, 0x00, 0x00};
  const auto be32 = [&](std::uint32_t v) {
    while ((b.size() - 4) % 4) b.push_back(0);
    for (int s = 24; s >= 0; s -= 8) b.push_back(static_cast<std::uint8_t>(v >> s));
  };
  const auto str = [&](const std::string& s) {
    be32(static_cast<std::uint32_t>(s.size() + 1));
    b.insert(b.end(), s.begin(), s.end());
    b.push_back(0);
  };
  be32(5);
  be32(6);
  str("cam");
  be32(2);  // height
  be32(3);  // width
  str("mono8");
  b.push_back(0);
  be32(3);  // step
  be32(6);
  for (int i = 0; i < 6; ++i) b.push_back(static_cast<std::uint8_t>(10 + i));
  const auto m = detail::decode_image(b.data(), b.size());
  EXPECT_EQ(m.header.stamp.sec, 5);
  EXPECT_EQ(m.header.stamp.nanosec, 6u);
  EXPECT_EQ(m.header.frame_id, "cam");
  EXPECT_EQ(m.image.width, 3u);
  EXPECT_EQ(m.image.height, 2u);
  EXPECT_EQ(m.image.encoding, "mono8");
  const cv::Mat bgr = io::image_to_bgr(m.image, "x");
  EXPECT_EQ(bgr.at<cv::Vec3b>(1, 2)[0], 15);
}

TEST(Cdr, ShortMessagesAndUnknownEncapsulation) {
  auto b = detail::encode_camera_info({}, 640, 480, "plumb_bob", {0, 0, 0, 0, 0}, {}, {}, {});
  EXPECT_NO_THROW(detail::decode_camera_info(b.data(), b.size()));
  for (const std::size_t cut : {std::size_t{3}, std::size_t{20}, b.size() - 1}) {
    try {
      detail::decode_camera_info(b.data(), cut);
      ADD_FAILURE() << "no error for " << cut << " bytes";
    } catch (const CdrError& e) {
      EXPECT_TRUE(std::string(e.what()).find("short") != std::string::npos) << e.what();
    }
  }
  b[1] = 0x0A;  // PL_CDR2
  EXPECT_THROW(detail::decode_camera_info(b.data(), b.size()), CdrError);
  // A sequence count larger than the message.
  auto tf = detail::encode_tf({detail::Pose{}});
  tf[4] = 0xFF;
  EXPECT_THROW(detail::decode_tf(tf.data(), tf.size()), CdrError);
}

TEST(Recording, EveryStorageVariantRoundTrips) {
  struct Variant {
    std::string name;
    WriterOptions o;
  };
  std::vector<Variant> variants;
  for (const std::string c : {"none", "lz4", "zstd"})
    for (const bool chunked : {true, false})
      for (const bool summary : {true, false}) {
        if (!chunked && c != "none") continue;
        WriterOptions o;
        o.storage = "mcap";
        o.compression = c;
        o.chunked = chunked;
        o.summary = summary;
        o.chunk_size = 4096;  // several chunks
        variants.push_back(
            {"mcap_" + c + (chunked ? "_chunked" : "_flat") + (summary ? "_summary" : "_nosummary"),
             o});
      }
  for (const std::string c : {"none", "zstd"})
    for (const bool tables : {true, false}) {
      WriterOptions o;
      o.storage = "sqlite3";
      o.compression = c;
      o.sqlite_schema_tables = tables;
      variants.push_back({"sqlite_" + c + (tables ? "_v4" : "_old"), o});
    }
  for (const auto& v : variants) {
    SCOPED_TRACE(v.name);
    const std::string dir = write_strings(v.name, v.o);
    const auto r = Recording::open(dir);
    EXPECT_EQ(r->storage_identifier(), v.o.storage);
    ASSERT_EQ(r->topics().size(), 2u);
    EXPECT_EQ(r->topics()[0].name, "/text");
    EXPECT_EQ(r->topics()[0].type, "std_msgs/msg/String");
    EXPECT_EQ(r->topics()[0].message_count, 20u);
    EXPECT_EQ(r->topics()[1].message_count, 20u);
    EXPECT_EQ(r->message_count(), 40u);
    EXPECT_EQ(r->start_ns(), 1000000000LL);
    EXPECT_EQ(r->end_ns(), 1000000000LL + 19 * 1000 + 1);
    const auto texts = read_strings(dir);
    ASSERT_EQ(texts.size(), 20u);
    EXPECT_EQ(texts[0], "message 0");
    EXPECT_EQ(texts[19], "message 19");
    // The storage file alone opens too (no metadata.yaml).
    EXPECT_EQ(read_strings(storage_file(dir)).size(), 20u);
  }
}

TEST(Recording, CorruptFilesAreReported) {
  WriterOptions raw;
  raw.chunk_size = 1 << 20;
  const std::string dir = write_strings("corrupt_src", raw);
  const std::string file = storage_file(dir);
  const auto good = bytes_of(file);
  const auto check = [&](const std::string& name, std::vector<char> b, const std::string& expect) {
    const std::string path = (temp_dir() / (name + ".mcap")).string();
    write_bytes(path, b);
    const std::string e = error_of([&] { read_strings(path); });
    EXPECT_NE(e.find(path), std::string::npos) << name << ": " << e;
    EXPECT_NE(e.find(expect), std::string::npos) << name << ": " << e;
  };
  auto b = good;
  b[1] = 'X';
  check("badmagic", b, "bad magic");
  check("truncated", std::vector<char>(good.begin(), good.begin() + good.size() / 2), "truncated");
  b = good;
  const std::size_t text = find(b, "message 7");
  ASSERT_NE(text, std::string::npos);
  b[text] = 'M';
  check("crc", b, "CRC mismatch");
  // A chunk that does not decompress: the zstd frame's magic broken.
  WriterOptions z = raw;
  z.compression = "zstd";
  auto zb = bytes_of(storage_file(write_strings("corrupt_zstd", z)));
  const std::size_t magic = find(zb, std::string("\x28\xB5\x2F\xFD", 4));
  ASSERT_NE(magic, std::string::npos);
  zb[magic] = 0;
  check("zstd", zb, "zstd cannot decompress");
  WriterOptions l = raw;
  l.compression = "lz4";
  auto lb = bytes_of(storage_file(write_strings("corrupt_lz4", l)));
  const std::size_t lmagic = find(lb, std::string("\x04\x22\x4D\x18", 4));
  ASSERT_NE(lmagic, std::string::npos);
  lb[lmagic] = 0;
  check("lz4", lb, "lz4 cannot decompress");
  // Neither MCAP nor sqlite3.
  const std::string junk = (temp_dir() / "junk.db3").string();
  write_bytes(junk, std::vector<char>(100, 'x'));
  EXPECT_NE(error_of([&] { Recording::open(junk); }).find("not a ROS 2 recording"),
            std::string::npos);
}

TEST(Recording, SqliteThatIsNotARecording) {
  const std::string path = (temp_dir() / "other.db3").string();
  fs::remove(path);
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  sqlite3_exec(db, "CREATE TABLE songs(id INTEGER, title TEXT);", nullptr, nullptr, nullptr);
  sqlite3_close(db);
  const std::string e = error_of([&] { Recording::open(path); });
  EXPECT_NE(e.find(path), std::string::npos) << e;
  EXPECT_NE(e.find("not a ROS 2 recording"), std::string::npos) << e;
  EXPECT_NE(e.find("songs"), std::string::npos) << e;
  // A truncated sqlite3 recording.
  WriterOptions o;
  o.storage = "sqlite3";
  const std::string dir = write_strings("sqlite_trunc", o, 200);
  auto b = bytes_of(storage_file(dir));
  b.resize(b.size() / 3);
  const std::string cut = (temp_dir() / "cut.db3").string();
  write_bytes(cut, b);
  EXPECT_FALSE(error_of([&] { read_strings(cut); }).empty());
}

namespace {

/// A small RGB-D recording: colour (rgb8), depth (16UC1), CameraInfo and TF ground truth.
struct Names {
  std::string rgb = "/camera/rgb/image_color", depth = "/camera/depth/image",
              info = "/camera/rgb/camera_info";
};

std::string write_rgbd(const std::string& name, const std::string& storage,
                       const std::function<void(int, detail::Header&, io::ImagePixels&)>& edit = {},
                       const Names& names = {}) {
  const std::string dir = fresh(name);
  WriterOptions o;
  o.storage = storage;
  RecordingWriter w(dir, o);
  const auto rgb = w.add_topic(names.rgb, "sensor_msgs/msg/Image");
  const auto depth = w.add_topic(names.depth, "sensor_msgs/msg/Image");
  const auto info = w.add_topic(names.info, "sensor_msgs/msg/CameraInfo");
  const auto tf = w.add_topic("/tf", "tf2_msgs/msg/TFMessage");
  for (int i = 0; i < 5; ++i) {
    detail::Header h;
    h.stamp = {100, static_cast<std::uint32_t>(i * 33000000)};
    cv::Mat bgr(12, 16, CV_8UC3, cv::Scalar(i, 2 * i, 3 * i));
    cv::Mat d(12, 16, CV_32FC1, cv::Scalar(0.5 + i));
    io::ImagePixels c = io::image_pixels(bgr, "rgb8");
    io::ImagePixels m = io::image_pixels(d, "16UC1");
    detail::Header hc = h;
    if (edit) edit(i, hc, c);
    const std::int64_t ns = 100000000000LL + i * 33000000LL;
    w.write(rgb, ns, detail::encode_image(hc, c));
    w.write(depth, ns, detail::encode_image(h, m));
    w.write(info, ns,
            detail::encode_camera_info(h, 16, 12, "plumb_bob", {0.1, 0, 0, 0, 0},
                                       {20, 0, 8, 0, 21, 6, 0, 0, 1}, {}, {}));
    detail::Pose p;
    p.header = h;
    p.header.frame_id = "world";
    p.child_frame_id = "kinect";
    p.t = {1.0 * i, 0, 0};
    w.write(tf, ns, detail::encode_tf({p}));
  }
  w.close();
  return dir;
}

}  // namespace

TEST(RecordingSource, FramesIntrinsicsAndGroundTruth) {
  for (const std::string storage : {"mcap", "sqlite3"}) {
    SCOPED_TRACE(storage);
    const auto s = RecordingSource::open(write_rgbd("rgbd_" + storage, storage));
    ASSERT_EQ(s->frames().size(), 5u);
    EXPECT_DOUBLE_EQ(s->frames()[1].rgb_timestamp, 100.033);
    const auto images = s->load(3, 5000.0);
    EXPECT_EQ(images.rgb.at<cv::Vec3b>(2, 2), cv::Vec3b(3, 6, 9));
    EXPECT_FLOAT_EQ(images.depth.at<float>(2, 2), 3.5f);
    const auto hints = s->camera_hints();
    ASSERT_TRUE(hints.intrinsics);
    EXPECT_EQ(hints.intrinsics->fx, 20);
    EXPECT_EQ(hints.intrinsics->distortion[0], 0.1);
    const auto gt = s->groundtruth();
    ASSERT_TRUE(gt);
    ASSERT_EQ(gt->size(), 5u);
    EXPECT_DOUBLE_EQ((*gt)[4].T_w_c.translation().x(), 4.0);
  }
}

TEST(RecordingSource, BadRecordingsGiveOneClearError) {
  const std::string dir = write_rgbd("rgbd_ok", "mcap");
  SourceOptions o;
  o.topics.rgb = "/nope";
  std::string e = error_of([&] { RecordingSource::open(dir, o); });
  EXPECT_NE(e.find("no topic '/nope'"), std::string::npos) << e;
  EXPECT_NE(e.find("/camera/depth/image (sensor_msgs/msg/Image, 5)"), std::string::npos) << e;

  e = error_of([&] {
    RecordingSource::open(
        write_rgbd("rgbd_back", "mcap", [](int i, detail::Header& h, io::ImagePixels&) {
          if (i == 3) h.stamp.nanosec = 1000;
        }));
  });
  EXPECT_NE(e.find("topic '/camera/rgb/image_color' message 3"), std::string::npos) << e;
  EXPECT_NE(e.find("timestamps go back"), std::string::npos) << e;

  e = error_of([&] {
    RecordingSource::open(
        write_rgbd("rgbd_enc", "sqlite3", [](int i, detail::Header&, io::ImagePixels& p) {
          if (i == 2) p.encoding = "yuv422";
        }));
  });
  EXPECT_NE(e.find("message 2"), std::string::npos) << e;
  EXPECT_NE(e.find("unknown colour encoding 'yuv422'"), std::string::npos) << e;

  e = error_of([&] {
    RecordingSource::open(
        write_rgbd("rgbd_short", "mcap", [](int i, detail::Header&, io::ImagePixels& p) {
          if (i == 1) p.data.resize(10);
        }));
  });
  EXPECT_NE(e.find("too short"), std::string::npos) << e;
}

TEST(RecordingSource, ExportThenReadIsTheSameFrames) {
  // export_recording of a recording's own frames, read back: the same pixels.
  const auto s = RecordingSource::open(write_rgbd("rgbd_src", "mcap"));
  PinholeCamera camera;
  camera.width = 16;
  camera.height = 12;
  camera.fx = 20;
  camera.fy = 21;
  camera.cx = 8;
  camera.cy = 6;
  for (const std::string storage : {"mcap", "sqlite3"})
    for (const std::string rgb : {"bgr8", "png"}) {
      SCOPED_TRACE(storage + " " + rgb);
      ExportOptions eo;
      eo.storage = storage;
      eo.rgb_encoding = rgb;
      eo.depth_encoding = rgb == "png" ? "png" : "32FC1";  // millimetres exact here
      eo.compression = "zstd";
      const std::string out = fresh("export_" + storage + rgb);
      EXPECT_EQ(export_recording(*s, camera, out, eo), 5u);
      EXPECT_TRUE(fs::is_regular_file(fs::path(out) / "metadata.yaml"));
      const auto back = RecordingSource::open(out);
      ASSERT_EQ(back->frames().size(), 5u);
      EXPECT_EQ(back->frames()[2].rgb_timestamp, s->frames()[2].rgb_timestamp);
      const auto a = s->load(4, 1.0), b = back->load(4, 1.0);
      EXPECT_EQ(cv::norm(a.rgb, b.rgb, cv::NORM_INF), 0.0);
      EXPECT_EQ(cv::norm(a.depth, b.depth, cv::NORM_INF), 0.0);
      ASSERT_TRUE(back->groundtruth());
      EXPECT_EQ(back->groundtruth()->size(), 5u);
      ASSERT_TRUE(back->camera_hints().settings_yaml);
      // The folder exists now: a second export refuses it.
      EXPECT_NE(error_of([&] { export_recording(*s, camera, out, eo); }).find("already exists"),
                std::string::npos);
    }
}

TEST(Recording, FileCompressionAsRosbag2WritesIt) {
  // rosbag2's --compression-mode file: each storage file zstd-compressed whole (NAME.db3.zstd),
  // metadata.yaml listing the compressed names.
  for (const std::string storage : {"sqlite3", "mcap"}) {
    SCOPED_TRACE(storage);
    WriterOptions o;
    o.storage = storage;
    const std::string dir = write_strings("file_zstd_" + storage, o);
    const std::string file = storage_file(dir);
    const auto plain = bytes_of(file);
    const auto z =
        detail::zstd_compress(reinterpret_cast<const std::uint8_t*>(plain.data()), plain.size(), 3);
    write_bytes(file + ".zstd", std::vector<char>(z.begin(), z.end()));
    fs::remove(file);
    const std::string name = fs::path(file).filename().string();
    std::ifstream in(fs::path(dir) / "metadata.yaml");
    std::string yaml((std::istreambuf_iterator<char>(in)), {});
    in.close();
    for (const std::string& key : {"    - " + name, "    - path: " + name}) {
      const auto at = yaml.find(key);
      ASSERT_NE(at, std::string::npos);
      yaml.insert(at + key.size(), ".zstd");
    }
    for (const auto& [from, to] : {std::pair<std::string, std::string>{"compression_format: \"\"",
                                                                       "compression_format: zstd"},
                                   {"compression_mode: \"\"", "compression_mode: FILE"}})
      yaml.replace(yaml.find(from), from.size(), to);
    std::ofstream(fs::path(dir) / "metadata.yaml") << yaml;
    const auto r = Recording::open(dir);
    EXPECT_EQ(r->compression_mode(), "FILE");
    EXPECT_EQ(read_strings(dir).size(), 20u);
  }
}

TEST(ImageMessage, CompressedColourAndDepth) {
  cv::Mat bgr(30, 40, CV_8UC3, cv::Scalar(10, 120, 230));
  std::vector<std::uint8_t> jpeg;
  cv::imencode(".jpg", bgr, jpeg);
  EXPECT_EQ(
      io::check_compressed("rgb8; jpeg compressed bgr8", jpeg.data(), jpeg.size(), false, "x"),
      cv::Size(40, 30));
  const cv::Mat back = io::compressed_to_bgr("jpeg", jpeg.data(), jpeg.size(), "x");
  EXPECT_LT(cv::norm(back, bgr, cv::NORM_INF), 8.0);
  cv::Mat mm(30, 40, CV_16UC1, cv::Scalar(1234));
  std::vector<std::uint8_t> png;
  cv::imencode(".png", mm, png);
  std::vector<std::uint8_t> depth(12 + png.size(), 0);  // ConfigHeader, then the PNG
  std::memcpy(depth.data() + 12, png.data(), png.size());
  const cv::Mat m =
      io::compressed_depth_to_m("16UC1; compressedDepth png", depth.data(), depth.size(), "x");
  EXPECT_FLOAT_EQ(m.at<float>(3, 4), 1.234f);
  EXPECT_NE(error_of([&] {
              io::check_compressed("32FC1; compressedDepth", depth.data(), depth.size(), true,
                                   "here");
            }).find("unknown compressed depth format"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              io::check_compressed("tiff", jpeg.data(), jpeg.size(), false, "here");
            }).find("unknown compressed colour format 'tiff'"),
            std::string::npos);
}

TEST(RecordingSource, RealsensePresetHasTheRos2DriversNames) {
  SourceOptions o;
  o.topics = TopicOptions::preset("realsense");
  EXPECT_EQ(o.topics.rgb, "/camera/camera/color/image_raw");
  const Names ros2 = {"/camera/camera/color/image_raw",
                      "/camera/camera/aligned_depth_to_color/image_raw",
                      "/camera/camera/color/camera_info"};
  const auto a = RecordingSource::open(write_rgbd("rs_new", "mcap", {}, ros2), o);
  EXPECT_EQ(a->frames().size(), 5u);
  EXPECT_TRUE(a->camera_hints().intrinsics);
  EXPECT_FALSE(a->groundtruth());  // the preset has no ground-truth topic
  // The driver before 4.54 (no doubled /camera): found too.
  const Names old = {"/camera/color/image_raw", "/camera/aligned_depth_to_color/image_raw",
                     "/camera/color/camera_info"};
  const auto b = RecordingSource::open(write_rgbd("rs_old", "sqlite3", {}, old), o);
  EXPECT_EQ(b->frames().size(), 5u);
  EXPECT_TRUE(b->camera_hints().intrinsics);
  EXPECT_THROW(TopicOptions::preset("kinect"), InputError);
}

TEST(ImageMessage, BigEndianAndMisalignedDepth) {
  // 16UC1 with is_bigendian: 0x04D2 = 1234 mm; the data one byte off alignment.
  std::vector<std::uint8_t> bytes = {0, 0x04, 0xD2, 0x00, 0x0A};
  io::ImageMessage m;
  m.width = 2;
  m.height = 1;
  m.step = 4;
  m.encoding = "16UC1";
  m.is_bigendian = true;
  m.data = bytes.data() + 1;
  m.size = 4;
  cv::Mat d = io::image_to_depth_m(m, "x");
  EXPECT_FLOAT_EQ(d.at<float>(0, 0), 1.234f);
  EXPECT_FLOAT_EQ(d.at<float>(0, 1), 0.01f);
  m.is_bigendian = false;
  d = io::image_to_depth_m(m, "x");
  EXPECT_FLOAT_EQ(d.at<float>(0, 0), 53764 / 1000.0f);  // 0xD204
}
