#pragma once
/// @file foot.hpp
/// A rectangular sole and the points a query samples under it.

#include <vector>

namespace mobmap::mapping {

/// A rectangle sole: centre (x, y, z) in the map frame, yaw about +z (radians), length
/// along the yaw direction, width across, metres.
struct Foot {
  double x = 0, y = 0, z = 0, yaw = 0, length = 0.2, width = 0.1;
};

/// One sample under a sole: its sole coordinates (a along the yaw, b across, from the
/// centre) and where it lies in the map (x, y).
struct SoleSample {
  double a = 0, b = 0, x = 0, y = 0;
};

/// The longest side a sole may have in the front ends' queries (CLI, server, Python),
/// metres: a larger one is refused rather than sampled for seconds.
inline constexpr double kMaxSoleSideM = 10.0;
/// A sole the front ends answer for: both sides in (0, kMaxSoleSideM] (false for NaN).
[[nodiscard]] inline bool soleSizeAllowed(double length_m, double width_m) {
  return length_m > 0 && width_m > 0 && length_m <= kMaxSoleSideM && width_m <= kMaxSoleSideM;
}

/// Longest side of a sole, in voxels, that soleSamples() samples.
inline constexpr double kMaxSoleSamplesPerSide = 10000;

/// The centres of a grid of ceil(length / resolution) x ceil(width / resolution) equal
/// cells covering the sole (at least one each way): one sample per voxel. A 25 x 12 cm
/// sole in a 2 cm map gives 13 x 6 = 78 samples. None when x, y or yaw is not finite,
/// length, width or resolution is not positive, or a side is longer than
/// kMaxSoleSamplesPerSide voxels.
[[nodiscard]] std::vector<SoleSample> soleSamples(const Foot& foot, double resolution);
/// The same into `out` (cleared first; its storage is reused).
void soleSamples(const Foot& foot, double resolution, std::vector<SoleSample>& out);

}  // namespace mobmap::mapping
