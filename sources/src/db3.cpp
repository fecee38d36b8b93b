// A ROS 2 bag's sqlite3 storage (.db3, rosbag2's default up to Humble): a `topics`
// table (id, name, type, serialization_format) and a `messages` table (id, topic_id,
// timestamp, data), read through SQLite itself. The file is opened read-only and
// immutable, so a hostile file can neither be changed nor make SQLite write beside it.

#include "container.hpp"

#include "mobmap/sources/io_error.hpp"

#include <sqlite3.h>

#include <map>
#include <mutex>

namespace mobmap::sources {
namespace {

struct StatementCloser {
  void operator()(sqlite3_stmt* s) const { sqlite3_finalize(s); }
};
using Statement = std::unique_ptr<sqlite3_stmt, StatementCloser>;
struct DatabaseCloser {
  void operator()(sqlite3* db) const { sqlite3_close(db); }
};

class Db3Container : public Container {
 public:
  explicit Db3Container(const std::string& path) : path_(path) {
    std::FILE* probe = std::fopen(path.c_str(), "rb");
    if (!probe) throw IoError(path, "cannot open");
    char magic[16] = {0};
    const std::size_t n = std::fread(magic, 1, sizeof magic, probe);
    std::fclose(probe);
    if (n < 16 || std::string(magic, 15) != "SQLite format 3") throw IoError(path, "not an SQLite database (a ROS 2 .db3 is one)");
    const std::string uri = "file:" + uriEscape(path) + "?mode=ro&immutable=1";
    sqlite3* db = nullptr;
    const int opened = sqlite3_open_v2(uri.c_str(), &db, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI | SQLITE_OPEN_FULLMUTEX, nullptr);
    database_.reset(db);  // closed on every path, an error's too
    db_ = db;
    if (opened != SQLITE_OK) throw IoError(path, std::string("cannot open as SQLite: ") + (db ? sqlite3_errmsg(db) : "out of memory"));
    // Bounds for a hostile file: no huge blobs or strings, no runaway statement.
    sqlite3_limit(db_, SQLITE_LIMIT_LENGTH, 1 << 30);
    sqlite3_limit(db_, SQLITE_LIMIT_SQL_LENGTH, 1 << 16);
    Statement topics = prepare("SELECT id, name, type, serialization_format FROM topics");
    int rc;
    while ((rc = sqlite3_step(topics.get())) == SQLITE_ROW) {
      const auto id = sqlite3_column_int64(topics.get(), 0);
      ids_[id] = static_cast<int>(topics_.size());
      topics_.push_back({text(topics.get(), 1), normaliseType(text(topics.get(), 2)), text(topics.get(), 3)});
    }
    if (rc != SQLITE_DONE) throw IoError(path_, std::string("cannot read its topics table: ") + sqlite3_errmsg(db_));
  }

  std::optional<ContainerFault> scan(const std::function<void(const RawMessage&)>& visit) override {
    Statement s = prepare("SELECT id, topic_id, timestamp, data FROM messages ORDER BY id");
    int rc;
    while ((rc = sqlite3_step(s.get())) == SQLITE_ROW) {
      const auto id = sqlite3_column_int64(s.get(), 0);
      const auto topic = ids_.find(sqlite3_column_int64(s.get(), 1));
      if (topic == ids_.end()) continue;  // a message of no listed topic
      RawMessage m;
      m.topic = topic->second;
      m.log_time_ns = sqlite3_column_int64(s.get(), 2);
      m.data = static_cast<const std::uint8_t*>(sqlite3_column_blob(s.get(), 3));
      m.size = static_cast<std::size_t>(sqlite3_column_bytes(s.get(), 3));
      m.ref.a = static_cast<std::uint64_t>(id);
      visit(m);
    }
    if (rc != SQLITE_DONE) {
      return ContainerFault{path_ + ": its messages table cannot be read past this point (" + sqlite3_errmsg(db_) + ")"};
    }
    return std::nullopt;
  }

  const std::vector<ContainerTopic>& topics() const override { return topics_; }
  std::vector<std::string> files() const override { return {path_}; }

  std::vector<std::uint8_t> read(const MessageRef& ref) const override {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!read_) read_ = prepare("SELECT data FROM messages WHERE id = ?");
    sqlite3_reset(read_.get());
    sqlite3_bind_int64(read_.get(), 1, static_cast<sqlite3_int64>(ref.a));
    if (sqlite3_step(read_.get()) != SQLITE_ROW) {
      throw IoError(path_, "message " + std::to_string(ref.a) + " can no longer be read: " + sqlite3_errmsg(db_));
    }
    const auto* p = static_cast<const std::uint8_t*>(sqlite3_column_blob(read_.get(), 0));
    const auto n = static_cast<std::size_t>(sqlite3_column_bytes(read_.get(), 0));
    std::vector<std::uint8_t> out(p, p + n);
    sqlite3_reset(read_.get());
    return out;
  }

 private:
  static std::string uriEscape(const std::string& path) {
    std::string out;
    for (char c : path) {
      if (c == '%' || c == '?' || c == '#') {
        char buf[4];
        std::snprintf(buf, sizeof buf, "%%%02X", static_cast<unsigned char>(c));
        out += buf;
      } else {
        out += c;
      }
    }
    return out;
  }
  static std::string text(sqlite3_stmt* s, int col) {
    const auto* t = sqlite3_column_text(s, col);
    return t ? std::string(reinterpret_cast<const char*>(t), static_cast<std::size_t>(sqlite3_column_bytes(s, col))) : std::string();
  }
  Statement prepare(const char* sql) const {
    sqlite3_stmt* s = nullptr;
    if (sqlite3_prepare_v2(db_, sql, -1, &s, nullptr) != SQLITE_OK) {
      throw IoError(path_, std::string("not a ROS 2 bag database (") + sqlite3_errmsg(db_) + ")");
    }
    return Statement(s);
  }

  std::string path_;
  std::unique_ptr<sqlite3, DatabaseCloser> database_;
  sqlite3* db_ = nullptr;  // database_'s
  std::map<sqlite3_int64, int> ids_;
  std::vector<ContainerTopic> topics_;
  mutable std::mutex mutex_;
  mutable Statement read_;
};

}  // namespace

std::unique_ptr<Container> openDb3(const std::string& path) { return std::make_unique<Db3Container>(path); }

}  // namespace mobmap::sources
