// MCAP (https://mcap.dev/spec), read and written from the specification: magic, records
// (opcode, uint64 length, body), chunks (uncompressed, lz4 frames or zstd) with a CRC-32 of
// their records, message indexes, the summary section (schemas, channels, statistics, chunk
// indexes, summary offsets) and the footer.
#include <fcntl.h>
#include <lz4frame.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zstd.h>

#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <mutex>

#include "crc32.hpp"
#include "mcslam/core/error.hpp"
#include "storage.hpp"

namespace mcslam::rosbag2::detail {
namespace {

constexpr std::uint8_t kMagic[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};

enum Op : std::uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kStatistics = 0x0B,
  kMetadata = 0x0C,
  kMetadataIndex = 0x0D,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

/// A record's fields, little-endian; running past the end throws Short.
struct Short {
  const char* what;
};

struct Cursor {
  const std::uint8_t* p;
  std::size_t n, at = 0;
  void need(std::size_t k, const char* what) const {
    if (k > n - at) throw Short{what};
  }
  template <typename T>
  T get(const char* what) {
    need(sizeof(T), what);
    T v;
    std::memcpy(&v, p + at, sizeof(T));
    at += sizeof(T);
    return v;
  }
  std::uint8_t u8(const char* w) { return get<std::uint8_t>(w); }
  std::uint16_t u16(const char* w) { return get<std::uint16_t>(w); }
  std::uint32_t u32(const char* w) { return get<std::uint32_t>(w); }
  std::uint64_t u64(const char* w) { return get<std::uint64_t>(w); }
  std::string str(const char* w) {
    const std::uint32_t k = u32(w);
    need(k, w);
    std::string s(reinterpret_cast<const char*>(p + at), k);
    at += k;
    return s;
  }
  std::map<std::string, std::string> str_map(const char* w) {
    const std::uint32_t k = u32(w);
    need(k, w);
    Cursor inner{p + at, k};
    at += k;
    std::map<std::string, std::string> m;
    while (inner.at < inner.n) {
      std::string key = inner.str(w);
      m[key] = inner.str(w);
    }
    return m;
  }
};

/// The file, mapped read-only.
struct Mapping {
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
  Mapping() = default;
  Mapping(const Mapping&) = delete;
  Mapping& operator=(const Mapping&) = delete;
  ~Mapping() {
    if (data && size) ::munmap(const_cast<std::uint8_t*>(data), size);
  }
};

std::string hex_offset(std::uint64_t at) { return "offset " + std::to_string(at); }

/// Message counts of a scan: per topic, in all, and the first and last log times.
struct ScanTally {
  std::vector<std::uint64_t> counts;
  std::uint64_t total = 0;
  std::int64_t first = std::numeric_limits<std::int64_t>::max();
  std::int64_t last = std::numeric_limits<std::int64_t>::min();
};

/// What a scan does with each message: counts it, and passes it to `fn` when its topic is wanted.
struct ScanVisit {
  const std::vector<bool>& wanted;
  const StorageFile::Visitor& fn;
  ScanTally& tally;
};

class McapFile : public StorageFile {
 public:
  explicit McapFile(const std::string& path) : path_(path) { map(); }

  void open() {
    const std::uint8_t* d = map_.data;
    const std::size_t n = map_.size;
    if (n < 8 || std::memcmp(d, kMagic, 8) != 0)
      fail("not an MCAP file (bad magic: it does not start with \\x89MCAP0\\r\\n)");
    if (n < 8 + 9 + 20 + 8 || std::memcmp(d + n - 8, kMagic, 8) != 0)
      fail("truncated MCAP file (no closing magic at the end; " + std::to_string(n) +
           " bytes): the recording was cut off or not closed");
    const std::size_t footer = n - 8 - 29;
    if (d[footer] != kFooter) fail("corrupt MCAP file: no footer record before the closing magic");
    std::uint64_t len, summary_start, summary_offset_start;
    std::uint32_t summary_crc;
    std::memcpy(&len, d + footer + 1, 8);
    std::memcpy(&summary_start, d + footer + 9, 8);
    std::memcpy(&summary_offset_start, d + footer + 17, 8);
    std::memcpy(&summary_crc, d + footer + 25, 4);
    if (len != 20) fail("corrupt MCAP footer (length " + std::to_string(len) + ", expected 20)");
    bool have_listing = false;
    if (summary_start != 0) {
      if (summary_start < 8 || summary_start > footer)
        fail("corrupt MCAP footer: summary start " + std::to_string(summary_start) +
             " is outside the file");
      if (summary_crc != 0) {
        const std::uint32_t crc =
            crc32(0, d + summary_start, footer + 1 + 8 + 8 + 8 - summary_start);
        if (crc != summary_crc)
          fail("corrupt MCAP file: summary CRC mismatch (stored " + std::to_string(summary_crc) +
               ", computed " + std::to_string(crc) + ")");
      }
      have_listing = read_summary(summary_start, footer);
    }
    if (!have_listing) {
      // No summary (or no statistics): count by reading the whole file.
      for (auto& t : topics) t.count = 0;
      message_count = 0;
      counting_ = true;
      scan({}, {});
      counting_ = false;
    }
  }

  void scan(const std::vector<bool>& wanted, const Visitor& fn) override {
    ScanTally tally;
    tally.counts.assign(topics.size(), 0);
    const ScanVisit visit{wanted, fn, tally};
    chunks_.clear();
    const std::uint8_t* d = map_.data;
    const std::size_t n = map_.size - 8;
    std::size_t at = 8;
    bool header = false, footer = false;
    std::vector<std::uint8_t> buffer;
    while (at < n && !footer) {
      if (n - at < 9)
        fail("truncated MCAP file: a record header at " + hex_offset(at) + " runs past the end");
      const std::uint8_t op = d[at];
      std::uint64_t len;
      std::memcpy(&len, d + at + 1, 8);
      if (len > n - at - 9)
        fail("truncated or corrupt MCAP file: record (opcode " + std::to_string(op) + ") at " +
             hex_offset(at) + " is " + std::to_string(len) + " bytes, past the end of the file");
      Cursor c{d + at + 9, static_cast<std::size_t>(len)};
      const std::size_t record_at = at;
      at += 9 + len;
      if (!header && op != kHeader)
        fail("corrupt MCAP file: the first record is not a Header (opcode " + std::to_string(op) +
             ")");
      try {
        switch (op) {
          case kHeader: {
            header = true;
            const std::string profile = c.str("header profile");
            (void)profile;
            break;
          }
          case kFooter:
            footer = true;
            break;
          case kSchema:
            add_schema(c);
            break;
          case kChannel:
            add_channel(c);
            break;
          case kMessage:
            scan_message(c, -1, record_at + 9, record_at, visit);
            break;
          case kChunk:
            scan_chunk(record_at, buffer, visit);
            break;
          default:
            break;  // indexes, attachments, metadata, statistics, data end
        }
      } catch (const Short& s) {
        fail("corrupt MCAP record (opcode " + std::to_string(op) + ") at " + hex_offset(record_at) +
             ": too short for its " + s.what);
      }
    }
    if (!footer) fail("truncated MCAP file: no footer record");
    tally.counts.resize(topics.size(), 0);
    for (std::size_t t = 0; t < topics.size() && t < tally.counts.size(); ++t)
      topics[t].count = tally.counts[t];
    message_count = tally.total;
    start_ns = tally.total ? tally.first : 0;
    end_ns = tally.total ? tally.last : 0;
  }

  Payload fetch(std::int64_t key, std::uint64_t offset, std::uint64_t size) override {
    if (key < 0) {
      if (offset + size > map_.size) fail("message outside the file");
      return {map_.data + offset, size, nullptr};
    }
    std::lock_guard lock(mutex_);
    if (key != cached_key_) {
      auto buffer = std::make_shared<std::vector<std::uint8_t>>();
      const auto [records, n] =
          chunk_records(chunks_.at(static_cast<std::size_t>(key)), *buffer, false);
      if (records != buffer->data()) {
        if (offset + size > n) fail("message outside its chunk");
        return {records + offset, size, nullptr};  // an uncompressed chunk: in the mapping
      }
      cached_ = std::move(buffer);
      cached_key_ = key;
    }
    if (offset + size > cached_->size()) fail("message outside its chunk");
    return {cached_->data() + offset, size, cached_};
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(file_error(path_, what));
  }

  void map() {
    const int fd = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) fail(std::string("cannot open: ") + std::strerror(errno));
    struct stat st {};
    if (::fstat(fd, &st) != 0 || st.st_size == 0) {
      ::close(fd);
      fail("empty or unreadable file (not an MCAP recording)");
    }
    void* p = ::mmap(nullptr, static_cast<std::size_t>(st.st_size), PROT_READ, MAP_PRIVATE, fd, 0);
    ::close(fd);
    if (p == MAP_FAILED) fail(std::string("cannot map the file: ") + std::strerror(errno));
    ::madvise(p, static_cast<std::size_t>(st.st_size), MADV_SEQUENTIAL);
    map_.data = static_cast<const std::uint8_t*>(p);
    map_.size = static_cast<std::size_t>(st.st_size);
  }

  /// A Message record's body at `c` (chunk `key`, -1 outside chunks; its payload at `base` + the
  /// cursor's position in the file or the chunk): counted, and visited when its topic is wanted.
  /// `record_at` (the record's or its chunk's offset) names it in errors.
  void scan_message(Cursor& c, std::int64_t key, std::uint64_t base, std::uint64_t record_at,
                    const ScanVisit& visit) {
    ScanTally& tally = visit.tally;
    const std::uint16_t channel = c.u16("message channel id");
    c.u32("message sequence");
    const std::uint64_t log_time = c.u64("message log time");
    c.u64("message publish time");
    const auto it = channel_topic_.find(channel);
    if (it == channel_topic_.end())
      fail("corrupt MCAP file: message at " + hex_offset(record_at) + " on channel " +
           std::to_string(channel) + ", which no Channel record defines");
    const std::uint32_t topic = it->second;
    const auto ts = static_cast<std::int64_t>(log_time);
    if (topic >= tally.counts.size()) tally.counts.resize(topics.size(), 0);  // defined late
    ++tally.counts[topic];
    ++tally.total;
    tally.first = std::min(tally.first, ts);
    tally.last = std::max(tally.last, ts);
    if (visit.fn && topic < visit.wanted.size() && visit.wanted[topic])
      visit.fn(topic, ts, key, base + c.at, c.p + c.at, c.n - c.at);
  }

  /// The records of the Chunk record at `record_at` (decompressed into `buffer`): its schemas,
  /// channels and messages.
  void scan_chunk(std::size_t record_at, std::vector<std::uint8_t>& buffer,
                  const ScanVisit& visit) {
    const std::int64_t key = static_cast<std::int64_t>(chunks_.size());
    chunks_.push_back(record_at);
    const auto [records, size] = chunk_records(record_at, buffer);
    std::size_t k = 0;
    while (k < size) {
      if (size - k < 9)
        fail("corrupt MCAP chunk at " + hex_offset(record_at) +
             ": a record header runs past the chunk's end");
      const std::uint8_t inner_op = records[k];
      std::uint64_t inner_len;
      std::memcpy(&inner_len, records + k + 1, 8);
      if (inner_len > size - k - 9)
        fail("corrupt MCAP chunk at " + hex_offset(record_at) + ": record (opcode " +
             std::to_string(inner_op) + ") runs past the chunk's end");
      Cursor ic{records + k + 9, static_cast<std::size_t>(inner_len)};
      if (inner_op == kSchema) add_schema(ic);
      if (inner_op == kChannel) add_channel(ic);
      if (inner_op == kMessage) scan_message(ic, key, k + 9, record_at, visit);
      k += 9 + inner_len;
    }
  }

  void add_schema(Cursor& c) {
    const std::uint16_t id = c.u16("schema id");
    schemas_[id] = c.str("schema name");
  }

  void add_channel(Cursor& c) {
    const std::uint16_t id = c.u16("channel id");
    const std::uint16_t schema = c.u16("channel schema id");
    FileTopic t;
    t.name = c.str("channel topic");
    t.format = c.str("channel message encoding");
    const auto meta = c.str_map("channel metadata");
    if (auto it = meta.find("offered_qos_profiles"); it != meta.end()) t.qos = it->second;
    if (auto it = meta.find("topic_type_hash"); it != meta.end()) t.hash = it->second;
    if (schema != 0) {
      const auto it = schemas_.find(schema);
      if (it == schemas_.end())
        fail("corrupt MCAP file: channel '" + t.name + "' names schema " + std::to_string(schema) +
             ", which no Schema record defines");
      t.type = it->second;
    }
    if (channel_topic_.count(id)) return;
    for (std::uint32_t k = 0; k < topics.size(); ++k)
      if (topics[k].name == t.name && topics[k].type == t.type) {
        channel_topic_[id] = k;
        return;
      }
    channel_topic_[id] = static_cast<std::uint32_t>(topics.size());
    topics.push_back(std::move(t));
  }

  /// Reads the summary: schemas, channels and, when there are statistics, the counts.
  bool read_summary(std::size_t start, std::size_t end) {
    const std::uint8_t* d = map_.data;
    std::size_t at = start;
    bool statistics = false;
    std::map<std::uint16_t, std::uint64_t> channel_counts;
    std::uint64_t first = 0, last = 0, total = 0;
    while (at < end) {
      if (end - at < 9) fail("corrupt MCAP summary: a record header runs past its end");
      const std::uint8_t op = d[at];
      std::uint64_t len;
      std::memcpy(&len, d + at + 1, 8);
      if (len > end - at - 9)
        fail("corrupt MCAP summary: record (opcode " + std::to_string(op) + ") at " +
             hex_offset(at) + " runs past its end");
      Cursor c{d + at + 9, static_cast<std::size_t>(len)};
      try {
        if (op == kSchema) add_schema(c);
        if (op == kChannel) add_channel(c);
        if (op == kStatistics) {
          statistics = true;
          total = c.u64("message count");
          c.u16("schema count");
          c.u32("channel count");
          c.u32("attachment count");
          c.u32("metadata count");
          c.u32("chunk count");
          first = c.u64("message start time");
          last = c.u64("message end time");
          const std::uint32_t k = c.u32("channel message counts");
          c.need(k, "channel message counts");
          Cursor m{c.p + c.at, k};
          while (m.at < m.n) {
            const std::uint16_t ch = m.u16("channel message counts");
            channel_counts[ch] += m.u64("channel message counts");
          }
        }
      } catch (const Short& s) {
        fail("corrupt MCAP summary record (opcode " + std::to_string(op) + ") at " +
             hex_offset(at) + ": too short for its " + s.what);
      }
      at += 9 + len;
    }
    if (!statistics) return false;
    for (auto& t : topics) t.count = 0;
    for (const auto& [ch, count] : channel_counts) {
      const auto it = channel_topic_.find(ch);
      if (it != channel_topic_.end()) topics[it->second].count += count;
    }
    message_count = total;
    start_ns = static_cast<std::int64_t>(first);
    end_ns = static_cast<std::int64_t>(last);
    return true;
  }

  /// A chunk's records: in the mapping when uncompressed, else decompressed into `buffer`.
  /// Checks the sizes and the CRC.
  std::pair<const std::uint8_t*, std::size_t> chunk_records(std::size_t record_at,
                                                            std::vector<std::uint8_t>& buffer,
                                                            bool check_crc = true) {
    std::uint64_t len;
    std::memcpy(&len, map_.data + record_at + 1, 8);
    Cursor c{map_.data + record_at + 9, static_cast<std::size_t>(len)};
    std::uint64_t uncompressed_size = 0, records_size = 0;
    std::uint32_t crc = 0;
    std::string compression;
    try {
      c.u64("chunk start time");
      c.u64("chunk end time");
      uncompressed_size = c.u64("chunk uncompressed size");
      crc = c.u32("chunk CRC");
      compression = c.str("chunk compression");
      records_size = c.u64("chunk records length");
      c.need(records_size, "chunk records");
    } catch (const Short& s) {
      fail("corrupt MCAP chunk at " + hex_offset(record_at) + ": too short for its " + s.what);
    }
    const std::uint8_t* src = c.p + c.at;
    const std::string where = "MCAP chunk at " + hex_offset(record_at);
    const std::uint8_t* records = src;
    if (compression.empty()) {
      if (records_size != uncompressed_size)
        fail("corrupt " + where + ": uncompressed, but " + std::to_string(records_size) +
             " bytes where its header says " + std::to_string(uncompressed_size));
    } else {
      // No codec expands more than 65536 times (zstd's RLE blocks come nearest): a larger
      // claim is a corrupt header, not a reason to allocate it.
      if (uncompressed_size > records_size * 65536 + (1u << 20))
        fail("corrupt " + where + ": claims " + std::to_string(uncompressed_size) +
             " bytes uncompressed");
      buffer.resize(uncompressed_size);
      if (compression == "zstd") {
        const std::size_t got = ZSTD_decompress(buffer.data(), buffer.size(), src, records_size);
        if (ZSTD_isError(got))
          fail("corrupt " + where + ": zstd cannot decompress it (" + ZSTD_getErrorName(got) + ")");
        if (got != uncompressed_size)
          fail("corrupt " + where + ": " + std::to_string(got) +
               " bytes decompressed where its header says " + std::to_string(uncompressed_size));
      } else if (compression == "lz4") {
        LZ4F_dctx* ctx = nullptr;
        if (LZ4F_isError(LZ4F_createDecompressionContext(&ctx, LZ4F_VERSION)))
          fail("lz4: cannot create a decompression context");
        std::size_t in_at = 0, out_at = 0;
        std::size_t status = 1;
        while (status != 0 && in_at < records_size) {
          std::size_t in = records_size - in_at, out = buffer.size() - out_at;
          status = LZ4F_decompress(ctx, buffer.data() + out_at, &out, src + in_at, &in, nullptr);
          if (LZ4F_isError(status)) {
            const std::string e = LZ4F_getErrorName(status);
            LZ4F_freeDecompressionContext(ctx);
            fail("corrupt " + where + ": lz4 cannot decompress it (" + e + ")");
          }
          in_at += in;
          out_at += out;
          if (in == 0 && out == 0) break;
        }
        LZ4F_freeDecompressionContext(ctx);
        if (status != 0 || out_at != uncompressed_size)
          fail("corrupt " + where + ": lz4 gave " + std::to_string(out_at) +
               " bytes where its header says " + std::to_string(uncompressed_size) +
               (status != 0 ? " (the frame is incomplete)" : ""));
      } else {
        fail(where + ": unknown compression '" + compression + "' (lz4, zstd or none)");
      }
      records = buffer.data();
    }
    if (crc != 0 && check_crc) {
      const std::uint32_t got = crc32(0, records, uncompressed_size);
      if (got != crc)
        fail("corrupt " + where + ": CRC mismatch (stored " + std::to_string(crc) + ", computed " +
             std::to_string(got) + ")");
    }
    return {records, static_cast<std::size_t>(uncompressed_size)};
  }

  std::string path_;
  Mapping map_;
  std::map<std::uint16_t, std::string> schemas_;
  std::map<std::uint16_t, std::uint32_t> channel_topic_;
  std::vector<std::size_t> chunks_;  // file offset of each chunk record, in file order
  bool counting_ = false;
  std::mutex mutex_;
  std::int64_t cached_key_ = -1;
  std::shared_ptr<std::vector<std::uint8_t>> cached_;
};

// ---- writer ----

void put_u16(std::vector<std::uint8_t>& o, std::uint16_t v) {
  o.insert(o.end(), reinterpret_cast<std::uint8_t*>(&v), reinterpret_cast<std::uint8_t*>(&v) + 2);
}
void put_u32(std::vector<std::uint8_t>& o, std::uint32_t v) {
  o.insert(o.end(), reinterpret_cast<std::uint8_t*>(&v), reinterpret_cast<std::uint8_t*>(&v) + 4);
}
void put_u64(std::vector<std::uint8_t>& o, std::uint64_t v) {
  o.insert(o.end(), reinterpret_cast<std::uint8_t*>(&v), reinterpret_cast<std::uint8_t*>(&v) + 8);
}
void put_str(std::vector<std::uint8_t>& o, const std::string& s) {
  put_u32(o, static_cast<std::uint32_t>(s.size()));
  o.insert(o.end(), s.begin(), s.end());
}
/// Starts a record; returns where its length goes (filled by end_record).
std::size_t begin_record(std::vector<std::uint8_t>& o, std::uint8_t op) {
  o.push_back(op);
  put_u64(o, 0);
  return o.size() - 8;
}
void end_record(std::vector<std::uint8_t>& o, std::size_t len_at) {
  const std::uint64_t len = o.size() - len_at - 8;
  std::memcpy(o.data() + len_at, &len, 8);
}

class McapWriter : public StorageWriter {
 public:
  McapWriter(const std::string& path, const WriterOptions& o) : path_(path), options_(o) {
    file_ = std::fopen(path.c_str(), "wb");
    if (!file_)
      throw InputError(file_error(path, std::string("cannot write: ") + std::strerror(errno)));
    std::vector<std::uint8_t> out(kMagic, kMagic + 8);
    const std::size_t r = begin_record(out, kHeader);
    put_str(out, "ros2");
    put_str(out, "mcslam");
    end_record(out, r);
    emit(out);
  }
  ~McapWriter() override {
    if (file_) std::fclose(file_);
  }

  void add_topic(std::uint32_t id, const WriterTopic& t) override {
    flush_chunk();
    std::vector<std::uint8_t> out;
    const std::size_t s = begin_record(out, kSchema);
    put_u16(out, static_cast<std::uint16_t>(id + 1));
    put_str(out, t.type);
    put_str(out, "ros2msg");
    put_str(out, t.definition);
    end_record(out, s);
    const std::size_t c = begin_record(out, kChannel);
    put_u16(out, static_cast<std::uint16_t>(id));
    put_u16(out, static_cast<std::uint16_t>(id + 1));
    put_str(out, t.name);
    put_str(out, "cdr");
    std::vector<std::uint8_t> meta;
    put_str(meta, "offered_qos_profiles");
    put_str(meta, t.qos);
    put_u32(out, static_cast<std::uint32_t>(meta.size()));
    out.insert(out.end(), meta.begin(), meta.end());
    end_record(out, c);
    schemas_.insert(schemas_.end(), out.begin(), out.begin() + static_cast<std::ptrdiff_t>(c - 1));
    channel_records_.insert(channel_records_.end(),
                            out.begin() + static_cast<std::ptrdiff_t>(c - 1), out.end());
    emit(out);
    if (counts_.size() <= id) counts_.resize(id + 1, 0);
    ++channels_;
  }

  void write(std::uint32_t id, std::int64_t timestamp,
             const std::vector<std::uint8_t>& data) override {
    std::vector<std::uint8_t>& out = options_.chunked ? chunk_ : direct_;
    const std::uint64_t at = out.size();
    out.push_back(kMessage);
    put_u64(out, 2 + 4 + 8 + 8 + data.size());
    put_u16(out, static_cast<std::uint16_t>(id));
    put_u32(out, counts_[id] & 0xFFFFFFFFu);
    put_u64(out, static_cast<std::uint64_t>(timestamp));
    put_u64(out, static_cast<std::uint64_t>(timestamp));
    out.insert(out.end(), data.begin(), data.end());
    ++counts_[id];
    ++total_;
    first_ = std::min(first_, timestamp);
    last_ = std::max(last_, timestamp);
    if (options_.chunked) {
      chunk_first_ = std::min(chunk_first_, timestamp);
      chunk_last_ = std::max(chunk_last_, timestamp);
      index_[static_cast<std::uint16_t>(id)].push_back({static_cast<std::uint64_t>(timestamp), at});
      if (chunk_.size() >= options_.chunk_size) flush_chunk();
    } else {
      emit(direct_);
      direct_.clear();
    }
  }

  void close(const std::string& metadata_yaml) override {
    flush_chunk();
    std::vector<std::uint8_t> out;
    // As rosbag2's mcap plugin: the bag's metadata in a Metadata record named "rosbag2".
    const std::uint64_t metadata_at = position_;
    const std::size_t md = begin_record(out, kMetadata);
    put_str(out, "rosbag2");
    std::vector<std::uint8_t> map;
    put_str(map, "ROS_DISTRO");
    put_str(map, "");
    put_str(map, "serialized_metadata");
    put_str(map, metadata_yaml);
    put_u32(out, static_cast<std::uint32_t>(map.size()));
    out.insert(out.end(), map.begin(), map.end());
    end_record(out, md);
    const std::uint64_t metadata_length = out.size();
    emit(out);
    out.clear();
    const std::size_t de = begin_record(out, kDataEnd);
    put_u32(out, 0);  // data section CRC: not computed
    end_record(out, de);
    emit(out);
    out.clear();
    std::uint64_t summary_start = 0, summary_offset_start = 0;
    std::vector<std::uint8_t> summary;
    if (options_.summary) {
      summary_start = position_;
      struct Group {
        std::uint8_t op;
        std::uint64_t start, length;
      };
      std::vector<Group> groups;
      // Schemas and channels as written in the data section (one of each per topic).
      summary.insert(summary.end(), schemas_.begin(), schemas_.end());
      groups.push_back({kSchema, position_, summary.size()});
      summary.insert(summary.end(), channel_records_.begin(), channel_records_.end());
      groups.push_back({kChannel, position_ + schemas_.size(), channel_records_.size()});
      const std::size_t stats_at = summary.size();
      const std::size_t st = begin_record(summary, kStatistics);
      put_u64(summary, total_);
      put_u16(summary, static_cast<std::uint16_t>(channels_));
      put_u32(summary, channels_);
      put_u32(summary, 0);  // attachments
      put_u32(summary, 1);  // metadata
      put_u32(summary, static_cast<std::uint32_t>(chunk_indexes_.size()));
      put_u64(summary, total_ ? static_cast<std::uint64_t>(first_) : 0);
      put_u64(summary, total_ ? static_cast<std::uint64_t>(last_) : 0);
      put_u32(summary, static_cast<std::uint32_t>(counts_.size() * 10));
      for (std::size_t ch = 0; ch < counts_.size(); ++ch) {
        put_u16(summary, static_cast<std::uint16_t>(ch));
        put_u64(summary, counts_[ch]);
      }
      end_record(summary, st);
      groups.push_back({kStatistics, position_ + stats_at, summary.size() - stats_at});
      const std::size_t ci_at = summary.size();
      summary.insert(summary.end(), chunk_indexes_.begin(), chunk_indexes_.end());
      if (!chunk_indexes_.empty())
        groups.push_back({kChunkIndex, position_ + ci_at, summary.size() - ci_at});
      const std::size_t mi_at = summary.size();
      const std::size_t mi = begin_record(summary, kMetadataIndex);
      put_u64(summary, metadata_at);
      put_u64(summary, metadata_length);
      put_str(summary, "rosbag2");
      end_record(summary, mi);
      groups.push_back({kMetadataIndex, position_ + mi_at, summary.size() - mi_at});
      summary_offset_start = position_ + summary.size();
      for (const Group& g : groups) {
        const std::size_t so = begin_record(summary, kSummaryOffset);
        summary.push_back(g.op);
        put_u64(summary, g.start);
        put_u64(summary, g.length);
        end_record(summary, so);
      }
    }
    summary.push_back(kFooter);
    put_u64(summary, 20);
    put_u64(summary, summary_start);
    put_u64(summary, summary_offset_start);
    const std::uint32_t crc = options_.summary ? crc32(0, summary.data(), summary.size()) : 0;
    put_u32(summary, crc);
    summary.insert(summary.end(), kMagic, kMagic + 8);
    emit(summary);
    if (std::fclose(file_) != 0) {
      file_ = nullptr;
      throw InputError(file_error(path_, "cannot write (disk full?)"));
    }
    file_ = nullptr;
  }

 private:
  void emit(const std::vector<std::uint8_t>& bytes) {
    if (!bytes.empty() && std::fwrite(bytes.data(), 1, bytes.size(), file_) != bytes.size())
      throw InputError(file_error(path_, std::string("cannot write: ") + std::strerror(errno)));
    position_ += bytes.size();
  }

  void flush_chunk() {
    if (chunk_.empty()) return;
    const std::uint32_t crc = crc32(0, chunk_.data(), chunk_.size());
    std::vector<std::uint8_t> compressed;
    std::string compression = options_.compression == "none" ? "" : options_.compression;
    const std::uint8_t* records = chunk_.data();
    std::size_t records_size = chunk_.size();
    if (compression == "zstd") {
      compressed = zstd_compress(chunk_.data(), chunk_.size(), 1);
    } else if (compression == "lz4") {
      compressed.resize(LZ4F_compressFrameBound(chunk_.size(), nullptr));
      const std::size_t n = LZ4F_compressFrame(compressed.data(), compressed.size(), chunk_.data(),
                                               chunk_.size(), nullptr);
      if (LZ4F_isError(n)) throw InputError(file_error(path_, "lz4 compression failed"));
      compressed.resize(n);
    }
    if (!compression.empty()) {
      records = compressed.data();
      records_size = compressed.size();
    }
    const std::uint64_t chunk_start = position_;
    std::vector<std::uint8_t> out;
    out.push_back(kChunk);
    put_u64(out, 8 + 8 + 8 + 4 + 4 + compression.size() + 8 + records_size);
    put_u64(out, static_cast<std::uint64_t>(chunk_first_));
    put_u64(out, static_cast<std::uint64_t>(chunk_last_));
    put_u64(out, chunk_.size());
    put_u32(out, crc);
    put_str(out, compression);
    put_u64(out, records_size);
    emit(out);
    emit_raw(records, records_size);
    const std::uint64_t chunk_length = position_ - chunk_start;
    std::vector<std::uint8_t> indexes;
    std::vector<std::pair<std::uint16_t, std::uint64_t>> index_offsets;
    for (const auto& [channel, entries] : index_) {
      index_offsets.push_back({channel, position_ + indexes.size()});
      const std::size_t r = begin_record(indexes, kMessageIndex);
      put_u16(indexes, channel);
      put_u32(indexes, static_cast<std::uint32_t>(entries.size() * 16));
      for (const auto& [ts, offset] : entries) {
        put_u64(indexes, ts);
        put_u64(indexes, offset);
      }
      end_record(indexes, r);
    }
    emit(indexes);
    const std::size_t ci = begin_record(chunk_indexes_, kChunkIndex);
    put_u64(chunk_indexes_, static_cast<std::uint64_t>(chunk_first_));
    put_u64(chunk_indexes_, static_cast<std::uint64_t>(chunk_last_));
    put_u64(chunk_indexes_, chunk_start);
    put_u64(chunk_indexes_, chunk_length);
    put_u32(chunk_indexes_, static_cast<std::uint32_t>(index_offsets.size() * 10));
    for (const auto& [channel, offset] : index_offsets) {
      put_u16(chunk_indexes_, channel);
      put_u64(chunk_indexes_, offset);
    }
    put_u64(chunk_indexes_, indexes.size());
    put_str(chunk_indexes_, compression);
    put_u64(chunk_indexes_, records_size);
    put_u64(chunk_indexes_, chunk_.size());
    end_record(chunk_indexes_, ci);
    chunk_.clear();
    index_.clear();
    chunk_first_ = std::numeric_limits<std::int64_t>::max();
    chunk_last_ = std::numeric_limits<std::int64_t>::min();
  }

  void emit_raw(const std::uint8_t* p, std::size_t n) {
    if (n && std::fwrite(p, 1, n, file_) != n)
      throw InputError(file_error(path_, std::string("cannot write: ") + std::strerror(errno)));
    position_ += n;
  }

  std::string path_;
  WriterOptions options_;
  std::FILE* file_ = nullptr;
  std::uint64_t position_ = 0;
  std::vector<std::uint8_t> chunk_, direct_, chunk_indexes_, schemas_, channel_records_;
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>> index_;
  std::vector<std::uint64_t> counts_;
  std::uint32_t channels_ = 0;
  std::uint64_t total_ = 0;
  std::int64_t first_ = std::numeric_limits<std::int64_t>::max();
  std::int64_t last_ = std::numeric_limits<std::int64_t>::min();
  std::int64_t chunk_first_ = std::numeric_limits<std::int64_t>::max();
  std::int64_t chunk_last_ = std::numeric_limits<std::int64_t>::min();
};

}  // namespace

bool is_mcap_file(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return false;
  std::uint8_t head[8] = {};
  const bool ok = std::fread(head, 1, 8, f) == 8 && std::memcmp(head, kMagic, 8) == 0;
  std::fclose(f);
  return ok;
}

std::unique_ptr<StorageFile> open_mcap(const std::string& path) {
  auto file = std::make_unique<McapFile>(path);
  file->open();
  return file;
}

std::unique_ptr<StorageWriter> make_mcap_writer(const std::string& path, const WriterOptions& o) {
  return std::make_unique<McapWriter>(path, o);
}

std::vector<std::uint8_t> zstd_decompress(const std::uint8_t* data, std::size_t size) {
  const unsigned long long n = ZSTD_getFrameContentSize(data, size);
  if (n == ZSTD_CONTENTSIZE_ERROR) throw std::runtime_error("not a zstd frame");
  if (n != ZSTD_CONTENTSIZE_UNKNOWN) {
    if (n > size * 65536ull + (1u << 20))
      throw std::runtime_error("zstd frame claims " + std::to_string(n) + " bytes");
    std::vector<std::uint8_t> out(n);
    const std::size_t got = ZSTD_decompress(out.data(), out.size(), data, size);
    if (ZSTD_isError(got)) throw std::runtime_error(ZSTD_getErrorName(got));
    out.resize(got);
    return out;
  }
  // Streamed frames without a content size.
  std::vector<std::uint8_t> out;
  ZSTD_DStream* ds = ZSTD_createDStream();
  ZSTD_inBuffer in{data, size, 0};
  std::vector<std::uint8_t> block(ZSTD_DStreamOutSize());
  std::size_t ret = 1;
  while (in.pos < in.size) {
    ZSTD_outBuffer ob{block.data(), block.size(), 0};
    ret = ZSTD_decompressStream(ds, &ob, &in);
    if (ZSTD_isError(ret)) {
      ZSTD_freeDStream(ds);
      throw std::runtime_error(ZSTD_getErrorName(ret));
    }
    out.insert(out.end(), block.data(), block.data() + ob.pos);
    if (ob.pos == 0 && ret != 0 && in.pos == in.size) break;
  }
  ZSTD_freeDStream(ds);
  if (ret != 0) throw std::runtime_error("truncated zstd frame");
  return out;
}

std::vector<std::uint8_t> zstd_compress(const std::uint8_t* data, std::size_t size, int level) {
  std::vector<std::uint8_t> out(ZSTD_compressBound(size));
  const std::size_t n = ZSTD_compress(out.data(), out.size(), data, size, level);
  if (ZSTD_isError(n)) throw std::runtime_error(ZSTD_getErrorName(n));
  out.resize(n);
  return out;
}

}  // namespace mcslam::rosbag2::detail
