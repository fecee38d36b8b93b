#pragma once
// For the fuzz targets that read files: each input goes to one scratch file per
// process, which is removed when the fuzzer exits.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>

namespace mobmap::fuzz {

class ScratchFile {
 public:
  /// /tmp/mobmap-fuzz-PID-NAME, e.g. NAME "map.ot".
  explicit ScratchFile(const std::string& name)
      : path_("/tmp/mobmap-fuzz-" + std::to_string(::getpid()) + "-" + name) {}
  ScratchFile(const ScratchFile&) = delete;
  ScratchFile& operator=(const ScratchFile&) = delete;
  ~ScratchFile() { std::remove(path_.c_str()); }

  /// Replaces the file's contents with `data`; returns its path.
  const std::string& write(const std::uint8_t* data, std::size_t size) const {
    std::ofstream out(path_, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    return path_;
  }
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  std::string path_;
};

}  // namespace mobmap::fuzz
