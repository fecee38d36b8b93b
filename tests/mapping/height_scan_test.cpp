// Height scans against a brute-force column search in the octree, on the analytic voxel
// scene: floors, stair treads, beside and under a table, on it, against walls.
#include "mobmap/mapping/height_scan.hpp"
#include "mobmap/mapping/mobility_map.hpp"
#include "voxel_scene.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <random>

namespace mobmap::mapping {
namespace {

// The scene as a MobilityMap (a copy voxel by voxel: octomap's copy drops the payload).
MobilityMap sceneMap() {
  const Scene s;
  auto copy = std::make_unique<MobilityOcTree>(kRes);
  for (auto it = s.tree.begin_leafs(); it != s.tree.end_leafs(); ++it) copy->updateNode(it.getKey(), true)->copyData(*it);
  MapParams mp;
  mp.resolution_m = kRes;
  return MobilityMap(std::move(copy), mp, Eigen::Matrix3d::Identity());
}

// One grid point the slow way: voxel by voxel down the column from the clearance above
// the pose to the bottom of the map, then up the run to its top, and down the run for a
// mobility.
std::pair<float, float> bruteForce(const MobilityOcTree& tree, int bottom, double x, double y, double z, double clearance) {
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  const double top_z = z + clearance;
  octomap::OcTreeKey k;
  if (!tree.coordToKeyChecked(octomap::point3d(static_cast<float>(x), static_cast<float>(y), static_cast<float>(top_z)), k)) {
    return {kNaN, kNaN};
  }
  const auto occupied = [&](int kz) {
    const auto* n = tree.search(octomap::OcTreeKey(k[0], k[1], static_cast<octomap::key_type>(kz)));
    return n != nullptr && tree.isNodeOccupied(n);
  };
  for (int kz = k[2]; kz >= bottom; --kz) {
    if (!occupied(kz)) continue;
    int top = kz;
    while (occupied(top + 1)) ++top;
    const double top_face = tree.keyToCoord(static_cast<octomap::key_type>(top)) + kRes / 2;
    float mobility = kNaN;
    for (int m = top; m >= kz - 1000 && occupied(m); --m) {
      const auto* n = tree.search(octomap::OcTreeKey(k[0], k[1], static_cast<octomap::key_type>(m)));
      if (n->hasMobility()) {
        mobility = static_cast<float>(n->mobility());
        break;
      }
    }
    return {static_cast<float>(std::min(top_face, top_z) - z), mobility};
  }
  return {kNaN, kNaN};
}

void expectSameAsBruteForce(const MobilityMap& map, const std::vector<HeightScanPose>& poses, const HeightScanGrid& grid) {
  const HeightScan scan = map.heightScan(poses, grid);
  // The lowest voxel key of the map (the const getMetricMin walks every leaf: ask once).
  double min_x, min_y, min_z;
  map.tree().getMetricMin(min_x, min_y, min_z);
  const int bottom = map.tree().coordToKey(min_z);
  ASSERT_EQ(scan.poses, poses.size());
  ASSERT_EQ(scan.height.size(), poses.size() * static_cast<std::size_t>(scan.nx * scan.ny));
  std::size_t at = 0;
  for (const HeightScanPose& p : poses) {
    for (int j = 0; j < scan.ny; ++j) {
      for (int i = 0; i < scan.nx; ++i, ++at) {
        const double gx = (i - 0.5 * (scan.nx - 1)) * grid.resolution_m, gy = (j - 0.5 * (scan.ny - 1)) * grid.resolution_m;
        const double x = p.x + std::cos(p.yaw) * gx - std::sin(p.yaw) * gy;
        const double y = p.y + std::sin(p.yaw) * gx + std::cos(p.yaw) * gy;
        const auto [h, m] = bruteForce(map.tree(), bottom, x, y, p.z, grid.clearance_m);
        SCOPED_TRACE("pose (" + std::to_string(p.x) + ", " + std::to_string(p.y) + ", " + std::to_string(p.z) + ", " +
                     std::to_string(p.yaw) + ") point " + std::to_string(i) + ", " + std::to_string(j));
        if (std::isnan(h)) {
          ASSERT_TRUE(std::isnan(scan.height[at]));
        } else {
          ASSERT_EQ(scan.height[at], h);
        }
        if (std::isnan(m)) {
          ASSERT_TRUE(std::isnan(scan.mobility[at]));
        } else {
          ASSERT_EQ(scan.mobility[at], m);
        }
      }
    }
  }
}

TEST(HeightScan, EqualsAColumnSearchInTheOctreeOnRandomPoses) {
  const MobilityMap map = sceneMap();
  std::mt19937 rng(54);
  std::uniform_real_distribution<double> x(-0.5, 4.0), y(-0.5, 2.5), z(0.0, 1.4), yaw(-M_PI, M_PI);
  std::vector<HeightScanPose> poses;
  for (int k = 0; k < 400; ++k) poses.push_back({x(rng), y(rng), z(rng), yaw(rng)});
  // On a stair tread, beside and under the table, on it, against the room's wall.
  poses.push_back({1.2, 0.3, 0.52, 0.3});
  poses.push_back({0.85, 1.5, 0.45, 1.0});
  poses.push_back({0.5, 1.5, 0.45, -2.0});
  poses.push_back({0.5, 1.5, 1.12, 0.0});
  poses.push_back({2.2, 1.6, 0.5, 0.7});
  expectSameAsBruteForce(map, poses, {});
  expectSameAsBruteForce(map, poses, {0.5, 0.3, 0.02});  // one point per voxel
  expectSameAsBruteForce(map, poses, {1.6, 1.0, 0.1, 0.0});  // nothing above the pose
  expectSameAsBruteForce(map, poses, {1.6, 1.0, 0.1, 0.25});
}

TEST(HeightScan, SeesTerrainUpToTheClearanceAndNothingOverhead) {
  const MobilityMap map = sceneMap();
  const auto at = [&](double x, double y, double z, double clearance) {
    return map.heightScan({{x, y, z, 0.0}}, {0, 0, 0.1, clearance}).height.at(0);
  };
  // A low base at the foot of the stairs (z 0.12): the treads above it read their
  // heights (tops 0.22 and 0.32) up to the clearance; with none they read the base's.
  EXPECT_FLOAT_EQ(at(1.5, 0.3, 0.12, 0.3), 0.10f);
  EXPECT_FLOAT_EQ(at(1.7, 0.3, 0.12, 0.3), 0.20f);
  EXPECT_FLOAT_EQ(at(1.7, 0.3, 0.12, 0.15), 0.15f);
  EXPECT_FLOAT_EQ(at(1.7, 0.3, 0.12, 0.0), 0.0f);
  // Under the table (top 0.72 m): within the default clearance it is the terrain there;
  // with 0.2 m it is overhead and the floor is read.
  EXPECT_FLOAT_EQ(at(0.5, 1.5, 0.45, kDefaultScanClearanceM), 0.27f);
  EXPECT_FLOAT_EQ(at(0.5, 1.5, 0.45, 0.2), -0.43f);
  // The room's wall (1 m) reads the clearance, or its top when that is lower.
  EXPECT_FLOAT_EQ(at(2.21, 1.5, 0.5, 0.3), 0.3f);
  EXPECT_FLOAT_EQ(at(2.21, 1.5, 0.5, 1.0), 0.5f);
}

TEST(HeightScan, FindsTheSurfaceAFootMeetsFromThePosesHeight) {
  const MobilityMap map = sceneMap();
  const HeightScanGrid one{0, 0, 0.1, 0.0};  // a single point under the pose, nothing above it
  const auto at = [&](double x, double y, double z) {
    const HeightScan s = map.heightScan({{x, y, z, 0.0}}, one);
    return std::make_pair(s.height.at(0), s.mobility.at(0));
  };
  // The floor's top face is at 0.02 m.
  EXPECT_FLOAT_EQ(at(2.0, 1.0, 0.42).first, -0.40f);
  // Under the table (top 0.72 m) from below it: the floor, not the table.
  EXPECT_FLOAT_EQ(at(0.5, 1.5, 0.45).first, -0.43f);
  // From above the table: its top.
  EXPECT_FLOAT_EQ(at(0.5, 1.5, 1.12).first, -0.40f);
  // The middle tread (top 0.22 m), walkable.
  EXPECT_FLOAT_EQ(at(1.5, 0.3, 0.62).first, -0.40f);
  EXPECT_FLOAT_EQ(at(1.5, 0.3, 0.62).second, 1.0f);
  // In the room's wall (1 m high) at 0.5 m: the wall is as high as the base.
  EXPECT_FLOAT_EQ(at(2.21, 1.5, 0.5).first, 0.0f);
  EXPECT_FLOAT_EQ(at(2.21, 1.5, 0.5).second, 0.0f);
  // The hole across the floor, and beyond the map: unknown.
  EXPECT_TRUE(std::isnan(at(0.41, 1.0, 0.42).first));
  EXPECT_TRUE(std::isnan(at(0.41, 1.0, 0.42).second));
  EXPECT_TRUE(std::isnan(at(50.0, 1.0, 0.42).first));
  EXPECT_TRUE(std::isnan(at(1e30, -1e30, 1e30).first));
  // Below the floor: nothing under the pose.
  EXPECT_TRUE(std::isnan(at(2.0, 1.0, -0.1).first));
}

TEST(HeightScan, TheGridTurnsWithTheYawAndXVariesFastest) {
  const MobilityMap map = sceneMap();
  // Facing +y from the floor beside the stairs: the grid's x runs along map +y, onto
  // the floor; facing -y its x runs down over the stairs (y < 0.6) at x = 1.5.
  const HeightScanGrid line{0.8, 0, 0.1, 0.0};
  const HeightScan s = map.heightScan({{1.5, 0.95, 0.62, M_PI / 2}, {1.5, 0.95, 0.62, -M_PI / 2}}, line);
  ASSERT_EQ(s.nx, 9);
  ASSERT_EQ(s.ny, 1);
  for (int i = 0; i < 9; ++i) {
    const double y_up = 0.95 + (i - 4) * 0.1, y_down = 0.95 - (i - 4) * 0.1;
    EXPECT_FLOAT_EQ(s.height[i], y_up < 0.6 ? -0.40f : -0.60f) << i;
    EXPECT_FLOAT_EQ(s.height[9 + i], y_down < 0.6 ? -0.40f : -0.60f) << i;
  }
}

TEST(HeightScan, BadInputIsRefusedWithAReason) {
  const MobilityMap map = sceneMap();
  const auto refused = [&](const std::vector<HeightScanPose>& poses, const HeightScanGrid& grid, const std::string& says) {
    try {
      (void)map.heightScan(poses, grid);
      ADD_FAILURE() << "accepted: " << says;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
  };
  const double nan = std::nan("");
  refused({{1, 1, nan, 0}}, {}, "poses[0]");
  refused({{1, 1, 0.5, 0}, {1, std::numeric_limits<double>::infinity(), 0.5, 0}}, {}, "poses[1]");
  refused({{1, 1, 0.5, 0}}, {1.6, 1.0, 0.0}, "resolution");
  refused({{1, 1, 0.5, 0}}, {1.6, 1.0, nan}, "resolution");
  refused({{1, 1, 0.5, 0}}, {-1.0, 1.0, 0.1}, "size");
  refused({{1, 1, 0.5, 0}}, {1e9, 1.0, 0.1}, "a side");
  refused({{1, 1, 0.5, 0}}, {1.6, 1.0, 0.1, -0.1}, "clearance");
  refused({{1, 1, 0.5, 0}}, {1.6, 1.0, 0.1, nan}, "clearance");
  refused(std::vector<HeightScanPose>(1'000'000, {1, 1, 0.5, 0}), {10, 10, 0.1}, "per call");
  const HeightScan empty = map.heightScan({}, {});
  EXPECT_EQ(empty.poses, 0u);
  EXPECT_TRUE(empty.height.empty());
  EXPECT_EQ(empty.nx, 17);
  EXPECT_EQ(empty.ny, 11);
}

TEST(HeightScan, TheColumnsAreKeptUntilTheMapChanges) {
  MobilityMap map = sceneMap();
  const MobilityMap& reader = map;
  const auto first = reader.surfaceColumns();
  EXPECT_EQ(reader.surfaceColumns(), first);  // kept
  map.finalize();
  const auto second = reader.surfaceColumns();
  EXPECT_NE(second, first);  // built again after a change
  // A new floor voxel at (5.01, 5.01): scans see it once the map changed.
  map.tree().updateNode(octomap::point3d(5.01f, 5.01f, 0.01f), true);
  EXPECT_FLOAT_EQ(reader.heightScan({{5.01, 5.01, 0.42, 0}}, {0, 0, 0.1, 0.0}).height.at(0), -0.40f);
}

}  // namespace
}  // namespace mobmap::mapping
