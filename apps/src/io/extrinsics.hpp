#pragma once
// `--extrinsics`: the camera's pose in the frame a sequence's poses are given for; the
// library's (mobmap/sources/adjusted.hpp).

#include "io/sequence.hpp"

#include "mobmap/sources/adjusted.hpp"

namespace mobmap::app {

using sources::extrinsicsText;
using sources::parseExtrinsics;
using sources::withExtrinsics;

}  // namespace mobmap::app
