// libFuzzer target: arbitrary bytes as a .ot file must give a map or a MapIoError,
// never a crash, hang or unbounded allocation.
#include "scratch_file.hpp"

#include "mobmap/mapping/mobility_map.hpp"

#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const mobmap::fuzz::ScratchFile scratch("map.ot");
  const std::string& path = scratch.write(data, size);
  try {
    auto tree = mobmap::mapping::loadMobilityMap(path);
    (void)tree->size();
  } catch (const mobmap::mapping::MapIoError&) {
  }
  return 0;
}
