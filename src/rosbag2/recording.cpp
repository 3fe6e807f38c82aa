#include "mcslam/rosbag2/recording.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include "io/yaml_subset.hpp"
#include "mcslam/core/error.hpp"
#include "storage.hpp"

namespace fs = std::filesystem;

namespace mcslam::rosbag2 {
namespace {

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(file_error(path, "cannot read"));
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// The trailing number of a split file's stem ("bag_12.db3" -> 12), for ordering.
long split_index(const std::string& name) {
  std::string stem = fs::path(name).stem().string();
  std::size_t end = stem.size();
  std::size_t begin = end;
  while (begin > 0 && std::isdigit(static_cast<unsigned char>(stem[begin - 1]))) --begin;
  if (begin == end || end - begin > 9) return -1;
  return std::stol(stem.substr(begin, end - begin));
}

std::string scalar(const io::detail::YamlNode* node) {
  return node && node->kind == io::detail::YamlNode::Kind::kScalar ? node->scalar : "";
}

std::int64_t integer(const io::detail::YamlNode* node, const std::string& path,
                     const std::string& key) {
  const std::string s = scalar(node);
  if (s.empty()) return 0;
  try {
    std::size_t used = 0;
    const long long v = std::stoll(s, &used);
    if (used != s.size()) throw std::invalid_argument(s);
    return v;
  } catch (const std::exception&) {
    throw InputError(file_error(path, key + ": not an integer ('" + s + "')"));
  }
}

std::atomic<int> g_temp_counter{0};

/// Whether a message is a zstd frame (rosbag2's per-message compression; a CDR payload starts
/// with 00). A storage file opened without its metadata.yaml does not say it is compressed.
bool is_zstd(const std::uint8_t* data, std::size_t size) {
  return size >= 4 && data[0] == 0x28 && data[1] == 0xB5 && data[2] == 0x2F && data[3] == 0xFD;
}

}  // namespace

struct Recording::Impl {
  std::string path;    // as given
  std::string folder;  // where the storage files are
  std::string storage;
  std::vector<std::unique_ptr<detail::StorageFile>> files;
  std::vector<std::string> file_paths;  // full paths (for errors)
  std::vector<FileInfo> file_infos;
  std::vector<std::vector<std::uint32_t>> local_to_global;  // per file
  std::vector<TopicInfo> topics;
  std::int64_t start = 0, end = 0;
  std::uint64_t count = 0;
  std::string compression_format, compression_mode, ros_distro;
  int metadata_version = 0;
  bool message_zstd = false;
  std::vector<std::string> temp_files;

  ~Impl() {
    files.clear();
    std::error_code ignored;
    for (const auto& t : temp_files) fs::remove(t, ignored);
  }

  void add_file(const std::string& full, const std::string& relative);
  std::string decompress_file(const std::string& full);
  void finish();
};

std::string Recording::Impl::decompress_file(const std::string& full) {
  std::ifstream in(full, std::ios::binary);
  if (!in) throw InputError(file_error(full, "cannot read"));
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), {});
  std::vector<std::uint8_t> plain;
  try {
    plain = detail::zstd_decompress(bytes.data(), bytes.size());
  } catch (const std::exception& e) {
    throw InputError(file_error(full, std::string("rosbag2 file compression: zstd cannot "
                                                  "decompress it (") +
                                          e.what() + ")"));
  }
  const fs::path tmp = fs::temp_directory_path() / ("mcslam-rosbag2-" + std::to_string(::getpid()) +
                                                    "-" + std::to_string(g_temp_counter++) + "-" +
                                                    fs::path(full).stem().filename().string());
  std::ofstream out(tmp, std::ios::binary);
  out.write(reinterpret_cast<const char*>(plain.data()),
            static_cast<std::streamsize>(plain.size()));
  if (!out) throw InputError(file_error(tmp.string(), "cannot write the decompressed file"));
  temp_files.push_back(tmp.string());
  return tmp.string();
}

void Recording::Impl::add_file(const std::string& full, const std::string& relative) {
  if (!fs::is_regular_file(full))
    throw InputError(file_error(full, "no such file (metadata.yaml lists it)"));
  std::string actual = full;
  if (ends_with(full, ".zstd") || compression_mode == "FILE") actual = decompress_file(full);
  std::unique_ptr<detail::StorageFile> file;
  if (detail::is_mcap_file(actual)) {
    file = detail::open_mcap(actual);
    if (storage.empty()) storage = "mcap";
  } else if (detail::is_sqlite_file(actual)) {
    file = detail::open_sqlite(actual);
    if (storage.empty()) storage = "sqlite3";
  } else if (ends_with(full, ".mcap") || storage == "mcap") {
    file = detail::open_mcap(actual);  // reports the bad magic
  } else {
    throw InputError(file_error(full,
                                "neither an MCAP file nor a sqlite3 database (bad magic; "
                                "not a ROS 2 recording)"));
  }
  std::vector<std::uint32_t> map;
  for (const auto& t : file->topics) {
    std::uint32_t g = 0;
    while (g < topics.size() && !(topics[g].name == t.name && topics[g].type == t.type)) ++g;
    if (g == topics.size()) {
      TopicInfo info;
      info.name = t.name;
      info.type = t.type;
      info.serialization_format = t.format;
      info.offered_qos_profiles = t.qos;
      info.type_description_hash = t.hash;
      topics.push_back(info);
    }
    topics[g].message_count += t.count;
    map.push_back(g);
  }
  FileInfo fi;
  fi.path = relative;
  fi.start_ns = file->start_ns;
  fi.duration_ns = file->end_ns - file->start_ns;
  fi.message_count = file->message_count;
  if (ros_distro.empty()) ros_distro = file->ros_distro;
  local_to_global.push_back(std::move(map));
  files.push_back(std::move(file));
  file_paths.push_back(full);
  file_infos.push_back(fi);
}

void Recording::Impl::finish() {
  std::int64_t first = std::numeric_limits<std::int64_t>::max();
  std::int64_t last = std::numeric_limits<std::int64_t>::min();
  count = 0;
  for (const auto& f : files) {
    if (f->message_count == 0) continue;
    count += f->message_count;
    first = std::min(first, f->start_ns);
    last = std::max(last, f->end_ns);
  }
  start = count ? first : 0;
  end = count ? last : 0;
}

std::unique_ptr<Recording> Recording::open(const std::string& path) {
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    impl->folder = path;
    const fs::path meta = fs::path(path) / "metadata.yaml";
    if (fs::is_regular_file(meta)) {
      const std::string name = meta.string();
      const auto root = io::detail::parse_yaml(read_text(name), name);
      const auto* info = root.find("rosbag2_bagfile_information");
      if (!info || info->kind != io::detail::YamlNode::Kind::kMap)
        throw InputError(file_error(name,
                                    "no rosbag2_bagfile_information (not a rosbag2 "
                                    "metadata file)"));
      impl->metadata_version = static_cast<int>(integer(info->find("version"), name, "version"));
      const std::string storage = scalar(info->find("storage_identifier"));
      if (storage != "sqlite3" && storage != "mcap")
        throw InputError(file_error(name, "storage_identifier '" + storage +
                                              "': mcslam reads sqlite3 and mcap recordings"));
      impl->storage = storage;
      impl->compression_format = scalar(info->find("compression_format"));
      impl->compression_mode = scalar(info->find("compression_mode"));
      impl->ros_distro = scalar(info->find("ros_distro"));
      if (!impl->compression_format.empty() && impl->compression_format != "zstd")
        throw InputError(file_error(name, "compression_format '" + impl->compression_format +
                                              "': mcslam reads zstd-compressed recordings only"));
      if (!impl->compression_format.empty() && impl->compression_mode != "FILE" &&
          impl->compression_mode != "MESSAGE")
        throw InputError(file_error(
            name, "compression_mode '" + impl->compression_mode + "' (FILE or MESSAGE)"));
      impl->message_zstd =
          impl->compression_format == "zstd" && impl->compression_mode == "MESSAGE";
      const auto* paths = info->find("relative_file_paths");
      if (!paths || paths->kind != io::detail::YamlNode::Kind::kSequence || paths->items.empty())
        throw InputError(file_error(name, "no relative_file_paths"));
      for (const auto& item : paths->items) {
        const std::string rel = scalar(&item);
        // Recordings made by older rosbag2 list paths with the folder's name in front.
        fs::path full = fs::path(path) / rel;
        if (!fs::exists(full)) full = fs::path(path) / fs::path(rel).filename();
        impl->add_file(full.string(), rel);
      }
    } else {
      // A split recording without metadata.yaml: its storage files, by their split index.
      std::vector<std::string> names;
      for (const auto& e : fs::directory_iterator(path, ec))
        if (e.is_regular_file()) {
          const std::string n = e.path().filename().string();
          if (ends_with(n, ".db3") || ends_with(n, ".mcap")) names.push_back(n);
        }
      if (names.empty())
        throw InputError(file_error(path,
                                    "not a ROS 2 recording: no metadata.yaml and no .db3 "
                                    "or .mcap files"));
      std::sort(names.begin(), names.end(), [](const std::string& a, const std::string& b) {
        const long ia = split_index(a), ib = split_index(b);
        return ia != ib ? ia < ib : a < b;
      });
      for (const auto& n : names) impl->add_file((fs::path(path) / n).string(), n);
    }
  } else if (fs::is_regular_file(path, ec)) {
    impl->folder = fs::path(path).parent_path().string();
    impl->add_file(path, fs::path(path).filename().string());
  } else {
    throw InputError(file_error(path, "no such file or folder"));
  }
  impl->finish();
  return std::unique_ptr<Recording>(new Recording(std::move(impl)));
}

Recording::Recording(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Recording::~Recording() = default;
const std::string& Recording::path() const { return impl_->path; }
const std::string& Recording::storage_identifier() const { return impl_->storage; }
const std::vector<TopicInfo>& Recording::topics() const { return impl_->topics; }
const std::vector<FileInfo>& Recording::files() const { return impl_->file_infos; }
std::int64_t Recording::start_ns() const { return impl_->start; }
std::int64_t Recording::end_ns() const { return impl_->end; }
std::uint64_t Recording::message_count() const { return impl_->count; }
const std::string& Recording::compression_format() const { return impl_->compression_format; }
const std::string& Recording::compression_mode() const { return impl_->compression_mode; }
int Recording::metadata_version() const { return impl_->metadata_version; }
const std::string& Recording::ros_distro() const { return impl_->ros_distro; }
std::string Recording::file_path(std::uint32_t file) const {
  return file < impl_->file_paths.size() ? impl_->file_paths[file] : impl_->path;
}

std::optional<std::size_t> Recording::find_topic(const std::string& name) const {
  for (std::size_t t = 0; t < impl_->topics.size(); ++t)
    if (impl_->topics[t].name == name) return t;
  return std::nullopt;
}

void Recording::read(const std::vector<bool>& wanted, const Visitor& fn) const {
  for (std::uint32_t f = 0; f < impl_->files.size(); ++f) {
    const auto& map = impl_->local_to_global[f];
    std::vector<bool> local(map.size(), false);
    for (std::size_t l = 0; l < map.size(); ++l)
      local[l] = map[l] < wanted.size() && wanted[map[l]];
    const std::string& file_path = impl_->file_paths[f];
    const bool zstd_messages = impl_->message_zstd;
    impl_->files[f]->scan(
        local, [&](std::uint32_t topic, std::int64_t ts, std::int64_t key, std::uint64_t offset,
                   const std::uint8_t* data, std::size_t size) {
          MessageRef ref;
          ref.topic = map[topic];
          ref.file = f;
          ref.timestamp = ts;
          ref.key = key;
          ref.offset = offset;
          ref.size = size;
          if (zstd_messages || is_zstd(data, size)) {
            std::vector<std::uint8_t> plain;
            try {
              plain = detail::zstd_decompress(data, size);
            } catch (const std::exception& e) {
              throw InputError(file_error(
                  file_path, "topic '" + impl_->topics[ref.topic].name +
                                 "': a message does not decompress (zstd: " + e.what() + ")"));
            }
            fn(ref, Payload{plain.data(), plain.size(), nullptr});
          } else {
            fn(ref, Payload{data, size, nullptr});
          }
        });
  }
}

Payload Recording::fetch(const MessageRef& ref) const {
  Payload p = impl_->files.at(ref.file)->fetch(ref.key, ref.offset, ref.size);
  if (!impl_->message_zstd && !is_zstd(p.data, p.size)) return p;
  try {
    auto plain =
        std::make_shared<std::vector<std::uint8_t>>(detail::zstd_decompress(p.data, p.size));
    return {plain->data(), plain->size(), plain};
  } catch (const std::exception& e) {
    throw InputError(
        file_error(impl_->file_paths.at(ref.file),
                   std::string("a message does not decompress (zstd: ") + e.what() + ")"));
  }
}

// ---- writer ----

std::string default_qos_profile() {
  return "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n  deadline:\n    sec: "
         "0\n    nsec: 0\n  lifespan:\n    sec: 0\n    nsec: 0\n  liveliness: 1\n  "
         "liveliness_lease_duration:\n    sec: 0\n    nsec: 0\n  "
         "avoid_ros_namespace_conventions: false";
}

namespace {

/// A YAML double-quoted scalar.
std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out += c;
  }
  return out + "\"";
}

}  // namespace

struct RecordingWriter::Impl {
  std::string folder, file_name;
  WriterOptions options;
  std::unique_ptr<detail::StorageWriter> storage;
  std::vector<detail::WriterTopic> topics;
  std::vector<std::uint64_t> counts;
  std::int64_t first = std::numeric_limits<std::int64_t>::max();
  std::int64_t last = std::numeric_limits<std::int64_t>::min();
  bool closed = false;

  /// The metadata as rosbag2 serialises it (the sqlite3 metadata table holds this text; in
  /// metadata.yaml it sits under rosbag2_bagfile_information).
  std::string metadata() const {
    std::uint64_t total = 0;
    for (const auto c : counts) total += c;
    const std::int64_t start = total ? first : 0;
    const std::int64_t duration = total ? last - first : 0;
    const bool sqlite_zstd = options.storage == "sqlite3" && options.compression == "zstd";
    std::ostringstream y;
    y << "version: 8\n"
      << "storage_identifier: " << options.storage << "\n"
      << "duration:\n  nanoseconds: " << duration << "\n"
      << "starting_time:\n  nanoseconds_since_epoch: " << start << "\n"
      << "message_count: " << total << "\n"
      << "topics_with_message_count:\n";
    for (std::size_t t = 0; t < topics.size(); ++t) {
      y << "  - topic_metadata:\n"
        << "      name: " << topics[t].name << "\n"
        << "      type: " << topics[t].type << "\n"
        << "      serialization_format: cdr\n"
        << "      offered_qos_profiles: " << quoted(topics[t].qos) << "\n"
        << "      type_description_hash: " << quoted(topics[t].hash) << "\n"
        << "    message_count: " << counts[t] << "\n";
    }
    y << "compression_format: " << quoted(sqlite_zstd ? "zstd" : "") << "\n"
      << "compression_mode: " << quoted(sqlite_zstd ? "MESSAGE" : "") << "\n"
      << "relative_file_paths:\n  - " << file_name << "\n"
      << "files:\n  - path: " << file_name << "\n"
      << "    starting_time:\n      nanoseconds_since_epoch: " << start << "\n"
      << "    duration:\n      nanoseconds: " << duration << "\n"
      << "    message_count: " << total << "\n"
      << "custom_data: ~\n"
      << "ros_distro: \"\"\n";
    return y.str();
  }

  /// metadata.yaml: the metadata under rosbag2_bagfile_information.
  std::string metadata_file() const {
    std::string out = "rosbag2_bagfile_information:\n";
    std::istringstream in(metadata());
    for (std::string line; std::getline(in, line);) out += "  " + line + "\n";
    return out;
  }
};

RecordingWriter::RecordingWriter(const std::string& folder, const WriterOptions& options)
    : impl_(std::make_unique<Impl>()) {
  if (options.storage != "mcap" && options.storage != "sqlite3")
    throw InputError(file_error(folder, "storage '" + options.storage + "' (mcap or sqlite3)"));
  const bool mcap = options.storage == "mcap";
  if (options.compression != "none" && options.compression != "zstd" &&
      !(mcap && options.compression == "lz4"))
    throw InputError(file_error(folder, "compression '" + options.compression + "' (" +
                                            (mcap ? "none, lz4 or zstd" : "none or zstd") +
                                            " for " + options.storage + ")"));
  std::error_code ec;
  if (fs::exists(folder, ec))
    throw InputError(file_error(folder, "already exists (a ROS 2 recording is a new folder)"));
  if (!fs::create_directories(folder, ec))
    throw InputError(file_error(folder, "cannot create the folder: " + ec.message()));
  impl_->folder = folder;
  impl_->options = options;
  impl_->file_name = fs::path(folder).lexically_normal().filename().string();
  if (impl_->file_name.empty())
    impl_->file_name = fs::path(folder).parent_path().filename().string();
  impl_->file_name += mcap ? "_0.mcap" : "_0.db3";
  const std::string file = (fs::path(folder) / impl_->file_name).string();
  impl_->storage =
      mcap ? detail::make_mcap_writer(file, options) : detail::make_sqlite_writer(file, options);
}

RecordingWriter::~RecordingWriter() = default;

std::uint32_t RecordingWriter::add_topic(const std::string& name, const std::string& type,
                                         const std::string& definition) {
  const auto id = static_cast<std::uint32_t>(impl_->topics.size());
  detail::WriterTopic t{name, type, definition, default_qos_profile(), ""};
  impl_->storage->add_topic(id, t);
  impl_->topics.push_back(t);
  impl_->counts.push_back(0);
  return id;
}

void RecordingWriter::write(std::uint32_t topic, std::int64_t timestamp_ns,
                            const std::vector<std::uint8_t>& cdr) {
  impl_->storage->write(topic, timestamp_ns, cdr);
  ++impl_->counts.at(topic);
  impl_->first = std::min(impl_->first, timestamp_ns);
  impl_->last = std::max(impl_->last, timestamp_ns);
}

void RecordingWriter::close() {
  if (impl_->closed) return;
  impl_->closed = true;
  impl_->storage->close(impl_->metadata());
  const std::string yaml = impl_->metadata_file();
  impl_->storage.reset();
  const std::string meta = (fs::path(impl_->folder) / "metadata.yaml").string();
  std::ofstream out(meta, std::ios::binary);
  out << yaml;
  if (!out) throw InputError(file_error(meta, "cannot write"));
}

}  // namespace mcslam::rosbag2
