#pragma once
/// @file height_scan.hpp
/// Height scans: the surface around a robot's base sampled on a grid that turns with the
/// robot, as learned locomotion policies read the terrain (legged_gym: 17 x 11 points
/// 0.1 m apart over 1.6 x 1.0 m). Many poses at once, for many robots.

#include <cstddef>
#include <vector>

namespace mobmap::mapping {

class SurfaceColumns;

/// The grid, in the pose's frame: x along its yaw, y to its left, centred on the pose.
/// nx = length / resolution + 1 points along x, ny = width / resolution + 1 along y
/// (rounded to the nearest whole number of steps).
struct HeightScanGrid {
  double length_m = 1.6;
  double width_m = 1.0;
  double resolution_m = 0.1;
  [[nodiscard]] int nx() const;
  [[nodiscard]] int ny() const;
};

/// A base pose: position (map frame, z up) and heading (radians about +z, 0 along +x).
struct HeightScanPose {
  double x = 0, y = 0, z = 0, yaw = 0;
};

/// Points one call may ask for (poses x grid points): 50 million (~400 MB of answers).
inline constexpr std::size_t kMaxHeightScanPoints = 50'000'000;
/// Grid points along one side at most.
inline constexpr int kMaxHeightScanSide = 10'000;

/// For each pose and grid point, the surface a foot lowered from the pose's height meets:
/// the highest occupied voxel in that column at or below z, taken up to the top of its
/// run of occupied voxels but no higher than z (a wall or box the base is level with
/// reads 0). Arrays of shape (poses, ny, nx), x varying fastest.
struct HeightScan {
  std::size_t poses = 0;
  int ny = 0, nx = 0;
  /// The surface's height minus the pose's z (metres, <= 0); NaN where the column holds
  /// nothing at or below z (unknown).
  std::vector<float> height;
  /// The mobility of that surface: its run's top voxel's, or failing that the highest
  /// one below it in the run; NaN where unknown or never scored.
  std::vector<float> mobility;
};

/// std::invalid_argument naming the problem: a size or resolution not finite, a
/// resolution not above 0, a size below 0, more than kMaxHeightScanSide points a side, or
/// more than kMaxHeightScanPoints in all for `poses` poses.
void checkHeightScanGrid(const HeightScanGrid& grid, std::size_t poses);

/// Scans every pose over `columns` (built once per map snapshot; MobilityMap keeps one).
/// std::invalid_argument for a bad grid (checkHeightScanGrid) or a pose with a value that
/// is not finite (naming its index). No pose: an empty scan.
[[nodiscard]] HeightScan heightScan(const SurfaceColumns& columns, const std::vector<HeightScanPose>& poses,
                                    const HeightScanGrid& grid);

}  // namespace mobmap::mapping
