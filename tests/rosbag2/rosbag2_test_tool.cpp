// Makes bad ROS 2 recordings for tests/rosbag2/bad_recordings_test.sh:
//   rosbag2_test_tool mutate IN OUT encoding|stamps-back|short   (colour message 3 changed)
//   rosbag2_test_tool sqlite-other OUT.db3                       (a database that is no recording)
#include <sqlite3.h>

#include <cstring>
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
