// libFuzzer target: arbitrary bytes as an .mcap file, checked as container_check.hpp
// says. Never a crash, a hang or an unbounded allocation.
#include "container_check.hpp"
#include "scratch_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const mobmap::fuzz::ScratchFile scratch("bag.mcap");
  mobmap::fuzz::checkRecording(scratch.write(data, size), &mobmap::sources::openMcap);
  return 0;
}
