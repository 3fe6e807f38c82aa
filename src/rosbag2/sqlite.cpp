// rosbag2's sqlite3 storage through libsqlite3: tables topics(id, name, type,
// serialization_format[, offered_qos_profiles][, type_description_hash]) and messages(id,
// topic_id, timestamp, data); from schema version 3/4 also schema, metadata and
// message_definitions.
#include <sqlite3.h>

#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <mutex>
#include <set>

#include "mcslam/core/error.hpp"
#include "storage.hpp"

namespace mcslam::rosbag2::detail {
namespace {

class Statement {
 public:
  Statement(sqlite3* db, const std::string& sql, const std::string& path) : path_(path) {
    if (sqlite3_prepare_v2(db, sql.c_str(), -1, &stmt_, nullptr) != SQLITE_OK) {
      const std::string e = sqlite3_errmsg(db);
      throw InputError(file_error(path, "sqlite3: " + e + " (in: " + sql + ")"));
    }
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  /// True while there is a row; throws for an error (a corrupt database).
  bool step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    throw InputError(file_error(path_, std::string("sqlite3: ") +
                                           sqlite3_errmsg(sqlite3_db_handle(stmt_)) +
                                           " (truncated or corrupt database?)"));
  }
  void reset() { sqlite3_reset(stmt_); }
  sqlite3_stmt* get() { return stmt_; }
  std::string text(int col) {
    const unsigned char* t = sqlite3_column_text(stmt_, col);
    return t ? reinterpret_cast<const char*>(t) : "";
  }
  std::int64_t i64(int col) { return sqlite3_column_int64(stmt_, col); }

 private:
  sqlite3_stmt* stmt_ = nullptr;
  std::string path_;
};

class SqliteFile : public StorageFile {
 public:
  explicit SqliteFile(const std::string& path) : path_(path) {
    if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
      const std::string e = db_ ? sqlite3_errmsg(db_) : "out of memory";
      sqlite3_close_v2(db_);
      db_ = nullptr;
      throw InputError(file_error(path, "cannot open the sqlite3 database: " + e));
    }
    try {
      list();
    } catch (...) {
      sqlite3_close_v2(db_);
      db_ = nullptr;
      throw;
    }
  }
  ~SqliteFile() override {
    fetch_.reset();  // statements first: sqlite3_close fails while one is alive
    sqlite3_close_v2(db_);
  }

  void scan(const std::vector<bool>& wanted, const Visitor& fn) override {
    std::string ids;
    for (std::size_t t = 0; t < wanted.size() && t < db_ids_.size(); ++t)
      if (wanted[t]) {
        if (!ids.empty()) ids.push_back(',');
        ids.append(std::to_string(db_ids_[t]));
      }
    if (ids.empty()) return;
    Statement s(db_,
                "SELECT id, topic_id, timestamp, data FROM messages WHERE topic_id IN (" + ids +
                    ") ORDER BY timestamp, id",
                path_);
    while (s.step()) {
      const auto it = local_.find(s.i64(1));
      if (it == local_.end()) continue;
      const void* blob = sqlite3_column_blob(s.get(), 3);
      const int n = sqlite3_column_bytes(s.get(), 3);
      fn(it->second, s.i64(2), s.i64(0), 0, static_cast<const std::uint8_t*>(blob),
         static_cast<std::size_t>(n));
    }
  }

  Payload fetch(std::int64_t key, std::uint64_t, std::uint64_t) override {
    std::lock_guard lock(mutex_);
    if (!fetch_)
      fetch_ = std::make_unique<Statement>(db_, "SELECT data FROM messages WHERE id = ?", path_);
    fetch_->reset();
    sqlite3_bind_int64(fetch_->get(), 1, key);
    if (!fetch_->step())
      throw InputError(file_error(path_, "message row " + std::to_string(key) + " is gone"));
    const auto* blob = static_cast<const std::uint8_t*>(sqlite3_column_blob(fetch_->get(), 0));
    const int n = sqlite3_column_bytes(fetch_->get(), 0);
    auto copy = std::make_shared<std::vector<std::uint8_t>>(blob, blob + n);
    fetch_->reset();
    return {copy->data(), copy->size(), copy};
  }

 private:
  std::set<std::string> columns(const std::string& table) {
    std::set<std::string> out;
    Statement s(db_, "PRAGMA table_info(" + table + ")", path_);
    while (s.step()) out.insert(s.text(1));
    return out;
  }

  void list() {
    sqlite3_exec(db_, "PRAGMA mmap_size=1099511627776", nullptr, nullptr, nullptr);
    std::set<std::string> tables;
    {
      Statement s(db_, "SELECT name FROM sqlite_master WHERE type = 'table'", path_);
      while (s.step()) tables.insert(s.text(0));
    }
    if (!tables.count("topics") || !tables.count("messages")) {
      std::string has;
      for (const auto& t : tables) {
        if (!has.empty()) has.append(", ");
        has.append(t);
      }
      if (has.empty()) has = "none";
      std::string what = "a sqlite3 database but not a ROS 2 recording (no 'topics' and ";
      what.append("'messages' tables; its tables: ").append(has).append(")");
      throw InputError(file_error(path_, what));
    }
    const auto topic_columns = columns("topics");
    const auto message_columns = columns("messages");
    for (const char* c : {"id", "name", "type", "serialization_format"})
      if (!topic_columns.count(c))
        throw InputError(file_error(path_, std::string("not a ROS 2 recording: the topics table "
                                                       "has no column '") +
                                               c + "'"));
    for (const char* c : {"id", "topic_id", "timestamp", "data"})
      if (!message_columns.count(c))
        throw InputError(file_error(path_, std::string("not a ROS 2 recording: the messages "
                                                       "table has no column '") +
                                               c + "'"));
    if (tables.count("schema")) {
      Statement s(db_, "SELECT schema_version, ros_distro FROM schema", path_);
      if (s.step()) ros_distro = s.text(1);
    }
    const bool qos = topic_columns.count("offered_qos_profiles") > 0;
    const bool hash = topic_columns.count("type_description_hash") > 0;
    {
      Statement s(db_,
                  std::string("SELECT id, name, type, serialization_format, ") +
                      (qos ? "offered_qos_profiles" : "''") + ", " +
                      (hash ? "type_description_hash" : "''") + " FROM topics ORDER BY id",
                  path_);
      while (s.step()) {
        FileTopic t;
        t.name = s.text(1);
        t.type = s.text(2);
        t.format = s.text(3);
        t.qos = s.text(4);
        t.hash = s.text(5);
        local_[s.i64(0)] = static_cast<std::uint32_t>(topics.size());
        db_ids_.push_back(s.i64(0));
        topics.push_back(std::move(t));
      }
    }
    Statement s(db_,
                "SELECT topic_id, COUNT(*), MIN(timestamp), MAX(timestamp) FROM messages GROUP "
                "BY topic_id",
                path_);
    std::int64_t first = std::numeric_limits<std::int64_t>::max();
    std::int64_t last = std::numeric_limits<std::int64_t>::min();
    while (s.step()) {
      const auto it = local_.find(s.i64(0));
      if (it == local_.end())
        throw InputError(file_error(path_, "corrupt recording: " + std::to_string(s.i64(1)) +
                                               " messages on topic id " + std::to_string(s.i64(0)) +
                                               ", which the topics table does not list"));
      topics[it->second].count = static_cast<std::uint64_t>(s.i64(1));
      message_count += static_cast<std::uint64_t>(s.i64(1));
      first = std::min(first, s.i64(2));
      last = std::max(last, s.i64(3));
    }
    start_ns = message_count ? first : 0;
    end_ns = message_count ? last : 0;
  }

  std::string path_;
  sqlite3* db_ = nullptr;
  std::map<std::int64_t, std::uint32_t> local_;  // topics.id -> local topic
  std::vector<std::int64_t> db_ids_;
  std::mutex mutex_;
  std::unique_ptr<Statement> fetch_;
};

void exec(sqlite3* db, const std::string& sql, const std::string& path) {
  char* error = nullptr;
  if (sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &error) != SQLITE_OK) {
    const std::string e = error ? error : "unknown error";
    sqlite3_free(error);
    throw InputError(file_error(path, "sqlite3: " + e));
  }
}

class SqliteWriter : public StorageWriter {
 public:
  SqliteWriter(const std::string& path, const WriterOptions& o) : path_(path), options_(o) {
    if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr) !=
        SQLITE_OK) {
      const std::string e = db_ ? sqlite3_errmsg(db_) : "out of memory";
      sqlite3_close_v2(db_);
      db_ = nullptr;
      throw InputError(file_error(path, "cannot create the sqlite3 database: " + e));
    }
    exec(db_, "PRAGMA journal_mode=MEMORY; PRAGMA synchronous=OFF;", path_);
    if (o.sqlite_schema_tables) {
      exec(db_,
           "CREATE TABLE schema(schema_version INTEGER PRIMARY KEY,ros_distro TEXT NOT NULL);"
           "INSERT INTO schema (schema_version, ros_distro) VALUES (4, '');"
           "CREATE TABLE metadata(id INTEGER PRIMARY KEY,metadata_version INTEGER NOT NULL,"
           "metadata TEXT NOT NULL);"
           "CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT NULL,type TEXT NOT NULL,"
           "serialization_format TEXT NOT NULL,offered_qos_profiles TEXT NOT NULL,"
           "type_description_hash TEXT NOT NULL);"
           "CREATE TABLE message_definitions(id INTEGER PRIMARY KEY,topic_type TEXT NOT NULL,"
           "encoding TEXT NOT NULL,encoded_message_definition TEXT NOT NULL,"
           "type_description_hash TEXT NOT NULL);",
           path_);
    } else {
      exec(db_,
           "CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT NULL,type TEXT NOT NULL,"
           "serialization_format TEXT NOT NULL,offered_qos_profiles TEXT NOT NULL);",
           path_);
    }
    exec(db_,
         "CREATE TABLE messages(id INTEGER PRIMARY KEY,topic_id INTEGER NOT NULL,timestamp "
         "INTEGER NOT NULL, data BLOB NOT NULL);"
         "CREATE INDEX timestamp_idx ON messages (timestamp ASC);"
         "BEGIN TRANSACTION;",
         path_);
    insert_ = std::make_unique<Statement>(
        db_, "INSERT INTO messages (timestamp, topic_id, data) VALUES (?, ?, ?)", path_);
  }
  ~SqliteWriter() override {
    insert_.reset();
    sqlite3_close_v2(db_);
  }

  void add_topic(std::uint32_t id, const WriterTopic& t) override {
    const bool v4 = options_.sqlite_schema_tables;
    Statement s(db_,
                v4 ? "INSERT INTO topics (id, name, type, serialization_format, "
                     "offered_qos_profiles, type_description_hash) VALUES (?, ?, ?, 'cdr', ?, ?)"
                   : "INSERT INTO topics (id, name, type, serialization_format, "
                     "offered_qos_profiles) VALUES (?, ?, ?, 'cdr', ?)",
                path_);
    sqlite3_bind_int64(s.get(), 1, id + 1);
    sqlite3_bind_text(s.get(), 2, t.name.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_text(s.get(), 3, t.type.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_text(s.get(), 4, t.qos.c_str(), -1, SQLITE_TRANSIENT);
    if (v4) sqlite3_bind_text(s.get(), 5, t.hash.c_str(), -1, SQLITE_TRANSIENT);
    s.step();
    if (v4 && defined_.insert(t.type).second) {
      Statement d(db_,
                  "INSERT INTO message_definitions (topic_type, encoding, "
                  "encoded_message_definition, type_description_hash) VALUES (?, 'ros2msg', ?, ?)",
                  path_);
      sqlite3_bind_text(d.get(), 1, t.type.c_str(), -1, SQLITE_TRANSIENT);
      sqlite3_bind_text(d.get(), 2, t.definition.c_str(), -1, SQLITE_TRANSIENT);
      sqlite3_bind_text(d.get(), 3, t.hash.c_str(), -1, SQLITE_TRANSIENT);
      d.step();
    }
  }

  void write(std::uint32_t id, std::int64_t timestamp,
             const std::vector<std::uint8_t>& data) override {
    insert_->reset();
    sqlite3_bind_int64(insert_->get(), 1, timestamp);
    sqlite3_bind_int64(insert_->get(), 2, id + 1);
    if (options_.compression == "zstd") {
      const auto z = zstd_compress(data.data(), data.size(), 1);
      sqlite3_bind_blob64(insert_->get(), 3, z.data(), z.size(), SQLITE_TRANSIENT);
    } else {
      sqlite3_bind_blob64(insert_->get(), 3, data.data(), data.size(), SQLITE_STATIC);
    }
    insert_->step();
    insert_->reset();
  }

  void close(const std::string& metadata_yaml) override {
    if (options_.sqlite_schema_tables) {
      Statement s(db_, "INSERT INTO metadata (metadata_version, metadata) VALUES (?, ?)", path_);
      sqlite3_bind_int(s.get(), 1, 8);
      sqlite3_bind_text(s.get(), 2, metadata_yaml.c_str(), -1, SQLITE_TRANSIENT);
      s.step();
    }
    exec(db_, "COMMIT;", path_);
    insert_.reset();
    if (sqlite3_close_v2(db_) != SQLITE_OK)
      throw InputError(file_error(path_, "sqlite3: cannot close the database"));
    db_ = nullptr;
  }

 private:
  std::string path_;
  WriterOptions options_;
  sqlite3* db_ = nullptr;
  std::unique_ptr<Statement> insert_;
  std::set<std::string> defined_;
};

}  // namespace

bool is_sqlite_file(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return false;
  char head[16] = {};
  const bool ok = std::fread(head, 1, 16, f) == 16 && std::memcmp(head, "SQLite format 3", 16) == 0;
  std::fclose(f);
  return ok;
}

std::unique_ptr<StorageFile> open_sqlite(const std::string& path) {
  return std::make_unique<SqliteFile>(path);
}

std::unique_ptr<StorageWriter> make_sqlite_writer(const std::string& path, const WriterOptions& o) {
  return std::make_unique<SqliteWriter>(path, o);
}

}  // namespace mcslam::rosbag2::detail
