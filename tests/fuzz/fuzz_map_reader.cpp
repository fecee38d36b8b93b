// libFuzzer target: arbitrary bytes as a .ot file must give a map or a MapIoError,
// never a crash, hang or unbounded allocation.
#include "mobmap/mapping/mobility_map.hpp"

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // One scratch file per process, removed when the fuzzer exits.
  struct Scratch {
    std::string path = "/tmp/mobmap-fuzz-" + std::to_string(::getpid()) + ".ot";
    ~Scratch() { std::remove(path.c_str()); }
  };
  static const Scratch scratch;
  const std::string& path = scratch.path;
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  try {
    auto tree = mobmap::mapping::loadMobilityMap(path);
    (void)tree->size();
  } catch (const mobmap::mapping::MapIoError&) {
  }
  return 0;
}
