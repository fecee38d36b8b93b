// libFuzzer target: arbitrary bytes as a ROS 1 bag read without its index (a
// `.bag.active` left by a killed `rosbag record`): the pass over its records must end or
// report a fault, every message it gives must read again to the same bytes, and
// Recording::open must open it or refuse it with IoError; each frame it offers must
// load or fail with IoError. Never a crash, a hang or an unbounded allocation.
#include "container.hpp"
#include "scratch_file.hpp"

#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/recording.hpp"

#include <cstdint>
#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const mobmap::fuzz::ScratchFile scratch("bag.bag.active");
  const std::string& path = scratch.write(data, size);
  using mobmap::sources::IoError;
  try {
    auto bag = mobmap::sources::openRos1Bag(path);
    std::vector<std::pair<mobmap::sources::MessageRef, std::vector<std::uint8_t>>> seen;
    (void)bag->scan([&](const mobmap::sources::RawMessage& m) {
      if (static_cast<std::size_t>(m.topic) >= bag->topics().size()) std::abort();
      if (seen.size() >= 4096) return;  // the harness's own memory stays bounded
      seen.emplace_back(m.ref, std::vector<std::uint8_t>(m.data, m.data + m.size));
    });
    for (const auto& [ref, bytes] : seen) {
      if (bag->read(ref) != bytes) std::abort();
    }
  } catch (const IoError&) {
  } catch (const mobmap::sources::ros::MessageError&) {
  }
  try {
    const auto rec = mobmap::sources::Recording::open(path);
    for (int n : rec->frames()) {
      try {
        const auto f = rec->load(n);
        if (f.depth.width != rec->intrinsics().width || f.depth.height != rec->intrinsics().height) std::abort();
      } catch (const IoError&) {
      }
    }
  } catch (const IoError&) {
  }
  return 0;
}
