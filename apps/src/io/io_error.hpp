#pragma once
// The apps' errors: IoError is the library's (a file and what is wrong with it);
// UsageError is a mistake on the command line.

#include "mobmap/sources/io_error.hpp"

#include <stdexcept>

namespace mobmap::app {

using sources::IoError;

/// A mistake on the command line (exit code 2).
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace mobmap::app
