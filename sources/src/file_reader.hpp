#pragma once
// A file read at given offsets (pread), from several threads at once.

#include <cstddef>
#include <cstdint>
#include <string>

namespace mobmap::sources {

class FileReader {
 public:
  /// IoError naming `path` if it cannot be opened.
  explicit FileReader(const std::string& path);
  ~FileReader();
  FileReader(const FileReader&) = delete;
  FileReader& operator=(const FileReader&) = delete;

  /// Reads exactly `n` bytes at `offset`; false when the file ends first or a read fails.
  bool readAt(std::uint64_t offset, void* out, std::size_t n) const;
  [[nodiscard]] std::uint64_t size() const { return size_; }
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  std::string path_;
  int fd_ = -1;
  std::uint64_t size_ = 0;
};

}  // namespace mobmap::sources
