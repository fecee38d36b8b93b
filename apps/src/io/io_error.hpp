#pragma once
// The apps' errors: IoError is the library's (a file and what is wrong with it);
// UsageError is a mistake on the command line. A value the library cannot take
// (util::FieldError) is a usage mistake too, reported with its field's flag (cli_text.hpp).

#include "mobmap/sources/io_error.hpp"
#include "mobmap/util/field_error.hpp"

#include <stdexcept>

namespace mobmap::app {

using sources::IoError;
using util::FieldError;

/// A mistake on the command line (exit code 2): its message names the flag.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace mobmap::app
