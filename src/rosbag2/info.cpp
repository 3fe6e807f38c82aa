#include <cstdio>
#include <ctime>
#include <filesystem>
#include <sstream>

#include "mcslam/rosbag2/recording.hpp"
#include "mcslam/rosbag2/source.hpp"

namespace fs = std::filesystem;

namespace mcslam::rosbag2 {

nlohmann::json recording_info(const std::string& path) {
  const auto r = Recording::open(path);
  nlohmann::json j;
  j["path"] = path;
  j["storage_identifier"] = r->storage_identifier();
  std::uint64_t bytes = 0;
  nlohmann::json files = nlohmann::json::array();
  for (std::uint32_t f = 0; f < r->files().size(); ++f) {
    std::error_code ec;
    const auto size = fs::file_size(r->file_path(f), ec);
    if (!ec) bytes += size;
    files.push_back({{"path", r->files()[f].path}, {"message_count", r->files()[f].message_count}});
  }
  j["files"] = files;
  j["bag_size"] = bytes;
  j["start_ns"] = r->start_ns();
  j["end_ns"] = r->end_ns();
  j["duration_ns"] = r->end_ns() - r->start_ns();
  j["message_count"] = r->message_count();
  j["compression_format"] = r->compression_format();
  j["compression_mode"] = r->compression_mode();
  j["metadata_version"] = r->metadata_version();
  nlohmann::json topics = nlohmann::json::array();
  for (const auto& t : r->topics())
    topics.push_back({{"name", t.name},
                      {"type", t.type},
                      {"message_count", t.message_count},
                      {"serialization_format", t.serialization_format}});
  j["topics"] = topics;
  return j;
}

namespace {

std::string size_text(double bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (bytes >= 1024.0 && u < 4) {
    bytes /= 1024.0;
    ++u;
  }
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f %s", bytes, units[u]);
  return text;
}

std::string time_text(std::int64_t ns) {
  const std::time_t s = static_cast<std::time_t>(ns / 1000000000);
  std::tm tm{};
  gmtime_r(&s, &tm);
  char date[64];
  std::strftime(date, sizeof(date), "%b %e %Y %H:%M:%S", &tm);
  char text[128];
  std::snprintf(text, sizeof(text), "%s.%03d (%lld.%03d)", date,
                static_cast<int>((ns / 1000000) % 1000), static_cast<long long>(s),
                static_cast<int>((ns / 1000000) % 1000));
  return text;
}

}  // namespace

std::string info_text(const nlohmann::json& info) {
  std::ostringstream o;
  const auto field = [&o](const char* name) {
    o << name;
    for (std::size_t i = std::string(name).size(); i < 19; ++i) o << ' ';
  };
  field("Files:");
  bool first = true;
  for (const auto& f : info["files"]) {
    if (!first) o << std::string(19, ' ');
    o << f["path"].get<std::string>() << "\n";
    first = false;
  }
  if (first) o << "\n";
  field("Bag size:");
  o << size_text(info["bag_size"].get<double>()) << "\n";
  field("Storage id:");
  o << info["storage_identifier"].get<std::string>() << "\n";
  if (info.contains("compression_format") &&
      !info["compression_format"].get<std::string>().empty()) {
    field("Compression:");
    o << info["compression_format"].get<std::string>() << " ("
      << info["compression_mode"].get<std::string>() << ")\n";
  }
  char duration[32];
  std::snprintf(duration, sizeof(duration), "%.3fs", info["duration_ns"].get<double>() * 1e-9);
  field("Duration:");
  o << duration << "\n";
  field("Start:");
  o << time_text(info["start_ns"].get<std::int64_t>()) << "\n";
  field("End:");
  o << time_text(info["end_ns"].get<std::int64_t>()) << "\n";
  field("Messages:");
  o << info["message_count"].get<std::uint64_t>() << "\n";
  field("Topic information:");
  first = true;
  for (const auto& t : info["topics"]) {
    if (!first) o << std::string(19, ' ');
    o << "Topic: " << t["name"].get<std::string>() << " | Type: " << t["type"].get<std::string>()
      << " | Count: " << t["message_count"].get<std::uint64_t>()
      << " | Serialization Format: " << t["serialization_format"].get<std::string>() << "\n";
    first = false;
  }
  if (first) o << "\n";
  return o.str();
}

}  // namespace mcslam::rosbag2
