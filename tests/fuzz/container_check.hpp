#pragma once
// What the recording fuzz targets check of a file in a container format: the pass over
// it ends or reports a fault, every message it gives reads again to the same bytes, and
// Recording::open opens it or refuses it with IoError, each frame it offers loading or
// failing with IoError. Anything else (a crash, another exception, a mismatch) aborts.
#include "container.hpp"

#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/recording.hpp"

#include <cstdint>
#include <cstdlib>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace mobmap::fuzz {

inline void checkRecording(const std::string& path, std::unique_ptr<sources::Container> (*open)(const std::string&)) {
  using sources::IoError;
  try {
    auto container = open(path);
    std::vector<std::pair<sources::MessageRef, std::vector<std::uint8_t>>> seen;
    (void)container->scan([&](const sources::RawMessage& m) {
      if (static_cast<std::size_t>(m.topic) >= container->topics().size()) std::abort();
      if (seen.size() >= 4096) return;  // the harness's own memory stays bounded
      seen.emplace_back(m.ref, std::vector<std::uint8_t>(m.data, m.data + m.size));
    });
    for (const auto& [ref, bytes] : seen) {
      if (container->read(ref) != bytes) std::abort();
    }
  } catch (const IoError&) {
  } catch (const sources::ros::MessageError&) {
  }
  try {
    const auto rec = sources::Recording::open(path);
    for (int n : rec->frames()) {
      try {
        const auto f = rec->load(n);
        if (f.depth.width != rec->intrinsics().width || f.depth.height != rec->intrinsics().height) std::abort();
      } catch (const IoError&) {
      }
    }
  } catch (const IoError&) {
  }
}

}  // namespace mobmap::fuzz
