#pragma once
// Errors of the readers: IoError for a file (the message starts with its path and says
// what is wrong with it); a caller's value they cannot take (an intrinsics spec) is a
// util::FieldError naming the field.

#include "mobmap/util/field_error.hpp"

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
