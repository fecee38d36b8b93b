// libFuzzer target: arbitrary bytes as a ROS 2 bag's .db3 (an SQLite database, hostile
// or corrupt). Opening and indexing must succeed or fail with IoError, every frame
// offered must load or fail with IoError; SQLite opens it read-only and immutable.
#include "scratch_file.hpp"

#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/recording.hpp"

#include <cstdint>
#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const mobmap::fuzz::ScratchFile scratch("bag.db3");
  const std::string& path = scratch.write(data, size);
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
  return 0;
}
