#pragma once
/// @file height_scan.hpp
/// Height scans: the surface around a robot's base sampled on a grid that turns with the
/// robot, as learned locomotion policies read the terrain (legged_gym: 17 x 11 points
/// 0.1 m apart over 1.6 x 1.0 m). Many poses at once, for many robots.

#include <cstddef>
#include <vector>

namespace mobmap::mapping {

class SurfaceColumns;

/// The height above a pose up to which a scan reports surfaces by default: the layers'
/// robot height (`level_clearance_m`), 1 m.
inline constexpr double kDefaultScanClearanceM = 1.0;

/// The grid, in the pose's frame: x along its yaw, y to its left, centred on the pose.
/// nx = length / resolution + 1 points along x, ny = width / resolution + 1 along y
/// (rounded to the nearest whole number of steps).
struct HeightScanGrid {
  double length_m = 1.6;
  double width_m = 1.0;
  double resolution_m = 0.1;
  /// Surfaces are reported up to this height above the pose (m, >= 0); what lies wholly
  /// above it is overhead (a ceiling, a table the robot walks under) and left out.
  double clearance_m = kDefaultScanClearanceM;
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

/// For each pose and grid point, the terrain a policy trained on height fields expects:
/// the highest occupied voxel in that column at or below z + clearance_m, taken up to the
/// top of its run of occupied voxels but no higher than z + clearance_m. So the treads of
/// a staircase rising ahead of the pose read their heights up to the clearance, a wall
/// reads z + clearance_m, and a ceiling or overhang wholly above the clearance is not
/// seen. Arrays of shape (poses, ny, nx), x varying fastest.
struct HeightScan {
  std::size_t poses = 0;
  int ny = 0, nx = 0;
  /// The surface's height minus the pose's z (metres, <= clearance_m); NaN where the
  /// column holds nothing at or below z + clearance_m (unknown).
  std::vector<float> height;
  /// The mobility of that surface: its run's top voxel's, or failing that the highest
  /// one below it in the run; NaN where unknown or never scored.
  std::vector<float> mobility;
};

/// std::invalid_argument naming the problem: a size or resolution not finite, a
/// resolution not above 0, a size below 0, a clearance not finite or below 0, more than kMaxHeightScanSide points a side, or
/// more than kMaxHeightScanPoints in all for `poses` poses.
void checkHeightScanGrid(const HeightScanGrid& grid, std::size_t poses);

/// Scans every pose over `columns` (built once per map snapshot; MobilityMap keeps one).
/// std::invalid_argument for a bad grid (checkHeightScanGrid) or a pose with a value that
/// is not finite (naming its index). No pose: an empty scan.
[[nodiscard]] HeightScan heightScan(const SurfaceColumns& columns, const std::vector<HeightScanPose>& poses,
                                    const HeightScanGrid& grid);

}  // namespace mobmap::mapping
