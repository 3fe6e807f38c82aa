#pragma once
// Internal to the rosbag2 module: the storage backends (one storage file each).

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "mcslam/rosbag2/recording.hpp"

namespace mcslam::rosbag2::detail {

struct FileTopic {
  std::string name, type, format = "cdr", qos, hash;
  std::uint64_t count = 0;
};

class StorageFile {
 public:
  virtual ~StorageFile() = default;
  /// Topics of this file (local indices), with their message counts; the time range.
  std::vector<FileTopic> topics;
  std::int64_t start_ns = 0, end_ns = 0;
  std::uint64_t message_count = 0;
  std::string ros_distro;

  using Visitor =
      std::function<void(std::uint32_t topic, std::int64_t timestamp, std::int64_t key,
                         std::uint64_t offset, const std::uint8_t* data, std::size_t size)>;
  /// Every message of the wanted (local) topics, in the file's order; checks the whole file.
  virtual void scan(const std::vector<bool>& wanted, const Visitor& fn) = 0;
  virtual Payload fetch(std::int64_t key, std::uint64_t offset, std::uint64_t size) = 0;
};

std::unique_ptr<StorageFile> open_sqlite(const std::string& path);
std::unique_ptr<StorageFile> open_mcap(const std::string& path);
/// Whether the file starts with MCAP's or SQLite's magic.
bool is_mcap_file(const std::string& path);
bool is_sqlite_file(const std::string& path);

struct WriterTopic {
  std::string name, type, definition, qos, hash;
};

class StorageWriter {
 public:
  virtual ~StorageWriter() = default;
  virtual void add_topic(std::uint32_t id, const WriterTopic& topic) = 0;
  virtual void write(std::uint32_t id, std::int64_t timestamp,
                     const std::vector<std::uint8_t>& data) = 0;
  /// `metadata_yaml`: what metadata.yaml holds (sqlite3 keeps a copy in its metadata table).
  virtual void close(const std::string& metadata_yaml) = 0;
};

std::unique_ptr<StorageWriter> make_mcap_writer(const std::string& path, const WriterOptions& o);
std::unique_ptr<StorageWriter> make_sqlite_writer(const std::string& path, const WriterOptions& o);

/// zstd of a whole buffer; throws std::runtime_error.
std::vector<std::uint8_t> zstd_decompress(const std::uint8_t* data, std::size_t size);
std::vector<std::uint8_t> zstd_compress(const std::uint8_t* data, std::size_t size, int level);

}  // namespace mcslam::rosbag2::detail
