// A ROS 1 bag (format 2.0) read record by record, without its index: every bag, and so
// also one whose recorder was killed (`rosbag record` writes NAME.bag.active and its
// index only when it closes), as `rosbag reindex` reads it. No ROS library is involved:
// a bag from a stranger costs what chunk_cache.hpp bounds. The format (wiki.ros.org/Bags/Format/2.0): after
// "#ROSBAG V2.0\n", records of a header (length, then fields "name=value", each with
// its length) and data (length, bytes). Chunks (op 5) hold connection records (op 7) and
// messages (op 2), uncompressed, bz2 or lz4 (the LZ4 frame format). A chunk the recorder
// never finished has sizes 0: an uncompressed one is read up to where it ends, a
// compressed one cannot be. Chunks cost what chunk_cache.hpp bounds.
#include "chunk_cache.hpp"
#include "container.hpp"
#include "file_reader.hpp"

#include "mobmap/sources/io_error.hpp"

#include <bzlib.h>

#include <array>
#include <cstring>
#include <map>
#include <optional>
#include <string_view>

namespace mobmap::sources {
namespace {

constexpr char kMagic[] = "#ROSBAG V2.0\n";
constexpr std::uint64_t kMagicBytes = 13;
constexpr std::uint32_t kMaxHeaderBytes = 16u << 20;  // a connection's header holds its message definition
enum Op : std::uint8_t { kMessage = 0x02, kBagHeader = 0x03, kChunk = 0x05, kConnection = 0x07 };

std::uint32_t le32(const std::uint8_t* p) { return std::uint32_t{p[0]} | std::uint32_t{p[1]} << 8 | std::uint32_t{p[2]} << 16 | std::uint32_t{p[3]} << 24; }

// A record's header fields that mobmap reads, as views into the record's bytes (any
// other field is skipped): a chunk of a hostile bag may hold millions of them.
class Header {
 public:
  Header() = default;
  Header(const std::uint8_t* p, std::size_t n) {
    std::size_t at = 0;
    while (at < n) {
      if (n - at < 4) throw ros::MessageError("a header field's length runs past its header");
      const std::uint32_t len = le32(p + at);
      at += 4;
      if (len > n - at) throw ros::MessageError("a header field runs past its header");
      const std::string_view field(reinterpret_cast<const char*>(p + at), len);
      const auto eq = field.find('=');
      if (eq == std::string_view::npos) throw ros::MessageError("a header field without '='");
      for (std::size_t i = 0; i < kNames.size(); ++i) {
        if (field.substr(0, eq) == kNames[i]) values_[i] = field.substr(eq + 1);
      }
      at += len;
    }
  }
  [[nodiscard]] std::optional<std::string_view> find(std::string_view name) const {
    for (std::size_t i = 0; i < kNames.size(); ++i) {
      if (kNames[i] == name) return values_[i];
    }
    return std::nullopt;
  }

 private:
  static constexpr std::array<std::string_view, 9> kNames = {"op",          "conn", "time",      "topic",    "type",
                                                             "compression", "size", "index_pos", "encryptor"};
  std::array<std::optional<std::string_view>, 9> values_;
};

std::uint32_t u32Field(const Header& f, const char* name) {
  const auto v = f.find(name);
  if (!v || v->size() != 4) throw ros::MessageError(std::string("no 4-byte field ") + name);
  return le32(reinterpret_cast<const std::uint8_t*>(v->data()));
}

std::string textField(const Header& f, const char* name) {
  const auto v = f.find(name);
  if (!v) throw ros::MessageError(std::string("no field ") + name);
  return std::string(*v);
}

class Ros1Scan : public Container {
 public:
  explicit Ros1Scan(const std::string& path) : file_(path), budget_(file_.size()) {
    char magic[kMagicBytes] = {0};
    (void)file_.readAt(0, magic, kMagicBytes);
    const std::string version(magic, kMagicBytes);
    if (version.rfind("#ROSBAG V", 0) != 0) throw IoError(path, "not a ROS 1 bag (no #ROSBAG header)");
    if (version != kMagic) {
      throw IoError(path, "a ROS 1 bag of format " + version.substr(9, 3) + "; mobmap reads format 2.0 (`rosbag fix` converts it)");
    }
  }

  std::optional<ContainerFault> scan(const std::function<void(const RawMessage&)>& visit) override {
    std::uint64_t at = kMagicBytes;
    std::vector<std::uint8_t> head, data;
    chunks_ = 0;
    while (at < file_.size()) {
      Header f;
      std::uint64_t data_at = 0;
      std::uint32_t data_len = 0;
      if (auto fault = readRecord(at, &head, &f, &data_at, &data_len)) return fault;
      try {
        const std::string op = textField(f, "op");
        if (op.size() != 1) throw ros::MessageError("an op field of " + std::to_string(op.size()) + " bytes");
        const auto code = static_cast<std::uint8_t>(op[0]);
        if (code == kChunk) {
          if (auto fault = chunk(at, f, data_at, data_len, visit)) return fault;
          ++chunks_;
        } else if (code == kBagHeader) {
          if (const auto encryptor = f.find("encryptor"); encryptor && !encryptor->empty()) {
            throw IoError(file_.path(), "an encrypted ROS 1 bag (" + std::string(*encryptor) + "); `rosbag decrypt` writes it in the clear");
          }
          // Its index: where the header says, when that lies inside the file (0 until closed).
          const auto index = f.find("index_pos");
          std::uint64_t pos = 0;
          if (index && index->size() == 8) {
            const auto* b = reinterpret_cast<const std::uint8_t*>(index->data());
            pos = std::uint64_t{le32(b)} | std::uint64_t{le32(b + 4)} << 32;
          }
          indexed_ = pos != 0 && pos < file_.size();
        } else if (code == kConnection) {
          data.resize(data_len);
          if (!file_.readAt(data_at, data.data(), data.size())) return fault("cannot read the record at byte " + std::to_string(at));
          connection(f, data.data(), data.size());
        }  // index data and chunk infos: an index is what this reading does without
      } catch (const ros::MessageError& e) {
        return fault("the record at byte " + std::to_string(at) + " is malformed: " + e.what());
      }
      at = data_at + data_len;
    }
    return std::nullopt;
  }

  const std::vector<ContainerTopic>& topics() const override { return topics_; }
  std::vector<std::string> files() const override { return {file_.path()}; }
  std::string recovered() const override {
    if (indexed_) return {};
    return file_.path() + ": a ROS 1 bag without its index (its recorder did not close it): " + std::to_string(chunks_) +
           " chunk" + (chunks_ == 1 ? "" : "s") + " read one after another, as `rosbag reindex` would";
  }

  std::vector<std::uint8_t> read(const MessageRef& ref) const override {
    // a: the chunk record's offset, b: the message's data in its records, c: its length.
    try {
      return cache_.copy(ref.a, ref.b, ref.c, [&] { return declared_.at(ref.a); }, [&] { return unpackAgain(ref.a); });
    } catch (const std::out_of_range&) {
      throw IoError(file_.path(), "a message lies outside its chunk at byte " + std::to_string(ref.a));
    }
  }

 private:
  std::optional<ContainerFault> fault(const std::string& what) const { return ContainerFault{file_.path() + ": " + what}; }

  // The record at `at`: its header fields, where its data lies and how long it is.
  std::optional<ContainerFault> readRecord(std::uint64_t at, std::vector<std::uint8_t>* head, Header* f,
                                           std::uint64_t* data_at, std::uint32_t* data_len) const {
    std::uint8_t len[4];
    const std::string where = "the record at byte " + std::to_string(at);
    if (!file_.readAt(at, len, 4)) return fault("the file is cut short inside " + where);
    const std::uint32_t head_len = le32(len);
    if (head_len > kMaxHeaderBytes || head_len > file_.size() - at - 4) return fault("the file is cut short inside " + where);
    head->resize(head_len);
    if (!file_.readAt(at + 4, head->data(), head_len) || !file_.readAt(at + 4 + head_len, len, 4)) {
      return fault("the file is cut short inside " + where);
    }
    try {
      *f = Header(head->data(), head->size());
    } catch (const ros::MessageError& e) {
      return fault(where + " is malformed: " + e.what());
    }
    *data_at = at + 8 + head_len;
    *data_len = le32(len);
    if (*data_len > file_.size() - *data_at) return fault("the file is cut short inside " + where);
    return std::nullopt;
  }

  void connection(const Header& f, const std::uint8_t* data, std::size_t n) {
    const std::uint32_t id = u32Field(f, "conn");
    if (connections_.count(id)) return;  // in a chunk and again at the end
    const Header described(data, n);
    ContainerTopic t{textField(f, "topic"), textField(described, "type"), "ros1"};
    const auto [it, fresh] = topic_of_.try_emplace({t.name, t.type}, static_cast<int>(topics_.size()));
    if (fresh) topics_.push_back(std::move(t));
    connections_[id] = it->second;
  }

  // The chunk's records decompressed; "" or why not.
  std::string unpack(const Header& f, std::uint64_t data_at, std::uint32_t data_len,
                     ChunkBytes* records, bool reading_again) const {
    const std::string compression = textField(f, "compression");
    const std::uint32_t size = u32Field(f, "size");
    if (compression == "none") {
      if (size != data_len) return "its uncompressed records are " + std::to_string(data_len) + " bytes, not the " + std::to_string(size) + " it declares";
      if (std::string over = budget_.charge(size, reading_again); !over.empty()) return over;
      records->resize(data_len);
      return file_.readAt(data_at, records->data(), records->size()) ? "" : "cannot be read";
    }
    std::vector<std::uint8_t> stored(data_len);
    if (!file_.readAt(data_at, stored.data(), stored.size())) return "cannot be read";
    if (compression != "bz2" && compression != "lz4") return "its compression \"" + compression + "\" is not one ROS 1 bags use (none, bz2, lz4)";
    if (std::string over = budget_.charge(size, reading_again, compression == "bz2" ? 8 : 1); !over.empty()) return over;
    records->resize(size);
    if (compression == "bz2") {
      unsigned out = size;
      const int rc = BZ2_bzBuffToBuffDecompress(reinterpret_cast<char*>(records->data()), &out, reinterpret_cast<char*>(stored.data()),
                                                data_len, 0, 0);
      if (rc != BZ_OK) return "bzip2 cannot decompress it (error " + std::to_string(rc) + ")";
      if (out != size) return "it decompresses to " + std::to_string(out) + " bytes, not " + std::to_string(size);
      return {};
    }
    return expandLz4Frame(stored.data(), stored.size(), records);
  }

  std::optional<ContainerFault> chunk(std::uint64_t at, const Header& f, std::uint64_t data_at,
                                      std::uint32_t data_len, const std::function<void(const RawMessage&)>& visit) {
    const std::string where = "the chunk at byte " + std::to_string(at);
    ChunkBytes records;
    bool unfinished = false;
    if (data_len == 0 && u32Field(f, "size") == 0) {
      // Never finished: its sizes are the placeholders written when it was begun.
      if (textField(f, "compression") != "none") {
        return fault(where + " was never finished (its recorder was killed while writing it); its compressed messages are lost");
      }
      const std::uint64_t rest = std::min<std::uint64_t>(file_.size() - data_at, kMaxChunkBytes);
      records.resize(static_cast<std::size_t>(rest));
      if (!file_.readAt(data_at, records.data(), records.size())) return fault("cannot read " + where);
      unfinished = true;
    } else if (const std::string err = unpack(f, data_at, data_len, &records, false); !err.empty()) {
      return fault(where + " is unreadable: " + err);
    }
    declared_[at] = records.size();
    std::size_t i = 0;
    while (i < records.size()) {
      const std::uint8_t* p = records.data() + i;
      const std::size_t left = records.size() - i;
      const std::string inner = "a record at byte " + std::to_string(i) + " of " + where;
      if (left < 4 || le32(p) > left - 4 || left - 4 - le32(p) < 4) {
        if (unfinished) return fault(where + " was never finished (its recorder was killed while writing it): read up to its last whole message");
        return fault(inner + " runs past the chunk's end");
      }
      const std::uint32_t head_len = le32(p);
      const std::uint32_t len = le32(p + 4 + head_len);
      if (len > left - 8 - head_len) {
        if (unfinished) return fault(where + " was never finished (its recorder was killed while writing it): read up to its last whole message");
        return fault(inner + " runs past the chunk's end");
      }
      const std::uint8_t* data = p + 8 + head_len;
      try {
        const Header h(p + 4, head_len);
        const auto op = h.find("op");
        if (!op || op->size() != 1) throw ros::MessageError("a record without a one-byte op");
        if ((*op)[0] == static_cast<char>(kConnection)) {
          connection(h, data, len);
        } else if ((*op)[0] == static_cast<char>(kMessage)) {
          const auto c = connections_.find(u32Field(h, "conn"));
          if (c == connections_.end()) throw ros::MessageError("a message on a connection no record declares");
          const auto time = h.find("time");
          if (!time || time->size() != 8) throw ros::MessageError("a message without an 8-byte time");
          const auto* t = reinterpret_cast<const std::uint8_t*>(time->data());
          RawMessage m;
          m.topic = c->second;
          m.log_time_ns = static_cast<std::int64_t>(le32(t)) * 1000000000 + static_cast<std::int64_t>(le32(t + 4));
          m.data = data;
          m.size = len;
          m.ref = {0, at, static_cast<std::uint64_t>(data - records.data()), len};
          visit(m);
        }
      } catch (const ros::MessageError& e) {
        if (unfinished) return fault(where + " was never finished (its recorder was killed while writing it): read up to its last whole message");
        return fault(inner + " is malformed: " + e.what());
      }
      i += 8 + head_len + len;
    }
    if (unfinished) return fault(where + " was never finished (its recorder was killed while writing it): read to its end");
    return std::nullopt;
  }

  ChunkBytes unpackAgain(std::uint64_t at) const {
    std::vector<std::uint8_t> head;
    Header f;
    std::uint64_t data_at = 0;
    std::uint32_t data_len = 0;
    if (auto fault = readRecord(at, &head, &f, &data_at, &data_len)) throw IoError(file_.path(), fault->what);
    ChunkBytes records;
    if (data_len == 0) {  // the unfinished chunk, as the pass read it
      records.resize(static_cast<std::size_t>(declared_.at(at)));
      if (!file_.readAt(data_at, records.data(), records.size())) throw IoError(file_.path(), "cannot read the chunk at byte " + std::to_string(at));
      return records;
    }
    std::string err;
    try {
      err = unpack(f, data_at, data_len, &records, true);
    } catch (const ros::MessageError& e) {
      err = e.what();
    }
    if (!err.empty()) throw IoError(file_.path(), "the chunk at byte " + std::to_string(at) + " is unreadable: " + err);
    return records;
  }

  FileReader file_;
  InflateBudget budget_;
  ChunkCache cache_;
  std::map<std::uint32_t, int> connections_;  // connection id -> topic
  std::map<std::pair<std::string, std::string>, int> topic_of_;  // (name, type) -> topic
  std::vector<ContainerTopic> topics_;
  std::map<std::uint64_t, std::uint64_t> declared_;  // chunk offset -> its records' size
  std::size_t chunks_ = 0;
  bool indexed_ = false;  // its header points at an index (it was closed): nothing to say
};

}  // namespace

bool isActiveRos1Bag(const std::string& path) {
  const std::string suffix = ".bag.active";
  return path.size() > suffix.size() && path.compare(path.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::unique_ptr<Container> openRos1Bag(const std::string& path) { return std::make_unique<Ros1Scan>(path); }

}  // namespace mobmap::sources
