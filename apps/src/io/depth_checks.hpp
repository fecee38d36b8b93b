#pragma once
// Checks of depth against what depth cameras see (the library's:
// mobmap/builder/depth_checks.hpp) and `--depth-scale` (mobmap/sources/adjusted.hpp).

#include "mobmap/builder/depth_checks.hpp"
#include "mobmap/sources/adjusted.hpp"

namespace mobmap::app {

using builder::DepthCheckTally;
using builder::depthUnitProblem;
using builder::floorCutProblem;
using builder::kPlausibleMedianMax;
using builder::kPlausibleMedianMin;
using builder::LowZeroBits;
using builder::lowZeroBits;
using builder::rangeCutProblem;
using builder::rangeToSuggest;
using sources::DepthUnit;
using sources::depthRescaleFactor;
using sources::rescaleDepth;
using sources::scaleDepth;
using sources::scaleFrame;
using sources::withDepthScale;

}  // namespace mobmap::app
