#pragma once
// The apps' errors: IoError is the library's (a file and what is wrong with it);
// UsageError is a mistake on the command line.

#include "mobmap/sources/io_error.hpp"

namespace mobmap::app {

using sources::IoError;
/// A mistake on the command line (exit code 2); the library throws it for an invalid
/// argument too.
using sources::UsageError;

}  // namespace mobmap::app
