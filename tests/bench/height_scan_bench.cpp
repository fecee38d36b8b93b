// Height scans for many robots at once: 1000 random poses over a map, a legged_gym grid
// (17 x 11 points, 0.1 m), on one core. Prints the median of 7 passes of
// MobilityMap::heightScan, what building the surface columns costs once per map
// snapshot (time and memory), and the same scans asked voxel by voxel of the octree
// (a column search down from each pose's height) as the reference.
//   height_scan_bench MAP.ot [POSES=1000]

#include "mobmap/mapping/footholds.hpp"
#include "mobmap/mapping/mobility_map.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

namespace {

using mobmap::mapping::HeightScanGrid;
using mobmap::mapping::HeightScanPose;
using mobmap::mapping::MobilityOcTree;
using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// The slow way: voxel by voxel down each grid point's column from the pose's height.
double columnSearch(const MobilityOcTree& tree, int bottom, const std::vector<HeightScanPose>& poses,
                    const HeightScanGrid& grid) {
  double sum = 0;
  const int nx = grid.nx(), ny = grid.ny();
  for (const HeightScanPose& p : poses) {
    const double c = std::cos(p.yaw), s = std::sin(p.yaw);
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        const double gx = (i - 0.5 * (nx - 1)) * grid.resolution_m, gy = (j - 0.5 * (ny - 1)) * grid.resolution_m;
        octomap::OcTreeKey k;
        if (!tree.coordToKeyChecked(octomap::point3d(static_cast<float>(p.x + c * gx - s * gy),
                                                     static_cast<float>(p.y + s * gx + c * gy), static_cast<float>(p.z)),
                                    k)) {
          continue;
        }
        for (int kz = k[2]; kz >= bottom; --kz) {
          const auto* n = tree.search(octomap::OcTreeKey(k[0], k[1], static_cast<octomap::key_type>(kz)));
          if (n != nullptr && tree.isNodeOccupied(n)) {
            sum += tree.keyToCoord(static_cast<octomap::key_type>(kz)) - p.z;
            break;
          }
        }
      }
    }
  }
  return sum;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || argc > 3) {
    std::fprintf(stderr, "usage: height_scan_bench MAP.ot [POSES=1000]\n");
    return 2;
  }
  const int n_poses = argc == 3 ? std::atoi(argv[2]) : 1000;
  if (n_poses < 1) {
    std::fprintf(stderr, "height_scan_bench: POSES must be a whole number above 0\n");
    return 2;
  }
  const mobmap::mapping::MobilityMap map = mobmap::mapping::openMap(argv[1]);
  double x0, y0, z0, x1, y1, z1;
  map.tree().getMetricMin(x0, y0, z0);
  map.tree().getMetricMax(x1, y1, z1);
  std::mt19937 rng(54);
  std::uniform_real_distribution<double> x(x0, x1), y(y0, y1), z(z0, z1), yaw(-M_PI, M_PI);
  std::vector<HeightScanPose> poses;
  for (int k = 0; k < n_poses; ++k) poses.push_back({x(rng), y(rng), z(rng), yaw(rng)});
  const HeightScanGrid grid;  // 1.6 x 1.0 m at 0.1 m: 17 x 11

  std::vector<double> build_ms;
  std::size_t bytes = 0;
  for (int pass = 0; pass < 5; ++pass) {
    const auto t0 = Clock::now();
    const mobmap::mapping::SurfaceColumns columns(map.tree());
    build_ms.push_back(msSince(t0));
    bytes = columns.memoryBytes();
  }
  (void)map.surfaceColumns();  // kept from here on, as a user's second call finds it

  std::vector<double> scan_ms;
  double sink = 0;
  for (int pass = 0; pass < 7; ++pass) {
    const auto t0 = Clock::now();
    const auto scan = map.heightScan(poses, grid);
    scan_ms.push_back(msSince(t0));
    for (float h : scan.height) sink += std::isnan(h) ? 0.0 : h;
  }
  const int bottom = map.tree().coordToKey(z0);
  std::vector<double> ref_ms;
  for (int pass = 0; pass < 3; ++pass) {
    const auto t0 = Clock::now();
    sink += columnSearch(map.tree(), bottom, poses, grid);
    ref_ms.push_back(msSince(t0));
  }
  const double scan = median(scan_ms), ref = median(ref_ms);
  std::printf("%d poses x %d x %d points on %s\n", n_poses, grid.nx(), grid.ny(), argv[1]);
  std::printf("heightScan:             median %.2f ms (%.1f ns a point)\n", scan,
              1e6 * scan / (static_cast<double>(n_poses) * grid.nx() * grid.ny()));
  std::printf("surface columns, once:  median %.1f ms, %.1f MB kept\n", median(build_ms), bytes / 1e6);
  std::printf("octree column search:   median %.1f ms (%.0fx heightScan)\n", ref, ref / scan);
  std::printf("(checksum %.3f)\n", sink);
  return 0;
}
