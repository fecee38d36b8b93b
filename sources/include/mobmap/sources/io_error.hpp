#pragma once
// Errors of the readers: IoError for a file (the message starts with its path and says
// what is wrong with it), UsageError for a caller's argument (an intrinsics spec).

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

/// An argument that is not valid ("--intrinsics must be fx,fy,cx,cy or a camera file");
/// the command-line tool reports it as a usage mistake.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace mobmap::sources
