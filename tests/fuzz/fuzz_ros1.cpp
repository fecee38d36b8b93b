// libFuzzer target: arbitrary bytes as a ROS 1 bag read without its index (a
// `.bag.active` left by a killed `rosbag record`), checked as container_check.hpp says.
// Never a crash, a hang or an unbounded allocation.
#include "container_check.hpp"
#include "scratch_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const mobmap::fuzz::ScratchFile scratch("bag.bag.active");
  mobmap::fuzz::checkRecording(scratch.write(data, size), &mobmap::sources::openRos1Bag);
  return 0;
}
