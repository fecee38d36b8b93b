#pragma once
// The library's depth inputs (mobmap/sources/sequence.hpp) under the names the commands
// use; `--depth-scale` (withDepthScale) is in depth_checks.hpp.

#include "io/depth_checks.hpp"
#include "io/png_io.hpp"

#include "mobmap/sources/frame.hpp"
#include "mobmap/sources/sequence.hpp"

namespace mobmap::app {

using sources::Frame;
using sources::openSequence;
using sources::RecordingChoice;
using sources::Sequence;
using sources::SequenceOptions;

}  // namespace mobmap::app
