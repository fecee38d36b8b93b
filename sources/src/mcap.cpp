// An MCAP reader written to the published specification (mcap.dev/spec): the magic,
// then records (opcode, u64 length, content) through the data section's DataEnd;
// messages stored on their own or in chunks (uncompressed, lz4 frames or zstd), each
// chunk checked against its CRC when it has one. The summary section is not needed: one
// pass over the data section finds every channel and message, so a file whose recorder
// was killed before writing its summary reads up to where it ends.
// What a hostile file's chunks can cost is bounded as chunk_cache.hpp says.

#include "chunk_cache.hpp"
#include "container.hpp"
#include "file_reader.hpp"

#include "mobmap/sources/io_error.hpp"

#include <zlib.h>
#include <zstd.h>

#include <cstring>
#include <map>

namespace mobmap::sources {
namespace {

constexpr unsigned char kMagic[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
constexpr std::uint64_t kMaxRecordBytes = 1ULL << 30;  // a record's content as stored (also bounded by the file)
constexpr std::uint64_t kUnchunked = ~0ULL;

enum Op : std::uint8_t {
  kHeader = 0x01, kFooter = 0x02, kSchema = 0x03, kChannel = 0x04, kMessage = 0x05, kChunk = 0x06, kDataEnd = 0x0F
};

// Little-endian fields of one record's content, bounds-checked.
class Fields {
 public:
  Fields(const std::uint8_t* p, std::size_t n) : p_(p), n_(n) {}
  template <typename T>
  T get() {
    need(sizeof(T));
    T v = 0;
    for (std::size_t i = 0; i < sizeof(T); ++i) v = static_cast<T>(v | static_cast<T>(static_cast<T>(p_[at_ + i]) << (8 * i)));
    at_ += sizeof(T);
    return v;
  }
  std::string str() {
    const auto len = get<std::uint32_t>();
    need(len);
    std::string s(reinterpret_cast<const char*>(p_ + at_), len);
    at_ += len;
    return s;
  }
  void skip(std::uint64_t n) {
    need(n);
    at_ += static_cast<std::size_t>(n);
  }
  [[nodiscard]] std::size_t at() const { return at_; }
  [[nodiscard]] std::size_t left() const { return n_ - at_; }
  [[nodiscard]] const std::uint8_t* here() const { return p_ + at_; }

 private:
  void need(std::uint64_t n) const {
    if (n > n_ - at_) throw ros::MessageError("a record's fields run past its end");
  }
  const std::uint8_t* p_;
  std::size_t n_;
  std::size_t at_ = 0;
};

std::uint64_t le64(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

class McapContainer : public Container {
 public:
  explicit McapContainer(const std::string& path) : file_(path), budget_(file_.size()) {
    std::uint8_t magic[8];
    if (file_.size() < 8 || !file_.readAt(0, magic, 8) || std::memcmp(magic, kMagic, 8) != 0) {
      throw IoError(path, "not an MCAP file (no MCAP magic at its start)");
    }
  }

  std::optional<ContainerFault> scan(const std::function<void(const RawMessage&)>& visit) override {
    std::uint64_t at = 8;
    std::vector<std::uint8_t> content;
    while (true) {
      std::uint8_t head[9];
      if (!file_.readAt(at, head, 9)) return fault("the file is cut short at byte " + std::to_string(at) + " of " + std::to_string(file_.size()));
      const std::uint8_t op = head[0];
      const std::uint64_t len = le64(head + 1);
      if (len > kMaxRecordBytes) return fault("a record at byte " + std::to_string(at) + " claims " + std::to_string(len) + " bytes (at most 1 GiB read)");
      if (len > file_.size() - at - 9) return fault("the file is cut short inside the record at byte " + std::to_string(at));
      if (op == kDataEnd || op == kFooter) return std::nullopt;
      if (op == kMessage || op == kChunk || op == kChannel || op == kSchema) {
        content.resize(static_cast<std::size_t>(len));
        if (!file_.readAt(at + 9, content.data(), content.size())) return fault("cannot read the record at byte " + std::to_string(at));
        try {
          if (op == kChunk) {
            if (auto f = chunk(content, at, visit)) return f;
          } else {
            record(op, content.data(), content.size(), kUnchunked, at + 9, visit);
          }
        } catch (const ros::MessageError& e) {
          return fault("the record at byte " + std::to_string(at) + " is malformed: " + e.what());
        }
      } else if (op == kHeader && at != 8) {
        return fault("a second header record at byte " + std::to_string(at));
      }
      at += 9 + len;
    }
  }

  const std::vector<ContainerTopic>& topics() const override { return topics_; }
  std::vector<std::string> files() const override { return {file_.path()}; }

  std::vector<std::uint8_t> read(const MessageRef& ref) const override {
    // a: the chunk's record offset (kUnchunked for a lone message), b: the message
    // record's content offset (in the file or the chunk's records), c: its length.
    if (ref.a == kUnchunked) {
      std::vector<std::uint8_t> content(static_cast<std::size_t>(ref.c));
      if (!file_.readAt(ref.b, content.data(), content.size())) throw IoError(file_.path(), "cannot read the message at byte " + std::to_string(ref.b));
      return payload(content.data(), content.size());
    }
    std::vector<std::uint8_t> content;
    try {
      content = cache_.copy(ref.a, ref.b, ref.c, [&] { return declaredSize(ref.a); }, [&] { return unpackAgain(ref.a); });
    } catch (const std::out_of_range& e) {
      throw IoError(file_.path(), e.what());
    }
    return payload(content.data(), content.size());
  }

 private:
  std::optional<ContainerFault> fault(const std::string& what) const { return ContainerFault{file_.path() + ": " + what}; }

  // A message record's data: after channel (2), sequence (4), log and publish time (16).
  static std::vector<std::uint8_t> payload(const std::uint8_t* p, std::size_t n) {
    if (n < 22) throw ros::MessageError("a message record shorter than its fields");
    return {p + 22, p + n};
  }

  void record(std::uint8_t op, const std::uint8_t* p, std::size_t n, std::uint64_t chunk_at, std::uint64_t content_at,
              const std::function<void(const RawMessage&)>& visit) {
    Fields f(p, n);
    if (op == kSchema) {
      const auto id = f.get<std::uint16_t>();
      schemas_[id] = f.str();
    } else if (op == kChannel) {
      const auto id = f.get<std::uint16_t>();
      const auto schema = f.get<std::uint16_t>();
      const std::string topic = f.str();
      const std::string encoding = f.str();
      if (channels_.count(id)) return;  // repeated in a later chunk
      const auto s = schemas_.find(schema);
      const std::string type = s == schemas_.end() ? std::string() : normaliseType(s->second);
      channels_[id] = static_cast<int>(topics_.size());
      topics_.push_back({topic, type, encoding});
    } else if (op == kMessage) {
      const auto channel = f.get<std::uint16_t>();
      (void)f.get<std::uint32_t>();  // sequence
      const auto log_time = f.get<std::uint64_t>();
      (void)f.get<std::uint64_t>();  // publish time
      const auto c = channels_.find(channel);
      if (c == channels_.end()) throw ros::MessageError("a message on channel " + std::to_string(channel) + ", which no channel record declares");
      RawMessage m;
      m.topic = c->second;
      m.log_time_ns = static_cast<std::int64_t>(log_time);
      m.data = f.here();
      m.size = f.left();
      m.ref = {0, chunk_at, content_at, n};
      visit(m);
    }
  }

  // The chunk's records, decompressed and checked; a reason on failure.
  // `reading_again`: for a frame, after the pass over the file (chunk_cache.hpp's bounds).
  std::string unpack(const std::uint8_t* p, std::size_t n, ChunkBytes* records, bool reading_again) const {
    Fields f(p, n);
    (void)f.get<std::uint64_t>();  // message start time
    (void)f.get<std::uint64_t>();  // message end time
    const auto size = f.get<std::uint64_t>();
    const auto crc = f.get<std::uint32_t>();
    const std::string compression = f.str();
    const auto stored = f.get<std::uint64_t>();
    if (stored > f.left()) return "its records run past its end";
    if (std::string over = budget_.charge(size, reading_again); !over.empty()) return over;
    const std::uint8_t* in = f.here();
    // What the declared size is checked against before it is allocated.
    if (compression.empty() && stored != size) {
      return "its uncompressed records are " + std::to_string(stored) + " bytes, not the " + std::to_string(size) + " it declares";
    }
    if (compression == "zstd") {
      const unsigned long long content = ZSTD_getFrameContentSize(in, static_cast<std::size_t>(stored));
      if (content == ZSTD_CONTENTSIZE_ERROR) return "its records are not a zstd frame";
      if (content != ZSTD_CONTENTSIZE_UNKNOWN && content != size) {
        return "its zstd frame holds " + std::to_string(content) + " bytes, not the " + std::to_string(size) + " it declares";
      }
    }
    if (compression == "lz4" && size > stored * 256 + 65536) return "it claims more bytes than lz4 can expand its records to";
    records->resize(static_cast<std::size_t>(size));
    if (compression.empty()) {
      if (size > 0) std::memcpy(records->data(), in, static_cast<std::size_t>(size));
    } else if (compression == "zstd") {
      const std::size_t got = ZSTD_decompress(records->data(), records->size(), in, static_cast<std::size_t>(stored));
      if (ZSTD_isError(got)) return std::string("zstd cannot decompress it (") + ZSTD_getErrorName(got) + ")";
      if (got != size) return "it decompresses to " + std::to_string(got) + " bytes, not " + std::to_string(size);
    } else if (compression == "lz4") {
      if (std::string err = expandLz4Frame(in, static_cast<std::size_t>(stored), records); !err.empty()) return err;
    } else {
      return "its compression \"" + compression + "\" is not one MCAP defines (none, lz4, zstd)";
    }
    if (crc != 0) {
      const auto got = static_cast<std::uint32_t>(::crc32(0L, records->data(), static_cast<uInt>(records->size())));
      if (got != crc) return "its records fail their CRC";
    }
    return {};
  }

  std::optional<ContainerFault> chunk(const std::vector<std::uint8_t>& content, std::uint64_t at,
                                      const std::function<void(const RawMessage&)>& visit) {
    ChunkBytes records;
    const std::string err = unpack(content.data(), content.size(), &records, false);
    if (!err.empty()) return fault("the chunk at byte " + std::to_string(at) + " is unreadable: " + err);
    std::size_t i = 0;
    while (i < records.size()) {
      if (records.size() - i < 9) return fault("the chunk at byte " + std::to_string(at) + " ends inside a record");
      const std::uint8_t op = records[i];
      const std::uint64_t len = le64(records.data() + i + 1);
      if (len > records.size() - i - 9) return fault("the chunk at byte " + std::to_string(at) + " ends inside a record");
      record(op, records.data() + i + 9, static_cast<std::size_t>(len), at, i + 9, visit);
      i += 9 + static_cast<std::size_t>(len);
    }
    return std::nullopt;
  }

  // The uncompressed size the chunk record at `at` declares (0 when it cannot be read).
  std::uint64_t declaredSize(std::uint64_t at) const {
    std::uint8_t head[9 + 24];
    return file_.readAt(at, head, sizeof head) ? le64(head + 9 + 16) : 0;
  }

  // The chunk at `at` decompressed again, for a frame.
  ChunkBytes unpackAgain(std::uint64_t at) const {
    std::uint8_t head[9];
    if (!file_.readAt(at, head, 9) || head[0] != kChunk) throw IoError(file_.path(), "no chunk at byte " + std::to_string(at));
    const std::uint64_t len = le64(head + 1);
    if (len > kMaxRecordBytes || len > file_.size() - at - 9) throw IoError(file_.path(), "the chunk at byte " + std::to_string(at) + " is cut short");
    std::vector<std::uint8_t> content(static_cast<std::size_t>(len));
    if (!file_.readAt(at + 9, content.data(), content.size())) throw IoError(file_.path(), "cannot read the chunk at byte " + std::to_string(at));
    ChunkBytes records;
    std::string err;
    try {
      err = unpack(content.data(), content.size(), &records, true);
    } catch (const ros::MessageError& e) {
      err = e.what();
    }
    if (!err.empty()) throw IoError(file_.path(), "the chunk at byte " + std::to_string(at) + " is unreadable: " + err);
    return records;
  }

  FileReader file_;
  std::map<std::uint16_t, std::string> schemas_;
  std::map<std::uint16_t, int> channels_;
  std::vector<ContainerTopic> topics_;
  InflateBudget budget_;
  ChunkCache cache_;
};

}  // namespace

std::unique_ptr<Container> openMcap(const std::string& path) { return std::make_unique<McapContainer>(path); }

}  // namespace mobmap::sources
