// Recordings from hostile or crashed writers: an MCAP decompression bomb, chunks that
// expand far beyond what they store, a .db3 whose messages are a view or a computed
// column, a ROS 2 recorder killed in WAL mode (no metadata.yaml, half the messages in the
// -wal), a `rosbag record` killed mid-run (.bag.active). Each is read as far as it can
// be, or refused naming the file and the problem, within bounded memory.
#include "bags_support.hpp"

#include <set>

namespace mobmap::cli_test {
namespace {

void putLe(std::string& out, std::uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
}
void mcapRecord(std::string& out, std::uint8_t op, const std::string& content) {
  out.push_back(static_cast<char>(op));
  putLe(out, content.size(), 8);
  out += content;
}
std::string mcapString(const std::string& s) {
  std::string out;
  putLe(out, s.size(), 4);
  return out + s;
}
// A zstd frame (RFC 8878) of `bytes` zero bytes made of run-length blocks: 4 bytes a
// 128 KiB block, what an attacker writes to expand the most from the least.
std::string zstdZeros(std::uint64_t bytes) {
  std::string f;
  putLe(f, 0xFD2FB528, 4);
  f.push_back(static_cast<char>(0xE0));  // 8-byte content size, single segment
  putLe(f, bytes, 8);
  for (std::uint64_t left = bytes; left > 0;) {
    const std::uint64_t n = std::min<std::uint64_t>(left, 128 * 1024);
    left -= n;
    putLe(f, (n << 3) | (1 << 1) | (left == 0 ? 1 : 0), 3);  // RLE block, last or not
    f.push_back('\0');
  }
  return f;
}
// An MCAP file of `chunks` zstd chunks, each declaring and expanding to `bytes` of
// zero-length records of opcode 0 (which readers skip), with no CRC.
std::string mcapBomb(int chunks, std::uint64_t bytes) {
  std::string out("\x89MCAP0\r\n", 8);
  mcapRecord(out, 0x01, mcapString("") + mcapString("bomb"));
  const std::string frame = zstdZeros(bytes);
  for (int i = 0; i < chunks; ++i) {
    std::string chunk;
    putLe(chunk, 0, 8);
    putLe(chunk, 0, 8);
    putLe(chunk, bytes, 8);
    putLe(chunk, 0, 4);  // no CRC
    chunk += mcapString("zstd");
    putLe(chunk, frame.size(), 8);
    chunk += frame;
    mcapRecord(out, 0x06, chunk);
  }
  mcapRecord(out, 0x0F, std::string(4, '\0'));
  return out;
}

// A bomb: 1 MB of chunks that would expand to 30 GiB (240 x 128 MiB, the largest chunk
// read). The pass over it stops at its budget, says why, and stays within 512 MB; a chunk
// claiming more than 128 MiB is refused as it is met.
TEST_F(Bags, AnMcapDecompressionBombStopsAtItsBudgetWithinBoundedMemory) {
  const std::uint64_t most = 128ULL * 1024 * 1024 - 8;  // the largest multiple of 9 (a record) in 128 MiB
  const std::string bomb = dir_ + "/bomb.mcap";
  std::ofstream(bomb, std::ios::binary) << mcapBomb(240, most);
  ASSERT_LT(fs::file_size(bomb), 1024 * 1024u);
  const Result info = run("info " + bomb);
  EXPECT_EQ(info.code, 0) << info.out;
  EXPECT_NE(info.out.find("warning: the recording ends early (" + bomb + ": the chunk at byte "), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("a decompression bomb, or chunks far beyond any recorder's"), std::string::npos) << info.out;
  const long info_kib = peakRssKib("info " + bomb);
  EXPECT_GT(info_kib, 0);
  EXPECT_LT(info_kib, 512 * 1024) << "info: " << info_kib << " KiB";
  const Result b = build(bomb, dir_ + "/bomb.ot");
  EXPECT_EQ(b.code, 1) << b.out;
  EXPECT_NE(b.out.find("error: " + bomb + ": has no depth image topic"), std::string::npos) << b.out;
  EXPECT_NE(b.out.find("; the recording ends early (" + bomb + ": the chunk at byte "), std::string::npos) << b.out;
  EXPECT_FALSE(fs::exists(dir_ + "/bomb.ot"));

  const std::string huge = dir_ + "/huge-chunk.mcap";
  std::ofstream(huge, std::ios::binary) << mcapBomb(1, 1ULL << 30);
  const Result h = run("info " + huge + " --json");
  EXPECT_EQ(h.code, 0) << h.out;
  EXPECT_NE(jsonLine(h.out)["fault"].get<std::string>().find("claims 1073741824 bytes uncompressed (mobmap reads chunks of at most 128 MiB)"),
            std::string::npos)
      << h.out;
}

// 94 KB of zstd chunks that expand to 18 million valid 1 x 1 depth images (1 GiB, within
// the decompression budget): what the index holds stops at 64 MiB + 16 times the file's
// size, so `info` and `build` stay within 512 MB (the index alone took 860 MB before) and
// say why the recording ended there. Large images that compress to nothing are bounded
// by the pixels they decode to.
TEST_F(Bags, MillionsOfTinyMessagesStopAtTheIndexBound) {
  const std::string flood = dir_ + "/flood.mcap";
  const Result w = runShell("node " + kFixtures + "/write_flood.mjs --out " + flood + " --chunks 32 --mib 32");
  ASSERT_EQ(w.code, 0) << w.out;
  ASSERT_LT(fs::file_size(flood), 1024 * 1024u);
  const Result info = run("info " + flood + " --json");
  ASSERT_EQ(info.code, 0) << info.out;
  EXPECT_NE(jsonLine(info.out)["fault"].get<std::string>().find("indexing it would hold more than 65 MiB (64 MiB + 16 times its"),
            std::string::npos)
      << info.out;
  const long info_kib = peakRssKib("info " + flood);
  EXPECT_GT(info_kib, 0);
  EXPECT_LT(info_kib, 512 * 1024) << "info: " << info_kib << " KiB";
  const Result b = build(flood, dir_ + "/flood.ot", "--intrinsics 1,1,0.5,0.5");
  EXPECT_EQ(b.code, 1) << b.out;
  EXPECT_NE(b.out.find("indexing it would hold more than"), std::string::npos) << b.out;
  // 34 KB that expand to 40 depth images of 2048 x 2048 (160 Mi pixels to decode and
  // perceive): the images are read up to 16 Mi pixels + 16 a stored byte, the first 4.
  const std::string large = dir_ + "/large-frames.mcap";
  const Result wl = runShell("node " + kFixtures + "/write_flood.mjs --out " + large + " --chunks 40 --mib 9 --side 2048");
  ASSERT_EQ(wl.code, 0) << wl.out;
  const Result l = build(large, dir_ + "/large.ot", "--intrinsics 1000,1000,1024,1024");
  EXPECT_EQ(l.code, 1) << l.out;  // no TF: the reason, and where the recording ended
  EXPECT_NE(l.out.find("its 40 depth images of 2048x2048 would decode to more than"), std::string::npos) << l.out;
  EXPECT_NE(l.out.find("the first 4 are read"), std::string::npos) << l.out;
}

// Chunks of 48 MiB that store a few hundred KiB (a frame and 48 MiB of zeros): the frames
// are read again from a cache of at most 64 MiB of chunks, so a build holds one such
// chunk at a time (four at once before: 192 MiB), and maps what the frames alone map.
TEST_F(Bags, ChunksKeptForReadingAgainStayWithinTheirBound) {
  const std::string padded = writeBag("padded.mcap", "--pad-mib 48");
  const std::string plain = writeBag("unpadded.mcap", "");
  ASSERT_LT(fs::file_size(padded), 4 * 1024 * 1024u);
  const long with = peakRssKib("build " + padded + " --out " + dir_ + "/padded.ot" + kBuild);
  const long without = peakRssKib("build " + plain + " --out " + dir_ + "/unpadded.ot" + kBuild);
  ASSERT_GT(with, 0);
  ASSERT_GT(without, 0);
  EXPECT_LT(with - without, 100 * 1024) << "build: " << with << " KiB with 48 MiB chunks, " << without << " KiB without";
  EXPECT_EQ(fileBytes(dir_ + "/padded.ot"), fileBytes(ref()));
  const long info_with = peakRssKib("info " + padded), info_without = peakRssKib("info " + plain);
  EXPECT_LT(info_with - info_without, 100 * 1024) << "info: " << info_with << " KiB, " << info_without << " KiB";
}

// A .db3 is rosbag2's tables: a `messages` that is a view (here over an endless
// recursive query, which ran forever before) or a table with a computed column is
// refused before a row is read.
TEST_F(Bags, ADb3WhoseMessagesAreComputedIsRefusedUnread) {
  const std::string topics =
      "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT, type TEXT, serialization_format TEXT, offered_qos_profiles TEXT);"
      "INSERT INTO topics VALUES (1, '/camera/depth/image_raw', 'sensor_msgs/msg/Image', 'cdr', '');";
  const std::vector<std::array<std::string, 3>> cases = {
      {"view", "CREATE VIEW messages AS WITH RECURSIVE n(x) AS (SELECT 1 UNION ALL SELECT x + 1 FROM n) "
               "SELECT x AS id, 1 AS topic_id, x AS timestamp, zeroblob(16) AS data FROM n;",
       "its messages is a view, not a table"},
      {"generated", "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER, timestamp INTEGER, "
                    "data BLOB GENERATED ALWAYS AS (zeroblob(100000000)) VIRTUAL);"
                    "INSERT INTO messages(topic_id, timestamp) VALUES (1, 1), (1, 2);",
       "its messages table computes its column data"},
      {"without-rowid", "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER, timestamp INTEGER, data BLOB) WITHOUT ROWID;",
       "not a ROS 2 bag database"},
  };
  for (const auto& [name, sql, expect] : cases) {
    SCOPED_TRACE(name);
    const std::string db = dir_ + "/" + name + ".db3";
    fs::remove(db);
    const Result made = runShell("python3 -c \"import sqlite3, sys; c = sqlite3.connect(sys.argv[1]); c.executescript(sys.argv[2]); c.commit()\" " +
                                 db + " \"" + topics + sql + "\"");
    ASSERT_EQ(made.code, 0) << made.out;
    for (const std::string& command : {"info " + db, "build " + db + " --out " + dir_ + "/computed.ot" + kBuild}) {
      const Result r = run(command);
      EXPECT_EQ(r.code, 1) << r.out;
      EXPECT_NE(r.out.find("error: " + db + ": "), std::string::npos) << r.out;
      EXPECT_NE(r.out.find(expect), std::string::npos) << r.out;
    }
  }
}

// The files in a folder, with their sizes and times: what reading must leave as it was.
std::map<std::string, std::pair<std::uintmax_t, fs::file_time_type>> listing(const std::string& dir) {
  std::map<std::string, std::pair<std::uintmax_t, fs::file_time_type>> out;
  for (const auto& e : fs::directory_iterator(dir)) out[e.path().filename().string()] = {e.file_size(), e.last_write_time()};
  return out;
}

// rosbag2 killed in WAL mode: the .db3 holds the first half of the messages, its -wal
// the rest (and a batch never committed), no metadata.yaml. The folder and the .db3
// alone build every frame, the map of the whole recording byte for byte, with a warning
// that says what was recovered; nothing is written beside the files (no -shm).
TEST_F(Bags, ACrashedRos2RecordingBuildsEveryFrameFromItsLog) {
  const std::string feed = dir_ + "/crashed.jsonl";
  writeBag("crashed", "--feed " + feed + " --layout base");
  const std::string bag = dir_ + "/crashed";
  fs::remove_all(bag);
  const Result made = runShell("python3 " + kFixtures + "/make_db3.py " + feed + " " + bag + " --killed");
  ASSERT_EQ(made.code, 0) << made.out;
  ASSERT_FALSE(fs::exists(bag + "/metadata.yaml"));
  ASSERT_GT(fs::file_size(bag + "/crashed_0.db3-wal"), 1024u * 1024u);
  fs::remove(bag + "/crashed_0.db3-shm");  // left or not by a killed writer: not needed
  const auto before = listing(bag);
  for (const std::string& input : {bag, bag + "/crashed_0.db3"}) {
    SCOPED_TRACE(input);
    const Result info = run("info " + input + " --json");
    ASSERT_EQ(info.code, 0) << info.out;
    const std::string recovered = jsonLine(info.out)["recovered"].get<std::string>();
    EXPECT_NE(recovered.find("messages recovered from crashed_0.db3-wal"), std::string::npos) << recovered;
    EXPECT_NE(recovered.find("pages of an unfinished commit left out"), std::string::npos) << recovered;
    EXPECT_EQ(recovered.find("no metadata.yaml") != std::string::npos, input == bag) << recovered;
    EXPECT_EQ(jsonLine(info.out)["frames"], 12);
    const Result r = build(input, dir_ + "/crashed.ot", "--force");
    ASSERT_EQ(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("warning: a recording its recorder did not finish, recovered: "), std::string::npos) << r.out;
    EXPECT_EQ(fileBytes(dir_ + "/crashed.ot"), fileBytes(ref()));
    const auto meta = nlohmann::json::parse(fileBytes(dir_ + "/crashed.json"));
    EXPECT_EQ(meta["frames"], 12);
    EXPECT_NE(meta["recovered"].get<std::string>().find("recovered from crashed_0.db3-wal"), std::string::npos);
    EXPECT_EQ(listing(bag), before) << "reading wrote beside the recording";
  }
  // Without its log, the database alone holds only the frames merged before the crash.
  fs::create_directories(dir_ + "/merged-only");
  fs::copy_file(bag + "/crashed_0.db3", dir_ + "/merged-only/crashed_0.db3", fs::copy_options::overwrite_existing);
  const Result half = run("info " + dir_ + "/merged-only/crashed_0.db3 --json");
  ASSERT_EQ(half.code, 0) << half.out;
  EXPECT_LT(jsonLine(half.out)["images"].get<int>(), 12);
  EXPECT_FALSE(jsonLine(half.out).contains("recovered"));
}

// A `rosbag record` killed mid-run leaves NAME.bag.active: no index, the chunk being
// written unfinished, what rosbag had not handed to the OS lost. Its chunks are read in
// order; every image before the kill but the last one or two (still in rosbag's buffers)
// is mapped, and the map is the 7-Scenes layout's of those frames, byte for byte.
TEST_F(Bags, AKilledRosbagRecordsActiveBagBuildsTheFramesItHolds) {
#ifndef MOBMAP_WRITE_BAG1
  GTEST_SKIP() << "the ROS 1 bag writer is not built (librosbag-storage-dev is not installed)";
#else
  // Uncompressed in 4 MiB chunks, the kill comes inside the second chunk (its sizes still
  // the placeholders rosbag writes first): read up to its last whole message.
  for (const std::string compression : {"none", "lz4", "bz2", "unfinished"}) {
    SCOPED_TRACE(compression);
    const std::string bag = dir_ + "/killed-" + compression + ".bag.active";
    const std::string options = compression == "unfinished" ? "--compression none --chunk-kb 4096" : "--compression " + compression;
    const Result w = runShell(std::string(MOBMAP_WRITE_BAG1) + " --seq " + dir_ + "/seq --out " + bag + " " + options +
                              " --layout base --killed-after 9");
    ASSERT_EQ(w.code, 0) << w.out;
    const Result info = run("info " + bag + " --json");
    ASSERT_EQ(info.code, 0) << info.out;
    EXPECT_EQ(jsonLine(info.out)["format"], "ROS 1 bag");
    EXPECT_NE(jsonLine(info.out)["recovered"].get<std::string>().find("a ROS 1 bag without its index"), std::string::npos) << info.out;
    const std::string out = dir_ + "/killed-" + compression + ".ot";
    const Result r = build(bag, out);
    ASSERT_EQ(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("warning: a recording its recorder did not finish, recovered: " + bag), std::string::npos) << r.out;
    if (compression == "unfinished") {
      EXPECT_NE(r.out.find("was never finished (its recorder was killed while writing it)"), std::string::npos) << r.out;
    }
    const auto meta = nlohmann::json::parse(fileBytes(dir_ + "/killed-" + compression + ".json"));
    const int frames = meta["frames"].get<int>();
    EXPECT_GE(frames, 7);
    EXPECT_LE(frames, 9);
    const Result same = run("build " + dir_ + "/seq --out " + dir_ + "/killed-ref.ot --frames 0:" + std::to_string(frames - 1) + kBuild +
                            " --force");
    ASSERT_EQ(same.code, 0) << same.out;
    EXPECT_EQ(fileBytes(out), fileBytes(dir_ + "/killed-ref.ot"));
  }
#endif
}

}  // namespace
}  // namespace mobmap::cli_test
