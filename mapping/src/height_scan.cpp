// Height scans over the surface columns: one column look-up per grid point.
#include "mobmap/mapping/height_scan.hpp"

#include "mobmap/mapping/footholds.hpp"

#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

namespace mobmap::mapping {
namespace {

// Beyond any map (2^15 voxels of at most 10 m each way), and small enough that a
// voxel key computed from it fits a long.
constexpr double kFar = 1e7;

int pointsAlong(double size_m, double resolution_m) {
  return static_cast<int>(std::lround(size_m / resolution_m)) + 1;
}

}  // namespace

int HeightScanGrid::nx() const { return pointsAlong(length_m, resolution_m); }
int HeightScanGrid::ny() const { return pointsAlong(width_m, resolution_m); }

void checkHeightScanGrid(const HeightScanGrid& grid, std::size_t poses) {
  const auto fail = [](const std::string& what) { throw std::invalid_argument("height scan: " + what); };
  if (!std::isfinite(grid.resolution_m) || !(grid.resolution_m > 0)) {
    fail("resolution must be a finite number above 0, got " + std::to_string(grid.resolution_m));
  }
  if (!std::isfinite(grid.length_m) || !std::isfinite(grid.width_m) || grid.length_m < 0 || grid.width_m < 0) {
    fail("size must be two finite lengths of at least 0, got " + std::to_string(grid.length_m) + " x " +
         std::to_string(grid.width_m));
  }
  if (!std::isfinite(grid.clearance_m) || grid.clearance_m < 0 || grid.clearance_m > kFar) {
    fail("clearance must be a finite height of at least 0, got " + std::to_string(grid.clearance_m));
  }
  const double nx = grid.length_m / grid.resolution_m + 1, ny = grid.width_m / grid.resolution_m + 1;
  if (nx > kMaxHeightScanSide || ny > kMaxHeightScanSide) {
    std::ostringstream m;
    m << "a " << grid.length_m << " x " << grid.width_m << " m grid at " << grid.resolution_m << " m has " << std::llround(nx)
      << " x " << std::llround(ny) << " points; at most " << kMaxHeightScanSide << " a side";
    fail(m.str());
  }
  const double total = static_cast<double>(poses) * static_cast<double>(grid.nx()) * static_cast<double>(grid.ny());
  if (total > static_cast<double>(kMaxHeightScanPoints)) {
    std::ostringstream m;
    m << poses << " poses x " << grid.nx() << " x " << grid.ny() << " points is " << total << " points; at most "
      << kMaxHeightScanPoints << " per call: ask in batches";
    fail(m.str());
  }
}

HeightScan heightScan(const SurfaceColumns& columns, const std::vector<HeightScanPose>& poses, const HeightScanGrid& grid) {
  checkHeightScanGrid(grid, poses.size());
  for (std::size_t p = 0; p < poses.size(); ++p) {
    const HeightScanPose& q = poses[p];
    if (!std::isfinite(q.x) || !std::isfinite(q.y) || !std::isfinite(q.z) || !std::isfinite(q.yaw)) {
      throw std::invalid_argument("height scan: poses[" + std::to_string(p) + "] holds a value that is not finite");
    }
  }
  HeightScan out;
  out.poses = poses.size();
  out.nx = grid.nx();
  out.ny = grid.ny();
  const std::size_t per_pose = static_cast<std::size_t>(out.nx) * static_cast<std::size_t>(out.ny);
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  out.height.assign(per_pose * poses.size(), kNaN);
  out.mobility.assign(per_pose * poses.size(), kNaN);
  const auto& runs = columns.runs();
  const double x_mid = 0.5 * (out.nx - 1), y_mid = 0.5 * (out.ny - 1);
  for (std::size_t p = 0; p < poses.size(); ++p) {
    const HeightScanPose& q = poses[p];
    if (std::abs(q.z) > kFar) continue;  // nothing there: unknown
    const double c = std::cos(q.yaw), s = std::sin(q.yaw);
    const double top_z = q.z + grid.clearance_m;
    const long kz = columns.keyOf(top_z);
    std::size_t at = p * per_pose;
    for (int j = 0; j < out.ny; ++j) {
      const double gy = (j - y_mid) * grid.resolution_m;
      for (int i = 0; i < out.nx; ++i, ++at) {
        const double gx = (i - x_mid) * grid.resolution_m;
        const double x = q.x + c * gx - s * gy, y = q.y + s * gx + c * gy;
        if (std::abs(x) > kFar || std::abs(y) > kFar) continue;
        const long col = columns.columnIndex(columns.keyOf(x), columns.keyOf(y));
        // Runs lie lowest first: the last one starting at or below the clearance's voxel.
        for (std::size_t r = columns.runEnd(col); r > columns.runBegin(col); --r) {
          const SurfaceColumns::Run& run = runs[r - 1];
          if (run.bottom > kz) continue;
          out.height[at] = static_cast<float>(std::min(columns.topFace(run), top_z) - q.z);
          out.mobility[at] = run.mobility;
          break;
        }
      }
    }
  }
  return out;
}

}  // namespace mobmap::mapping
