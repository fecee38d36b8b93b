// libFuzzer target: arbitrary bytes as a ROS 2 bag's .db3 (an SQLite database, hostile
// or corrupt), optionally with a write-ahead log beside it: an input that starts with
// "WAL1" and a 4-byte little-endian length holds that many bytes of database, and the
// rest is its -wal (what a killed recorder leaves). Opening and indexing must succeed or
// fail with IoError, every frame offered must load or fail with IoError; nothing may be
// written beside the files.
#include "scratch_file.hpp"

#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/recording.hpp"

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const mobmap::fuzz::ScratchFile scratch("bag.db3");
  static const mobmap::fuzz::ScratchFile log("bag.db3-wal");
  std::size_t db_size = size;
  if (size >= 8 && std::memcmp(data, "WAL1", 4) == 0) {
    std::uint32_t n = 0;
    for (int i = 0; i < 4; ++i) n |= static_cast<std::uint32_t>(data[4 + i]) << (8 * i);
    db_size = std::min<std::size_t>(n, size - 8);
    data += 8;
    size -= 8;
    log.write(data + db_size, size - db_size);
  } else {
    std::filesystem::remove(log.path());
  }
  const std::string& path = scratch.write(data, db_size);
  using mobmap::sources::IoError;
  try {
    const auto rec = mobmap::sources::Recording::open(path);
    for (int n : rec->frames()) {
      try {
        const auto f = rec->load(n);
        if (f.depth.width != rec->intrinsics().width) std::abort();
      } catch (const IoError&) {
      }
    }
  } catch (const IoError&) {
  }
  if (std::filesystem::exists(path + "-shm") || std::filesystem::exists(path + "-journal")) std::abort();  // written beside it
  return 0;
}
