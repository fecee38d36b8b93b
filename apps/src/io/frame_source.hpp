#pragma once
// One frame for `mobmap analyze` and what is done with it before and after the pipeline:
// the library's (mobmap/builder/frames.hpp).

#include "io/sequence.hpp"

#include "mobmap/builder/frames.hpp"

namespace mobmap::app {

using builder::decodeDepthFormat;
using builder::describeGround;
using builder::GroundExtent;
using builder::groundChoiceNote;
using builder::groundExtent;
using builder::kFarGroundM;
using builder::loadSequenceFrame;
using builder::loadSingleFrame;
using builder::parseVector3;
using builder::perceiveFrame;
using builder::toInputFrame;

}  // namespace mobmap::app
