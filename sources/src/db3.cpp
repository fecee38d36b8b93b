// A ROS 2 bag's sqlite3 storage (.db3, rosbag2's default up to Humble): a `topics`
// table (id, name, type, serialization_format) and a `messages` table (id, topic_id,
// timestamp, data), read through SQLite itself. The file is opened read-only and
// immutable, so a hostile file can neither be changed nor make SQLite write beside it;
// `topics` and `messages` must be plain tables (no view, no generated column), the
// schema is not trusted (no function with side effects runs from it), and a progress
// handler bounds the work of each statement by the file's size.
//
// A database whose writer was killed (rosbag2 in WAL mode) keeps its newest messages in
// its -wal file: its committed pages are laid over the database's (wal_overlay.hpp), and
// recovered() says how many messages that gave.

#include "container.hpp"

#include "file_reader.hpp"
#include "wal_overlay.hpp"

#include "mobmap/sources/io_error.hpp"

#include <sqlite3.h>

#include <filesystem>
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

// SQLite's work on one statement, in thousands of virtual machine steps: 100 million
// steps and 64 a byte of the files (a plain scan takes ~15 steps a row, and a row takes
// at least a few bytes).
struct WorkBudget {
  std::uint64_t ticks = 0, limit = 0;
  bool exceeded = false;
  static int tick(void* self) {
    auto* b = static_cast<WorkBudget*>(self);
    if (++b->ticks <= b->limit) return 0;
    b->exceeded = true;
    return 1;  // interrupts the statement
  }
};

class Db3Container : public Container {
 public:
  explicit Db3Container(const std::string& path) : path_(path) {
    namespace fs = std::filesystem;
    const FileReader file(path);
    std::uint8_t header[100] = {0};
    const bool has_header = file.readAt(0, header, sizeof header);
    // A log beside a database in WAL mode (or one with no page yet): its writer never
    // closed it, and its newest commits are there.
    std::error_code ec;
    const std::string wal = path + "-wal";
    if (fs::is_regular_file(wal, ec) && fs::file_size(wal, ec) > 32 && (!has_header || (header[18] == 2 && header[19] == 2))) {
      const std::uint32_t page_size = !has_header ? 0 : header[16] == 0 && header[17] == 1 ? 65536u : (header[16] << 8 | header[17]);
      overlay_ = readWal(wal, page_size);
      if (overlay_ && !overlay_->read(file, 0, header, sizeof header)) overlay_.reset();
    }
    if ((!has_header && !overlay_) || std::string(reinterpret_cast<const char*>(header), 15) != "SQLite format 3") {
      throw IoError(path, "not an SQLite database (a ROS 2 .db3 is one)");
    }
    work_limit_ = 100000 + (file.size() + (overlay_ ? overlay_->log->size() : 0)) / 16;
    std::string uri = "file:" + uriEscape(path) + "?mode=ro&immutable=1";
    std::string wal_id;
    if (overlay_) {
      wal_id = registerWal(overlay_.get());
      uri += "&mobmap_wal=" + wal_id;
    }
    sqlite3* db = nullptr;
    const int opened = sqlite3_open_v2(uri.c_str(), &db, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI | SQLITE_OPEN_FULLMUTEX,
                                       overlay_ ? walOverlayVfs() : nullptr);
    if (overlay_) unregisterWal(wal_id);
    database_.reset(db);  // closed on every path, an error's too
    db_ = db;
    if (opened != SQLITE_OK) throw IoError(path, std::string("cannot open as SQLite: ") + (db ? sqlite3_errmsg(db) : "out of memory"));
    harden(db_, &budget_);
    checkSchema();
    Statement topics = prepare("SELECT id, name, type, serialization_format FROM topics");
    int rc;
    while ((rc = sqlite3_step(topics.get())) == SQLITE_ROW) {
      const auto id = sqlite3_column_int64(topics.get(), 0);
      ids_[id] = static_cast<int>(topics_.size());
      topics_.push_back({text(topics.get(), 1), normaliseType(text(topics.get(), 2)), text(topics.get(), 3)});
    }
    if (rc != SQLITE_DONE) throw IoError(path_, "cannot read its topics table: " + failure());
    if (overlay_) describeRecovery(wal);
  }

  std::string recovered() const override { return recovered_; }

  std::optional<ContainerFault> scan(const std::function<void(const RawMessage&)>& visit) override {
    // By rowid (rosbag2's id is that alias): the table's own order, no sort, and each
    // message found again in O(log n).
    Statement s = prepare("SELECT rowid, topic_id, timestamp, data FROM messages ORDER BY rowid");
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
      return ContainerFault{path_ + ": its messages table cannot be read past this point (" + failure() + ")"};
    }
    return std::nullopt;
  }

  const std::vector<ContainerTopic>& topics() const override { return topics_; }
  std::vector<std::string> files() const override { return {path_}; }

  std::vector<std::uint8_t> read(const MessageRef& ref) const override {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!read_) read_ = prepare("SELECT data FROM messages WHERE rowid = ?");
    sqlite3_reset(read_.get());
    budget_ = WorkBudget{0, work_limit_};
    sqlite3_bind_int64(read_.get(), 1, static_cast<sqlite3_int64>(ref.a));
    if (sqlite3_step(read_.get()) != SQLITE_ROW) {
      throw IoError(path_, "message " + std::to_string(ref.a) + " can no longer be read: " + failure());
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
  // Bounds for a hostile file: no huge blobs or strings, no runaway statement, nothing
  // from its schema trusted.
  static void harden(sqlite3* db, WorkBudget* budget) {
    sqlite3_limit(db, SQLITE_LIMIT_LENGTH, 1 << 30);
    sqlite3_limit(db, SQLITE_LIMIT_SQL_LENGTH, 1 << 16);
    sqlite3_db_config(db, SQLITE_DBCONFIG_TRUSTED_SCHEMA, 0, nullptr);
    sqlite3_db_config(db, SQLITE_DBCONFIG_DEFENSIVE, 1, nullptr);
    sqlite3_progress_handler(db, 1000, &WorkBudget::tick, budget);
  }

  // rosbag2's tables, as tables: a view (an endless recursive query behind `messages`)
  // or a generated column (a blob computed per row) is refused before any row is read.
  void checkSchema() const {
    for (const char* table : {"topics", "messages"}) {
      Statement kind = prepare("SELECT type FROM sqlite_master WHERE name = ?");
      sqlite3_bind_text(kind.get(), 1, table, -1, SQLITE_STATIC);
      if (sqlite3_step(kind.get()) != SQLITE_ROW) throw IoError(path_, std::string("not a ROS 2 bag database (no ") + table + " table)");
      const std::string type = text(kind.get(), 0);
      if (type != "table") throw IoError(path_, std::string("not a ROS 2 bag database (its ") + table + " is a " + type + ", not a table)");
      Statement columns = prepare((std::string("SELECT name, hidden FROM pragma_table_xinfo('") + table + "')").c_str());
      while (sqlite3_step(columns.get()) == SQLITE_ROW) {
        if (sqlite3_column_int(columns.get(), 1) != 0) {
          throw IoError(path_, std::string("not a ROS 2 bag database (its ") + table + " table computes its column " +
                                   text(columns.get(), 0) + ")");
        }
      }
    }
  }

  // What the log added: the messages the database holds with it and without it.
  void describeRecovery(const std::string& wal) {
    std::uint64_t with = 0, without = 0;
    if (!countMessages(db_, &with)) return;
    sqlite3* plain = nullptr;
    const std::string uri = "file:" + uriEscape(path_) + "?mode=ro&immutable=1";
    if (sqlite3_open_v2(uri.c_str(), &plain, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI, nullptr) == SQLITE_OK) {
      WorkBudget budget;
      harden(plain, &budget);
      if (!countMessages(plain, &without, &budget)) without = 0;  // no table there yet: all of them are the log's
    }
    sqlite3_close(plain);
    const std::string name = std::filesystem::path(wal).filename().string();
    recovered_ = path_ + ": " + std::to_string(with - std::min(with, without)) + " of its " + std::to_string(with) +
                 " messages recovered from " + name + ", the write-ahead log its writer never merged (" +
                 std::to_string(overlay_->committed_frames) + " committed pages" +
                 (overlay_->dropped_frames ? ", " + std::to_string(overlay_->dropped_frames) + " pages of an unfinished commit left out" : "") +
                 "; nothing was written beside it)";
  }

  bool countMessages(sqlite3* db, std::uint64_t* n, WorkBudget* budget = nullptr) {
    WorkBudget& b = budget ? *budget : budget_;
    b = WorkBudget{0, work_limit_};
    sqlite3_stmt* raw = nullptr;
    if (sqlite3_prepare_v2(db, "SELECT count(*) FROM messages", -1, &raw, nullptr) != SQLITE_OK) return false;
    const Statement s(raw);
    if (sqlite3_step(s.get()) != SQLITE_ROW) return false;
    *n = static_cast<std::uint64_t>(sqlite3_column_int64(s.get(), 0));
    return true;
  }

  // Why the last call failed: SQLite's words, or the work bound's.
  std::string failure() const {
    if (budget_.exceeded) {
      return "SQLite's work on it passed " + std::to_string(work_limit_) + " thousand steps, the bound for a file of its size";
    }
    return sqlite3_errmsg(db_);
  }

  Statement prepare(const char* sql) const {
    sqlite3_stmt* s = nullptr;
    budget_ = WorkBudget{0, work_limit_};
    if (sqlite3_prepare_v2(db_, sql, -1, &s, nullptr) != SQLITE_OK) {
      throw IoError(path_, "not a ROS 2 bag database (" + failure() + ")");
    }
    return Statement(s);
  }

  std::string path_;
  std::unique_ptr<WalOverlay> overlay_;  // before database_: it outlives the connection reading through it
  mutable WorkBudget budget_;            // the running statement's (reads hold mutex_)
  std::uint64_t work_limit_ = 0;
  std::string recovered_;
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
