// Makes bad ROS 2 recordings for tests/rosbag2/bad_recordings_test.sh:
//   rosbag2_test_tool mutate IN OUT encoding|stamps-back|short   (colour message 3 changed)
//   rosbag2_test_tool sqlite-other OUT.db3                       (a database that is no recording)
//   rosbag2_test_tool seeds MCAP_DIR CDR_DIR                     (the fuzzers' seed corpora)
#include <sqlite3.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "mcslam/core/error.hpp"
#include "mcslam/rosbag2/recording.hpp"
#include "rosbag2/messages.hpp"

using namespace mcslam::rosbag2;

int main(int argc, char** argv) {
  try {
    const std::string command = argc > 1 ? argv[1] : "";
    if (command == "sqlite-other" && argc == 3) {
      sqlite3* db = nullptr;
      if (sqlite3_open(argv[2], &db) != SQLITE_OK) return 2;
      sqlite3_exec(db, "CREATE TABLE songs(id INTEGER, title TEXT);", nullptr, nullptr, nullptr);
      sqlite3_close(db);
      return 0;
    }
    if (command == "seeds" && argc == 4) {
      namespace fs = std::filesystem;
      int n = 0;
      for (const std::string c : {"none", "lz4", "zstd"})
        for (const bool chunked : {true, false})
          for (const bool summary : {true, false}) {
            if (!chunked && c != "none") continue;
            WriterOptions o;
            o.compression = c;
            o.chunked = chunked;
            o.summary = summary;
            o.chunk_size = 64;
            const fs::path tmp = fs::temp_directory_path() / ("mcslam_seed_" + std::to_string(n));
            fs::remove_all(tmp);
            {
              RecordingWriter w(tmp.string(), o);
              const auto t = w.add_topic("/chatter", "std_msgs/msg/String", "string data");
              for (int i = 0; i < 3; ++i)
                w.write(t, 1000 + i, detail::encode_string("hello " + std::to_string(i)));
              w.close();
            }
            fs::copy_file(tmp / (tmp.filename().string() + "_0.mcap"),
                          fs::path(argv[2]) / ("seed_" + std::to_string(n++) + ".mcap"),
                          fs::copy_options::overwrite_existing);
            fs::remove_all(tmp);
          }
      const auto put = [&](const std::string& name, const std::vector<std::uint8_t>& b) {
        std::ofstream(fs::path(argv[3]) / name, std::ios::binary)
            .write(reinterpret_cast<const char*>(b.data()), static_cast<long>(b.size()));
      };
      detail::Header h;
      h.stamp = {12, 34};
      h.frame_id = "camera";
      mcslam::io::ImagePixels px;
      px.encoding = "mono8";
      px.width = 4;
      px.height = 2;
      px.step = 4;
      px.data.assign(8, 7);
      put("image", detail::encode_image(h, px));
      put("compressed", detail::encode_compressed_image(h, "png", {0x89, 'P', 'N', 'G'}));
      put("camera_info", detail::encode_camera_info(h, 4, 2, "plumb_bob", {0, 0, 0, 0, 0},
                                                    {1, 0, 2, 0, 1, 1, 0, 0, 1}, {}, {}));
      detail::Pose pose;
      pose.header = h;
      pose.child_frame_id = "kinect";
      put("tf", detail::encode_tf({pose, pose}));
      put("string", detail::encode_string("hello"));
      return 0;
    }
    if (command != "mutate" || argc != 5) {
      std::cerr << "usage: rosbag2_test_tool mutate IN OUT encoding|stamps-back|short\n"
                   "       rosbag2_test_tool sqlite-other OUT.db3\n";
      return 2;
    }
    const std::string kind = argv[4];
    const auto in = Recording::open(argv[2]);
    WriterOptions o;
    o.storage = in->storage_identifier();
    RecordingWriter out(argv[3], o);
    for (const auto& t : in->topics()) out.add_topic(t.name, t.type);
    std::vector<bool> all(in->topics().size(), true);
    std::size_t rgb_count = 0;
    detail::Stamp first_stamp;
    in->read(all, [&](const MessageRef& ref, const Payload& p) {
      std::vector<std::uint8_t> data(p.data, p.data + p.size);
      if (in->topics()[ref.topic].name == "/camera/rgb/image_color") {
        const std::size_t k = rgb_count++;
        auto m = detail::decode_image(p.data, p.size);
        if (k == 0) first_stamp = m.header.stamp;
        if (k == 3) {
          mcslam::io::ImagePixels px;
          px.encoding = m.image.encoding;
          px.width = m.image.width;
          px.height = m.image.height;
          px.step = m.image.step;
          px.data.assign(m.image.data, m.image.data + m.image.size);
          if (kind == "encoding") px.encoding = "yuv422";
          if (kind == "stamps-back") m.header.stamp = first_stamp;
          data = detail::encode_image(m.header, px);
          if (kind == "short") data.resize(40);
        }
      }
      out.write(ref.topic, ref.timestamp, data);
    });
    out.close();
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "rosbag2_test_tool: " << e.what() << "\n";
    return 1;
  }
}
