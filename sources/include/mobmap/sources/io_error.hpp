#pragma once
// Errors of the readers and writers of files: the message always starts with the path
// and says what is wrong with it.

#include <stdexcept>
#include <string>

namespace mobmap::sources {

/// An I/O or format error: "<path>: <reason>".
class IoError : public std::runtime_error {
 public:
  IoError(const std::string& path, const std::string& reason)
      : std::runtime_error(path + ": " + reason), path_(path), reason_(reason) {}
  [[nodiscard]] const std::string& path() const { return path_; }
  [[nodiscard]] const std::string& reason() const { return reason_; }

 private:
  std::string path_;
  std::string reason_;
};

}  // namespace mobmap::sources
