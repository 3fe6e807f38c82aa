#pragma once
// ROS 2 recordings (rosbag2) without ROS 2: the storage layer. A recording is a folder with
// metadata.yaml and one or more storage files (sqlite3 `.db3` or MCAP `.mcap`), or one such file,
// or a split recording's folder without metadata.yaml (its listing rebuilt from the files, as
// `ros2 bag reindex` does). Messages are returned as they are stored (CDR bytes); rosbag2's
// own zstd compression (per file or per message) is undone here.

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace mcslam::rosbag2 {

struct TopicInfo {
  std::string name;
  std::string type;  // e.g. sensor_msgs/msg/Image
  std::string serialization_format = "cdr";
  std::string offered_qos_profiles;  // rosbag2's YAML text, as stored
  std::string type_description_hash;
  std::uint64_t message_count = 0;  // counted in the files
};

struct FileInfo {
  std::string path;  // relative to the recording's folder
  std::int64_t start_ns = 0;
  std::int64_t duration_ns = 0;
  std::uint64_t message_count = 0;
};

/// A stored message's bytes. `keep` holds what they point into while it lives.
struct Payload {
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
  std::shared_ptr<const void> keep;
};

/// Where a message is stored, to read it again later.
struct MessageRef {
  std::uint32_t topic = 0;  // index into Recording::topics()
  std::uint32_t file = 0;
  std::int64_t timestamp = 0;  // the storage's receive time, nanoseconds
  std::int64_t key = 0;        // sqlite3: the row id; MCAP: the chunk (-1: not in a chunk)
  std::uint64_t offset = 0;    // MCAP: where the message's data start (in the chunk or file)
  std::uint64_t size = 0;      // MCAP: its length
};

class Recording {
 public:
  /// Opens and lists a recording: its files, their topics and message counts. Throws
  /// InputError "<file>: <problem>" for a missing path, an unknown layout, a file that is not a
  /// recording (bad magic, not a database, no topics/messages tables), truncation or a corrupt
  /// listing. The messages themselves are checked by read().
  static std::unique_ptr<Recording> open(const std::string& path);
  ~Recording();

  const std::string& path() const;
  /// "sqlite3" or "mcap".
  const std::string& storage_identifier() const;
  const std::vector<TopicInfo>& topics() const;
  std::optional<std::size_t> find_topic(const std::string& name) const;
  const std::vector<FileInfo>& files() const;
  std::int64_t start_ns() const;
  std::int64_t end_ns() const;
  std::uint64_t message_count() const;
  /// From metadata.yaml ("" and 0 without one).
  const std::string& compression_format() const;
  const std::string& compression_mode() const;
  int metadata_version() const;
  const std::string& ros_distro() const;

  /// Reads every message of the topics with wanted[topic] set, file after file in each file's
  /// order (sqlite3: by timestamp), checking the whole recording on the way (MCAP: every record,
  /// chunk CRC and decompression). `fn` gets the bytes, valid during the call. Throws InputError.
  using Visitor = std::function<void(const MessageRef&, const Payload&)>;
  void read(const std::vector<bool>& wanted, const Visitor& fn) const;
  /// A message read earlier, again (thread-safe). Throws InputError.
  Payload fetch(const MessageRef& ref) const;
  /// The file a message is in (for error messages).
  std::string file_path(std::uint32_t file) const;

  struct Impl;

 private:
  explicit Recording(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// Writes a recording as rosbag2 does: `folder/` with metadata.yaml and `folder_0.mcap` or
/// `folder_0.db3`. The folder must not exist (rosbag2's rule).
struct WriterOptions {
  std::string storage = "mcap";  // or "sqlite3"
  /// MCAP: chunk compression "none", "lz4" or "zstd" (the mcap plugin's own, as its presets do);
  /// sqlite3: "none" or "zstd" (rosbag2's per-message compression, compression_mode MESSAGE).
  std::string compression = "none";
  /// MCAP: write the summary section (schemas, channels, statistics, chunk indexes).
  bool summary = true;
  /// MCAP: put messages in chunks (otherwise straight in the data section).
  bool chunked = true;
  /// sqlite3: create the schema, metadata and message_definitions tables (schema version 4);
  /// without them the layout of Foxy/Galactic recordings.
  bool sqlite_schema_tables = true;
  std::size_t chunk_size = 768 * 1024;
};

class RecordingWriter {
 public:
  /// Throws InputError for bad options or a folder that cannot be made.
  RecordingWriter(const std::string& folder, const WriterOptions& options);
  ~RecordingWriter();
  /// Returns the topic's index. `definition`: the ros2msg text of the type (may be empty).
  std::uint32_t add_topic(const std::string& name, const std::string& type,
                          const std::string& definition = "");
  void write(std::uint32_t topic, std::int64_t timestamp_ns, const std::vector<std::uint8_t>& cdr);
  /// Finishes the storage file and writes metadata.yaml.
  void close();

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

/// The offered QoS profile text rosbag2 stores for a reliable, volatile, keep-all publisher.
std::string default_qos_profile();

}  // namespace mcslam::rosbag2
