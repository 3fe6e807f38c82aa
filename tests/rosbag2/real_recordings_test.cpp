// Recordings made by ROS 2's own tools (../shared/data/rosbag2, from the ros2/rosbag2 test
// resources): the listing matches their metadata.yaml (rebuilt where they have none) and the
// std_msgs/msg/String messages decode to the recorded text. Skips when the data are absent.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "io/yaml_subset.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/rosbag2/recording.hpp"
#include "mcslam/rosbag2/source.hpp"
#include "rosbag2/messages.hpp"

namespace fs = std::filesystem;
using namespace mcslam;
using namespace mcslam::rosbag2;

namespace {

const std::string kRoot = std::string(MCSLAM_SHARED_DATA) + "/rosbag2";

struct Expected {
  std::string storage;
  std::map<std::string, std::pair<std::string, std::uint64_t>> topics;  // name -> type, count
  std::uint64_t total = 0;
  std::int64_t start = 0, duration = 0;
};

Expected from_metadata(const std::string& dir) {
  const std::string path = dir + "/metadata.yaml";
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  const auto root = io::detail::parse_yaml(s.str(), path);
  const auto* info = root.find("rosbag2_bagfile_information");
  Expected e;
  e.storage = info->find("storage_identifier")->scalar;
  e.total = std::stoull(info->find("message_count")->scalar);
  e.start = std::stoll(info->find("starting_time")->find("nanoseconds_since_epoch")->scalar);
  e.duration = std::stoll(info->find("duration")->find("nanoseconds")->scalar);
  for (const auto& t : info->find("topics_with_message_count")->items) {
    const auto* m = t.find("topic_metadata");
    e.topics[m->find("name")->scalar] = {m->find("type")->scalar,
                                         std::stoull(t.find("message_count")->scalar)};
  }
  return e;
}

std::vector<std::string> strings_of(const Recording& r, const std::string& topic) {
  std::vector<bool> wanted(r.topics().size(), false);
  wanted[*r.find_topic(topic)] = true;
  std::vector<std::string> out;
  r.read(wanted, [&](const MessageRef&, const Payload& p) {
    out.push_back(detail::decode_string(p.data, p.size));
  });
  return out;
}

class RealRecordings : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::is_directory(kRoot)) GTEST_SKIP() << kRoot << " not found";
  }
};

TEST_F(RealRecordings, ListingMatchesMetadata) {
  for (const std::string name :
       {"sqlite3/talker", "mcap/talker", "sqlite3/cdr_test", "mcap/cdr_test",
        "sqlite3/test_bag_for_seek", "mcap/test_bag_for_seek"}) {
    SCOPED_TRACE(name);
    const std::string dir = kRoot + "/" + name;
    const Expected e = from_metadata(dir);
    const auto r = Recording::open(dir);
    EXPECT_EQ(r->storage_identifier(), e.storage);
    EXPECT_EQ(r->message_count(), e.total);
    EXPECT_EQ(r->start_ns(), e.start);
    EXPECT_EQ(r->end_ns() - r->start_ns(), e.duration);
    ASSERT_EQ(r->topics().size(), e.topics.size());
    for (const auto& t : r->topics()) {
      ASSERT_TRUE(e.topics.count(t.name)) << t.name;
      EXPECT_EQ(t.type, e.topics.at(t.name).first) << t.name;
      EXPECT_EQ(t.message_count, e.topics.at(t.name).second) << t.name;
      EXPECT_EQ(t.serialization_format, "cdr");
    }
    // bag-info says the same.
    const auto info = recording_info(dir);
    EXPECT_EQ(info["message_count"].get<std::uint64_t>(), e.total);
    EXPECT_EQ(info["topics"].size(), e.topics.size());
  }
}

TEST_F(RealRecordings, SplitRecordingsWithoutMetadataAreRebuilt) {
  // README: 1324 + 1324 + 529 messages on /chatter (std_msgs/msg/String) in three files.
  for (const std::string name : {"sqlite3/multiple_files", "mcap/multiple_files"}) {
    SCOPED_TRACE(name);
    const auto r = Recording::open(kRoot + "/" + name);
    ASSERT_EQ(r->files().size(), 3u);
    if (name.rfind("sqlite3", 0) == 0) {
      EXPECT_EQ(r->files()[0].message_count, 1324u);
      EXPECT_EQ(r->files()[1].message_count, 1324u);
      EXPECT_EQ(r->files()[2].message_count, 529u);
    }
    ASSERT_EQ(r->topics().size(), 1u);
    EXPECT_EQ(r->topics()[0].name, "/chatter");
    EXPECT_EQ(r->topics()[0].type, "std_msgs/msg/String");
    EXPECT_EQ(r->topics()[0].message_count, 3177u);
    const auto texts = strings_of(*r, "/chatter");
    ASSERT_EQ(texts.size(), 3177u);
    for (const auto& t : texts) ASSERT_EQ(t, "test");
  }
}

TEST_F(RealRecordings, TalkerStringsDecode) {
  for (const std::string name : {"sqlite3/talker", "mcap/talker"}) {
    SCOPED_TRACE(name);
    const auto r = Recording::open(kRoot + "/" + name);
    const auto texts = strings_of(*r, "/topic");
    ASSERT_EQ(texts.size(), 10u);
    for (std::size_t i = 0; i < texts.size(); ++i)
      EXPECT_EQ(texts[i], "Hello, world! " + std::to_string(i));
  }
}

TEST_F(RealRecordings, AsAFrameSourceTheMissingTopicsAreListed) {
  try {
    RecordingSource::open(kRoot + "/mcap/talker");
    FAIL() << "no error";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("no topic '/camera/rgb/image_color'"), std::string::npos) << m;
    EXPECT_NE(m.find("/topic (std_msgs/msg/String, 10)"), std::string::npos) << m;
  }
}

}  // namespace
