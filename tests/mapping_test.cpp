// The MobilityOcTree and MobilityMap: storage, fusion, files, queries.
#include "mobmap/mapping/gravity.hpp"
#include "mobmap/mapping/map_lock.hpp"
#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/mapping/mobility_octree.hpp"
#include "mobmap/sim/corridor_scene.hpp"

#include <mrpt/poses/CPose3D.h>
#include <octomap/ColorOcTree.h>
#include <octomap/OcTree.h>

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <csignal>

#include <cmath>
#include <cstdio>
#include <functional>
#include <iterator>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <set>
#include <sstream>
#include <thread>
#include <tuple>

namespace mobmap::mapping {
namespace {

namespace fs = std::filesystem;

// This process's scratch folder, removed when the process ends (ctest runs each test
// in its own process, and folders left behind used to pile up in /tmp).
std::string tempPath(const std::string& name) {
  struct Scratch {
    fs::path dir = fs::temp_directory_path() / ("mobmap-mapping-" + std::to_string(::getpid()));
    ~Scratch() {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  };
  static const Scratch scratch;
  fs::create_directories(scratch.dir);
  return (scratch.dir / name).string();
}

TEST(MobilityOcTreeNode, IsNoLargerThanAnOcTreeNode) {
  static_assert(sizeof(MobilityOcTreeNode) <= sizeof(octomap::OcTreeNode), "payload must fit the padding");
  EXPECT_EQ(sizeof(MobilityOcTreeNode), sizeof(octomap::OcTreeNode));
}

TEST(MobilityOcTreeNode, QuantisationErrorIsFarBelowTheBound) {
  double worst = 0;
  for (int i = 0; i <= 100000; ++i) {
    const double m = i / 100000.0;
    worst = std::max(worst, std::abs(MobilityOcTreeNode::decodeMobility(MobilityOcTreeNode::encodeMobility(m)) - m));
  }
  EXPECT_LT(worst, 0.005);            // the requirement
  EXPECT_LE(worst, 0.5 / 16383 + 1e-12);  // what 14 bits give
  for (double w : {1e-3, 0.7, 12.0, 523.0, 19999.0}) {
    const double back = MobilityOcTreeNode::decodeWeight(MobilityOcTreeNode::encodeWeight(w));
    EXPECT_NEAR(back / w, 1.0, 0.011) << w;  // half a 2^(1/32) step
  }
}

TEST(MobilityOcTreeNode, UnknownIsDistinctFromUntraversable) {
  MobilityOcTreeNode n;
  EXPECT_FALSE(n.hasMobility());
  EXPECT_TRUE(std::isinf(n.variance()));
  n.fuse(0.0, 0.01, 1e9);
  EXPECT_TRUE(n.hasMobility());
  EXPECT_EQ(n.mobility(), 0.0);
  EXPECT_EQ(n.count(), 1);
}

TEST(MobilityOcTreeNode, InverseVarianceFusionWeighsConfidentObservationsMore) {
  MobilityOcTreeNode n;
  n.fuse(0.2, 0.01, 1e9);  // confident
  n.fuse(0.8, 0.04, 1e9);  // noisy
  // The stored weight of the first observation is within 1.1 % of 100 (log2 steps of
  // 1/32), which moves the fused value by at most ~0.001.
  EXPECT_NEAR(n.mobility(), (0.2 * 100 + 0.8 * 25) / 125.0, 0.0015);
  EXPECT_NEAR(n.variance(), 1.0 / 125.0, 0.025 / 125.0);
  EXPECT_EQ(n.count(), 2);
}

TEST(MobilityOcTreeNode, LongFusionTracksADoublePrecisionReference) {
  // The same capped inverse-variance recursion in double precision is the oracle; the
  // node's 16-bit, stochastically rounded storage must stay within 0.005 of it.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> m(0, 1), logvar(-6, -1);
  const double cap = 20000;
  for (int trial = 0; trial < 50; ++trial) {
    MobilityOcTreeNode n;
    double ref = 0, w_ref = 0;
    const double base = m(rng);
    for (int i = 0; i < 2000; ++i) {
      const double x = std::clamp(base + 0.2 * (m(rng) - 0.5), 0.0, 1.0);
      const double var = std::exp(logvar(rng));
      const double w = 1 / var;
      n.fuse(x, var, cap);
      ref = w_ref == 0 ? x : (w_ref * ref + w * x) / (w_ref + w);
      w_ref = std::min(w_ref + w, cap);
      // The node's weight is quantised (9 % steps), so its recursion uses slightly
      // different weights; follow its weight to isolate the mobility storage error.
      w_ref = n.weight();
      ASSERT_NEAR(n.mobility(), ref, 0.005) << "trial " << trial << " step " << i;
    }
  }
}

TEST(MobilityOcTree, PrunesOnlyIdenticalChildrenAndKeepsTheMinimumAbove) {
  MobilityOcTree tree(0.05);
  octomap::OcTreeKey base = tree.coordToKey(octomap::point3d(0.01f, 0.01f, 0.01f), 15);  // a depth-15 cell
  auto child_key = [&](int i) {
    return octomap::OcTreeKey(static_cast<octomap::key_type>(base[0] + (i & 1)), static_cast<octomap::key_type>(base[1] + ((i >> 1) & 1)),
                              static_cast<octomap::key_type>(base[2] + ((i >> 2) & 1)));
  };
  base = tree.coordToKey(tree.keyToCoord(base, 15) - octomap::point3d(0.025f, 0.025f, 0.025f));
  for (int i = 0; i < 8; ++i) {
    auto* n = tree.updateNode(child_key(i), true);
    n->setMobility(0.8, 100, 3);
  }
  tree.updateInnerOccupancy();
  tree.prune();
  EXPECT_EQ(tree.getNumLeafNodes(), 1u);  // identical: merged
  // Now one child differs by a single quantisation step: never merged.
  tree.clear();
  for (int i = 0; i < 8; ++i) {
    auto* n = tree.updateNode(child_key(i), true);
    n->setMobility(i == 5 ? 0.8 + 1.0 / 16383 : 0.8, 100, 3);
  }
  tree.updateInnerOccupancy();
  tree.prune();
  EXPECT_EQ(tree.getNumLeafNodes(), 8u);
  // The inner node above holds the minimum known mobility of its children.
  tree.updateNode(child_key(2), true)->setMobility(0.1, 5, 1);
  tree.updateInnerOccupancy();
  const MobilityOcTreeNode* parent = tree.search(child_key(0), 15);
  ASSERT_NE(parent, nullptr);
  EXPECT_NEAR(parent->mobility(), 0.1, 1e-4);
}

// updateLeaf (one descent) against OctoMap's updateNode (search, then descend) on the
// same random updates: hits and misses over a few voxels so that leaves reach the
// clamping bounds (the search's early return), with pruning now and then (pruned
// leaves above the finest level, expanded by the next update). The trees must stay
// equal to the byte, each update must return the node updateNode returns, and
// was_occupied must be the voxel's state before the update (its leaf's, or that of the
// pruned leaf holding it).
void checkUpdateLeafAgainstUpdateNode(bool with_path) {
  MobilityOcTree ours(0.02), stock(0.02);
  MobilityOcTree::UpdatePath path;
  for (MobilityOcTree* t : {&ours, &stock}) {
    t->setProbHit(0.7);
    t->setProbMiss(0.4);
    t->setClampingThresMin(0.12);
    t->setClampingThresMax(0.9);
  }
  const octomap::OcTreeKey base = ours.coordToKey(octomap::point3d(0.3f, -0.2f, 0.1f));
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> offset(0, 3);
  std::bernoulli_distribution hit(0.7);
  const auto bytes = [](const MobilityOcTree& t) {
    std::ostringstream out;
    t.write(out);
    return out.str();
  };
  int early_returns = 0, expanded = 0;
  for (int step = 0; step < 20000; ++step) {
    // Every seventh key lies in a block far away, so paths part at the top levels too.
    const int far = step % 7 == 3 ? 1000 : 0;
    const octomap::OcTreeKey key(static_cast<octomap::key_type>(base[0] + far + offset(rng)),
                                 static_cast<octomap::key_type>(base[1] + offset(rng)),
                                 static_cast<octomap::key_type>(base[2] + offset(rng)));
    // Later phases lean towards misses, so blocks saturate at both bounds.
    const bool occupied = step < 10000 ? hit(rng) : !hit(rng);
    // Where the key's path ends before the update: at the voxel (depth 16), at a
    // pruned leaf above it, or nowhere (a node with other children: before = null).
    const MobilityOcTreeNode* before = ours.getRoot();
    unsigned int depth_before = 0;
    while (before && depth_before < 16) {
      const unsigned int pos = octomap::computeChildIdx(key, static_cast<int>(15 - depth_before));
      if (!ours.nodeChildExists(before, pos)) {
        if (ours.nodeHasChildren(before)) before = nullptr;
        break;
      }
      before = ours.getNodeChild(before, pos);
      ++depth_before;
    }
    const bool expected_was = before && ours.isNodeOccupied(before);
    bool was_occupied = !expected_was;
    MobilityOcTreeNode* a = ours.updateLeaf(key, occupied, &was_occupied, with_path ? &path : nullptr);
    MobilityOcTreeNode* b = stock.updateNode(key, occupied, true);
    ASSERT_NE(a, nullptr);
    ASSERT_NE(b, nullptr);
    EXPECT_EQ(a->getLogOdds(), b->getLogOdds()) << "step " << step;
    EXPECT_EQ(ours.nodeHasChildren(a), stock.nodeHasChildren(b)) << "step " << step;
    EXPECT_EQ(was_occupied, expected_was) << "step " << step;
    if (before && a == before && depth_before < 16) ++early_returns;
    if (before && depth_before < 16 && a != before) ++expanded;
    if (step % 500 == 499) {
      for (MobilityOcTree* t : {&ours, &stock}) {
        t->updateInnerOccupancy();
        t->prune();
      }
      path = MobilityOcTree::UpdatePath();  // pruning deletes nodes a path may hold
      ASSERT_EQ(bytes(ours), bytes(stock)) << "after step " << step;
    }
  }
  EXPECT_EQ(bytes(ours), bytes(stock));
  // Both special paths ran: a pruned leaf at a bound returned as it was, and pruned
  // leaves expanded down to the voxel.
  EXPECT_GT(early_returns, 0);
  EXPECT_GT(expanded, 0);
}

TEST(MobilityOcTree, UpdateLeafEqualsOctomapsUpdateNode) { checkUpdateLeafAgainstUpdateNode(false); }
TEST(MobilityOcTree, UpdateLeafFromThePreviousPathEqualsOctomapsUpdateNode) { checkUpdateLeafAgainstUpdateNode(true); }

// A small scored "frame": a floor patch (mobility 1) and a wall (0) seen from 1.2 m.
// Surfaces sit mid-voxel (z = 0.01, x = 1.61) so float rounding cannot move them
// across a voxel boundary.
perception::FrameResult syntheticFrame() {
  perception::FrameResult r;
  perception::Segment floor, wall;
  floor.mobility = 1.0;
  floor.variance = 0.002;
  wall.mobility = 0.0;
  wall.variance = 0.002;
  for (int i = -30; i <= 30; ++i) {
    for (int j = 0; j < 60; ++j) {
      r.points.emplace_back(i * 0.01f, 1.19f, 1.0f + j * 0.01f);  // camera frame: floor 1.19 m below
      r.segment_of_point.push_back(0);
      floor.points.push_back(static_cast<int>(r.points.size() - 1));
      r.points.emplace_back(i * 0.01f, 1.19f - j * 0.01f, 1.61f);  // wall 1.61 m ahead
      r.segment_of_point.push_back(1);
      wall.points.push_back(static_cast<int>(r.points.size() - 1));
    }
  }
  r.segments = {floor, wall};
  return r;
}

Eigen::Isometry3d cameraLookingForward() {
  // Camera axes (x right, y down, z forward) in a z-up world, at 1.2 m height.
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  Eigen::Matrix3d r;
  r.col(0) = Eigen::Vector3d(0, -1, 0);
  r.col(1) = Eigen::Vector3d(0, 0, -1);
  r.col(2) = Eigen::Vector3d(1, 0, 0);
  T.linear() = r;
  T.translation() = Eigen::Vector3d(0, 0, 1.2);
  return T;
}

MobilityMap builtMap() {
  MobilityMap map;
  const auto frame = syntheticFrame();
  for (int i = 0; i < 3; ++i) map.integrate(frame, cameraLookingForward());
  map.finalize();
  return map;
}

TEST(MobilityMap, SurfacesGetTheirSegmentsMobilityInTheGravityAlignedFrame) {
  const MobilityMap map = builtMap();
  const PointQuery floor = map.query({1.3, 0.0, 0.01});
  EXPECT_EQ(floor.state, VoxelState::kSurface);
  ASSERT_TRUE(floor.has_mobility);
  EXPECT_NEAR(floor.mobility, 1.0, 1e-3);
  EXPECT_EQ(floor.count, 3);
  const PointQuery wall = map.query({1.61, 0.0, 0.31});
  EXPECT_EQ(wall.state, VoxelState::kSurface);
  EXPECT_NEAR(wall.mobility, 0.0, 1e-3);
  EXPECT_EQ(map.query({5, 5, 5}).state, VoxelState::kUnknown);
}

TEST(MobilityMap, MrptPoseGivesTheSameMapAsEigen) {
  MobilityMap a, b;
  const auto frame = syntheticFrame();
  const Eigen::Isometry3d T = cameraLookingForward();
  a.integrate(frame, T);
  mrpt::math::CMatrixDouble44 m;
  m.asEigen() = T.matrix();
  b.integrate(frame, mrpt::poses::CPose3D(m));
  EXPECT_EQ(a.tree().size(), b.tree().size());
  const auto q = b.query({1.3, 0.1, 0.005});
  EXPECT_EQ(q.state, VoxelState::kSurface);
}

// n x n x n voxels of 2 cm from the voxel whose centre is `first`, in one segment.
perception::FrameResult cubeFrame(const Eigen::Vector3f& first, int n, double mobility) {
  perception::FrameResult r;
  perception::Segment s;
  s.mobility = mobility;
  s.variance = 0.002;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      for (int l = 0; l < n; ++l) {
        r.points.push_back(first + 0.02f * Eigen::Vector3f(static_cast<float>(i), static_cast<float>(j), static_cast<float>(l)));
        r.segment_of_point.push_back(0);
        s.points.push_back(static_cast<int>(r.points.size() - 1));
      }
    }
  }
  r.segments = {s};
  return r;
}

// Every node (leaves and inner aggregates, in tree order) equal in depth, occupancy and payload.
void expectSameTree(const MobilityOcTree& a, const MobilityOcTree& b) {
  ASSERT_EQ(a.size(), b.size());
  auto ib = b.begin_tree();
  int differing = 0;
  for (auto ia = a.begin_tree(); ia != a.end_tree(); ++ia, ++ib) {
    const bool same = ia.getDepth() == ib.getDepth() && ia.getKey() == ib.getKey() && ia->getValue() == ib->getValue() &&
                      ia->payload() == ib->payload();
    if (!same && ++differing <= 3) {
      ADD_FAILURE() << "node at depth " << ia.getDepth() << " (" << ia.getX() << ", " << ia.getY() << ", " << ia.getZ()
                    << "): count " << ia->count() << " vs " << ib->count();
    }
  }
  EXPECT_EQ(differing, 0);
}

// A map finalized, saved and loaded between frames, then fused further, equals the map
// fused in one go (what `mobmap build --extend` relies on): pruned blocks that new data
// lands in are expanded, and inner nodes count a pruned node's observations once per
// voxel it stands for, as they did before it was pruned.
TEST(MobilityMap, FinalizingSavingAndLoadingMidwayGivesTheSameMapAsOneRun) {
  MapParams p;
  p.range_variance_per_m2 = 0.0;  // equal weights: the cubes' voxels are equal and prune
  const auto two_cubes = [] {
    perception::FrameResult r = cubeFrame({0.01f, 0.01f, 0.97f}, 2, 1.0);
    const perception::FrameResult other = cubeFrame({0.41f, 0.01f, 0.97f}, 2, 1.0);
    for (std::size_t i = 0; i < other.points.size(); ++i) {
      r.points.push_back(other.points[i]);
      r.segment_of_point.push_back(0);
      r.segments[0].points.push_back(static_cast<int>(r.points.size() - 1));
    }
    return r;
  }();
  const perception::FrameResult one_voxel = cubeFrame({0.43f, 0.03f, 0.99f}, 1, 0.0);
  const Eigen::Isometry3d T = Eigen::Isometry3d::Identity();

  MobilityMap whole(p);
  for (int n = 0; n < 3; ++n) whole.integrate(two_cubes, T);
  whole.integrate(one_voxel, T);
  whole.finalize();

  MobilityMap first(p);
  for (int n = 0; n < 3; ++n) first.integrate(two_cubes, T);
  first.finalize();
  ASSERT_EQ(first.tree().getNumLeafNodes(), 2u) << "each cube should have pruned into one node";
  const std::string path = tempPath("midway.ot");
  saveMobilityMap(first.tree(), path);
  MobilityMap resumed(loadMobilityMap(path), p, Eigen::Matrix3d::Identity());
  resumed.integrate(one_voxel, T);
  resumed.finalize();
  expectSameTree(whole.tree(), resumed.tree());
  EXPECT_EQ(resumed.query({0.03, 0.03, 0.99}).count, 3);  // a voxel of the cube left pruned
  EXPECT_LT(resumed.query({0.43, 0.03, 0.99}).mobility, 0.9);
}

// After finalize() (or in a loaded map) equal voxels are pruned into one node. OctoMap's
// updateNode() returns such a node itself, without descending, when the hit cannot raise
// its clamped occupancy; fusing the new mobility into it would overwrite the whole block.
TEST(MobilityMap, FusingIntoAPrunedBlockChangesOnlyTheVoxelHit) {
  MapParams p;
  p.range_variance_per_m2 = 0.0;  // equal weights, so the cube's voxels are equal and prune
  MobilityMap map(p);
  perception::FrameResult cube;
  perception::Segment walkable;
  walkable.mobility = 1.0;
  walkable.variance = 0.002;
  // 4 x 4 x 4 voxels of 2 cm, aligned to a node of the level above two (keys multiple of 4).
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      for (int l = 0; l < 4; ++l) {
        cube.points.emplace_back(0.01f + 0.02f * i, 0.01f + 0.02f * j, 0.97f + 0.02f * l);
        cube.segment_of_point.push_back(0);
        walkable.points.push_back(static_cast<int>(cube.points.size() - 1));
      }
    }
  }
  cube.segments = {walkable};
  for (int n = 0; n < 4; ++n) map.integrate(cube, Eigen::Isometry3d::Identity());  // clamped after 3
  map.finalize();
  ASSERT_EQ(map.tree().getNumLeafNodes(), 1u) << "the cube should have pruned into one node";

  perception::FrameResult one;
  perception::Segment obstacle;
  obstacle.mobility = 0.0;
  obstacle.variance = 0.002;
  obstacle.points = {0};
  one.points = {Eigen::Vector3f(0.01f, 0.01f, 0.97f)};
  one.segment_of_point = {0};
  one.segments = {obstacle};
  map.integrate(one, Eigen::Isometry3d::Identity());
  const PointQuery hit = map.query({0.01, 0.01, 0.97});
  EXPECT_NEAR(hit.size_m, 0.02, 1e-9);
  EXPECT_LT(hit.mobility, 0.9);
  EXPECT_EQ(hit.count, 5);
  for (const Eigen::Vector3d& q : {Eigen::Vector3d(0.03, 0.01, 0.97), Eigen::Vector3d(0.07, 0.07, 1.03)}) {
    const PointQuery other = map.query(q);
    EXPECT_NEAR(other.mobility, 1.0, 1e-3) << q.transpose();
    EXPECT_EQ(other.count, 4) << q.transpose();
  }
  map.finalize();
  EXPECT_EQ(map.query({0.07, 0.07, 1.03}).count, 4);
  EXPECT_LT(map.query({0.01, 0.01, 0.97}).mobility, 0.9);
}

TEST(MobilityMap, SnapAndFootprintQueries) {
  const MobilityMap map = builtMap();
  const auto snapped = map.snapDown({1.3, 0.0, 0.3}, 0.5);
  ASSERT_TRUE(snapped);
  EXPECT_NEAR(snapped->centre.z(), 0.01, 1e-6);  // the floor voxel [0, 0.02)
  EXPECT_FALSE(map.snapDown({1.3, 0.0, 0.3}, 0.1));
  const FootprintQuery flat = map.footprint({1.3, 0.0, 0.0, 0.3, 0.2, 0.1});
  EXPECT_NEAR(flat.min_mobility, 1.0, 1e-3);
  EXPECT_NEAR(flat.known_fraction, 1.0, 1e-9);
  EXPECT_LE(flat.max_height_difference_m, 1e-6);
  // A sole across the foot of the wall touches untraversable voxels.
  const FootprintQuery edge = map.footprint({1.61, 0.0, 0.0, 0.0, 0.2, 0.1}, 0.3, 0.1);
  EXPECT_NEAR(edge.min_mobility, 0.0, 1e-3);
  EXPECT_GT(edge.max_height_difference_m, 0.2);
}

// snapDown walks the column voxel by voxel: started on a voxel face (a height that is a
// multiple of the resolution, where stepping a point down by the resolution rounds to
// either side) it still finds the first surface below, and it stops at max_drop_m.
TEST(MobilityMap, SnapDownFindsTheSurfaceBelowFromAnyStartHeight) {
  for (const double res : {0.01, 0.02, 0.05}) {
    MapParams p;
    p.resolution_m = res;
    MobilityMap map(p);
    for (const int k : {3, 8, 13}) {
      map.tree().updateNode(octomap::point3d(0.01f, 0.01f, static_cast<float>((k + 0.5) * res)), true)->fuse(1.0, 0.01, 100.0);
    }
    int asked = 0;
    for (int m = 0; m <= 30; ++m) {
      for (const double frac : {0.0, 0.5, 0.999}) {
        const double z = (m + frac) * res;  // m + 0: on a face
        // On a surface voxel's bottom face the start voxel is either one, by rounding.
        if (frac == 0.0 && (m == 3 || m == 8 || m == 13)) continue;
        // The first voxel at or below z: the highest k <= floor(z / res) among 3, 8, 13.
        const int at = static_cast<int>(std::floor(z / res + 1e-9));
        int want = -1;
        for (const int k : {3, 8, 13}) want = k <= at ? k : want;
        const auto q = map.snapDown({0.01, 0.01, z}, 40 * res);
        ++asked;
        if (want < 0) {
          EXPECT_FALSE(q) << res << " " << z;
          continue;
        }
        ASSERT_TRUE(q) << res << " " << z;
        EXPECT_NEAR(q->centre.z(), (want + 0.5) * res, 1e-6) << res << " " << z;
        // A drop that ends just above that voxel's top misses it; one that reaches into it finds it.
        const double gap = z - (want + 1) * res;
        if (gap > 0.1 * res) {
          EXPECT_FALSE(map.snapDown({0.01, 0.01, z}, gap - 0.05 * res)) << res << " " << z;
          EXPECT_TRUE(map.snapDown({0.01, 0.01, z}, gap + 0.05 * res)) << res << " " << z;
        }
      }
    }
    EXPECT_EQ(asked, 90);
    EXPECT_FALSE(map.snapDown({0.01, 0.01, (3.5) * res}, -res));  // a negative drop searches nothing
    EXPECT_TRUE(map.snapDown({0.01, 0.01, (3.5) * res}, 0.0));    // a zero drop: the voxel at the point
  }
}

// The support plane under a sole against analytic surfaces laid voxel by voxel: a floor,
// a 12-degree ramp (soles along it, across it and turned), a 8 cm step.
TEST(MobilityMap, TheSupportPlaneOfASoleFollowsFloorsRampsAndSteps) {
  MapParams p;
  p.resolution_m = 0.01;
  MobilityMap map(p);
  const double res = p.resolution_m;
  const double slope = 12.0 * M_PI / 180.0;
  // One voxel per column: the one holding the surface point above the column's centre.
  const auto lay = [&](double x0, double x1, const std::function<double(double)>& height) {
    for (int i = 0; x0 + (i + 0.5) * res < x1; ++i) {
      for (int j = 0; j < 50; ++j) {
        const double x = x0 + (i + 0.5) * res, y = (j + 0.5) * res;
        map.tree().updateNode(octomap::point3d(static_cast<float>(x), static_cast<float>(y), static_cast<float>(height(x))), true)
            ->fuse(1.0, 0.01, 100.0);
      }
    }
  };
  lay(0.0, 0.5, [](double) { return 0.003; });                                               // tops at 0.01
  lay(1.0, 1.6, [&](double x) { return 0.2 + std::tan(slope) * (x - 1.0); });                // ramp
  lay(2.0, 2.5, [](double x) { return x < 2.25 ? 0.003 : 0.083; });                          // step: tops 0.01, 0.09

  const FootprintQuery flat = map.footprint({0.25, 0.25, 0.01, 0.4, 0.25, 0.12});
  ASSERT_TRUE(flat.has_support_plane);
  EXPECT_NEAR(flat.support_height_m, 0.01, 1e-6);
  EXPECT_NEAR(flat.support_tilt_deg, 0.0, 1e-4);
  EXPECT_NEAR(flat.support_normal.z(), 1.0, 1e-9);
  EXPECT_LT(flat.support_rms_m, 1e-6);

  const double xc = 1.3, true_z = 0.2 + std::tan(slope) * (xc - 1.0);
  for (const double yaw : {0.0, M_PI / 2, 0.6, -2.5}) {
    SCOPED_TRACE(yaw);
    const FootprintQuery ramp = map.footprint({xc, 0.25, true_z, yaw, 0.25, 0.12});
    ASSERT_TRUE(ramp.has_support_plane);
    EXPECT_NEAR(ramp.support_tilt_deg, 12.0, 1.0);  // 1 cm steps over a 25 x 12 cm sole
    // The normal leans downhill (-x), whichever way the sole points.
    EXPECT_NEAR(ramp.support_normal.x(), -std::sin(slope), 0.02);
    EXPECT_NEAR(ramp.support_normal.y(), 0.0, 0.02);
    EXPECT_NEAR(ramp.support_normal.norm(), 1.0, 1e-9);
    // Voxel tops lie 0..1 voxel above the surface: the plane half a voxel above, on average.
    EXPECT_NEAR(ramp.support_height_m, true_z + res / 2, res / 2);
    EXPECT_LT(ramp.support_rms_m, res / 2);
  }

  const FootprintQuery step = map.footprint({2.25, 0.25, 0.05, 0.0, 0.25, 0.12});
  ASSERT_TRUE(step.has_support_plane);
  EXPECT_NEAR(step.max_height_difference_m, 0.08, 1e-6);
  // No plane fits a step: a fit through it leaves ~2 cm of residual and leans 20-odd degrees.
  EXPECT_GT(step.support_rms_m, 0.015);
  EXPECT_GT(step.support_tilt_deg, 15.0);

  // A sole narrower than a voxel samples one line; a sole over nothing, no voxel.
  EXPECT_FALSE(map.footprint({0.25, 0.25, 0.01, 0.0, 0.25, 0.005}).has_support_plane);
  EXPECT_FALSE(map.footprint({5.0, 5.0, 0.0, 0.0, 0.25, 0.12}).has_support_plane);
}

TEST(MobilityMap, SeenThroughVoxelsBecomeFreeSoMovedObstaclesDisappear) {
  MapParams p;
  p.free_space_ray_stride_px = 4;  // rays are off by default
  MobilityMap map(p);
  const auto frame = syntheticFrame();
  const Eigen::Isometry3d T = cameraLookingForward();
  for (int i = 0; i < 3; ++i) map.integrate(frame, T);
  ASSERT_EQ(map.query({1.61, 0.0, 0.31}).state, VoxelState::kSurface);
  // The wall is gone: render what the camera now sees, the floor alone (at z = 0.01,
  // the mid-voxel height of the frame's floor), with a wide 160x120 camera
  // (+-53 x +-45 degrees) so the whole wall's place is in view.
  perception::PinholeIntrinsics k{160, 120, 60, 60, 80, 60};
  const std::vector<sim::Triangle> floor_only = {{{-5, -5, 0.01}, {9, -5, 0.01}, {9, 5, 0.01}, 1},
                                                 {{-5, -5, 0.01}, {9, 5, 0.01}, {-5, 5, 0.01}, 1}};
  const perception::DepthImage depth = sim::castRays(floor_only, k, T).depth;
  perception::FrameResult empty;
  // Three hits (+0.85 log-odds each) need seven misses (-0.41 each) to go free.
  for (int i = 0; i < 10; ++i) map.integrate(empty, T, &depth, &k);
  map.finalize();
  EXPECT_EQ(map.query({1.61, 0.0, 0.31}).state, VoxelState::kFree);
  // On the ray of pixel (82, 78), one of the stride-4 rays, which meets the floor 4 m
  // away: free space 1 m ahead.
  EXPECT_EQ(map.query({1.0, -2.0 / 60, 1.2 - 18.0 / 60}).state, VoxelState::kFree);
  // The floor below the camera's view is untouched.
  EXPECT_EQ(map.query({1.3, 0.0, 0.01}).state, VoxelState::kSurface);
}

// Clearing skips blocks of voxels outside the view: every voxel it skips must be one
// the per-voxel rule rejects. Voxels scattered all round the camera, then a view where
// everything in sight is seen through (a wall 10 m away): exactly the voxels whose
// centre projects into the image, 0.1 m to the range ahead, turn free.
TEST(MobilityMap, ClearingTouchesExactlyTheVoxelsInView) {
  MapParams p;
  p.max_range_m = 3.5;
  MobilityMap map(p);
  const Eigen::Isometry3d T = cameraLookingForward();
  perception::FrameResult hits;
  std::vector<Eigen::Vector3d> world;
  for (double x = -2.89; x <= 3.0; x += 0.22) {  // voxel centres, 11 voxels apart
    for (double y = -2.89; y <= 3.0; y += 0.22) {
      for (double z = -0.89; z <= 3.0; z += 0.22) {
        const Eigen::Vector3d w(x, y, z);
        if ((w - T.translation()).norm() > 3.4 || (w - T.translation()).norm() < 0.2) continue;
        world.push_back(w);
        hits.points.push_back((T.inverse() * w).cast<float>());
      }
    }
  }
  for (int i = 0; i < 3; ++i) map.integrate(hits, T);
  for (const auto& w : world) ASSERT_EQ(map.query(w).state, VoxelState::kSurface) << w.transpose();
  const perception::PinholeIntrinsics k{160, 120, 100, 100, 80, 60};
  perception::DepthImage far;
  far.width = k.width, far.height = k.height;
  far.depth_m.assign(static_cast<std::size_t>(k.width * k.height), 10.f);
  const perception::FrameResult nothing;
  for (int i = 0; i < 10; ++i) map.integrate(nothing, T, &far, &k);
  int in_view = 0, out_of_view = 0;
  for (const auto& w : world) {
    const PointQuery q = map.query(w);
    const Eigen::Vector3f c = (T.inverse() * q.centre).cast<float>();
    bool visible = c.z() >= 0.1f && c.z() <= 3.5f;
    if (visible) {
      const long u = std::lround(100.f * c.x() / c.z() + 80.f), v = std::lround(100.f * c.y() / c.z() + 60.f);
      visible = u >= 0 && v >= 0 && u < k.width && v < k.height;
    }
    (visible ? in_view : out_of_view)++;
    EXPECT_EQ(q.state, visible ? VoxelState::kFree : VoxelState::kSurface) << w.transpose();
  }
  EXPECT_GT(in_view, 100);
  EXPECT_GT(out_of_view, 1000);
}

TEST(MobilityMap, QueriesFromSeveralThreadsEqualSingleThreadedAnswers) {
  const MobilityMap map = builtMap();
  std::vector<Eigen::Vector3d> pts;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.5, 2.0);
  for (int i = 0; i < 20000; ++i) pts.emplace_back(u(rng), u(rng) * 0.3, u(rng) * 0.5);
  std::vector<PointQuery> single(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) single[i] = map.query(pts[i]);
  // Planners also ask for support under a point and for whole soles.
  auto footOf = [](const Eigen::Vector3d& p, std::size_t i) {
    Foot f;
    f.x = p.x(), f.y = p.y(), f.z = 0.05, f.yaw = 0.3 * static_cast<double>(i % 7), f.length = 0.24, f.width = 0.1;
    return f;
  };
  std::vector<std::optional<PointQuery>> single_snap(pts.size());
  std::vector<FootprintQuery> single_foot(pts.size() / 10);
  for (std::size_t i = 0; i < pts.size(); ++i) single_snap[i] = map.snapDown(pts[i], 0.5);
  for (std::size_t i = 0; i < single_foot.size(); ++i) single_foot[i] = map.footprint(footOf(pts[i], i));
  std::vector<std::vector<PointQuery>> per_thread(4, std::vector<PointQuery>(pts.size()));
  std::vector<std::vector<std::optional<PointQuery>>> snaps(4, std::vector<std::optional<PointQuery>>(pts.size()));
  std::vector<std::vector<FootprintQuery>> feet(4, std::vector<FootprintQuery>(single_foot.size()));
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      const auto ti = static_cast<std::size_t>(t);
      for (std::size_t i = 0; i < pts.size(); ++i) {
        per_thread[ti][i] = map.query(pts[i]);
        snaps[ti][i] = map.snapDown(pts[i], 0.5);
        if (i < feet[ti].size()) feet[ti][i] = map.footprint(footOf(pts[i], i));
      }
    });
  }
  for (auto& th : threads) th.join();
  for (std::size_t t = 0; t < per_thread.size(); ++t) {
    for (std::size_t i = 0; i < pts.size(); ++i) {
      ASSERT_EQ(per_thread[t][i].state, single[i].state);
      ASSERT_EQ(per_thread[t][i].mobility, single[i].mobility);
      ASSERT_EQ(per_thread[t][i].centre, single[i].centre);
      ASSERT_EQ(snaps[t][i].has_value(), single_snap[i].has_value());
      if (snaps[t][i]) {
        ASSERT_EQ(snaps[t][i]->centre, single_snap[i]->centre);
      }
    }
    for (std::size_t i = 0; i < single_foot.size(); ++i) {
      ASSERT_EQ(feet[t][i].min_mobility, single_foot[i].min_mobility);
      ASSERT_EQ(feet[t][i].mean_mobility, single_foot[i].mean_mobility);
      ASSERT_EQ(feet[t][i].known_fraction, single_foot[i].known_fraction);
    }
  }
  // The answers are not all alike (the test would prove little otherwise).
  std::size_t surface = 0, snapped = 0, known_feet = 0;
  for (const auto& q : single) surface += q.state == VoxelState::kSurface;
  for (const auto& q : single_snap) snapped += q.has_value();
  for (const auto& f : single_foot) known_feet += f.known_fraction > 0;
  EXPECT_GT(surface, 50u);
  EXPECT_GT(snapped, 1000u);
  EXPECT_GT(known_feet, 100u);
}

TEST(MapFiles, OtRoundTripIsExact) {
  const MobilityMap map = builtMap();
  const std::string path = tempPath("round.ot");
  saveMobilityMap(map.tree(), path);
  const auto back = loadMobilityMap(path);
  ASSERT_EQ(back->size(), map.tree().size());
  EXPECT_EQ(back->getResolution(), map.tree().getResolution());
  auto a = map.tree().begin_tree(), b = back->begin_tree();
  for (; a != map.tree().end_tree(); ++a, ++b) {
    ASSERT_NE(b, back->end_tree());
    ASSERT_EQ(a.getKey(), b.getKey());
    ASSERT_EQ(a.getDepth(), b.getDepth());
    ASSERT_EQ(a->getValue(), b->getValue());
    ASSERT_EQ(a->payload(), b->payload());
  }
  EXPECT_EQ(b, back->end_tree());
}

// A run where nothing was in range leaves an empty tree: every format still writes it,
// and what OctoMap reads back is empty too (ColorOcTree used to crash on it).
TEST(MapFiles, AnEmptyMapIsWrittenInEveryFormat) {
  MobilityMap map;
  map.finalize();
  ASSERT_EQ(map.tree().size(), 0u);
  const std::string ot = tempPath("empty.ot"), bt = tempPath("empty.bt"), colour = tempPath("empty.octovis.ot"),
                    pcd = tempPath("empty.pcd");
  saveMobilityMap(map.tree(), ot);
  EXPECT_EQ(loadMobilityMap(ot)->size(), 0u);
  saveOccupancyBt(map.tree(), bt);
  octomap::OcTree occupancy(0.1);
  ASSERT_TRUE(occupancy.readBinary(bt));
  EXPECT_EQ(occupancy.size(), 0u);
  EXPECT_DOUBLE_EQ(occupancy.getResolution(), map.tree().getResolution());
  saveOctovisColorTree(map.tree(), colour);
  std::unique_ptr<octomap::AbstractOcTree> read(octomap::AbstractOcTree::read(colour));
  const auto* colour_tree = dynamic_cast<const octomap::ColorOcTree*>(read.get());
  ASSERT_NE(colour_tree, nullptr);
  EXPECT_EQ(colour_tree->size(), 0u);
  saveSurfacePcd(map.tree(), pcd);
  std::ifstream in(pcd);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("\nPOINTS 0\nDATA ascii\n"), std::string::npos) << text;
  EXPECT_EQ(text.substr(text.size() - 11), "DATA ascii\n");
}

std::string loadError(const std::string& path) {
  try {
    (void)loadMobilityMap(path);
  } catch (const MapIoError& e) {
    return e.what();
  }
  return "no error";
}

TEST(MapFiles, HostileFilesGiveClearErrors) {
  const MobilityMap map = builtMap();
  const std::string good = tempPath("good.ot");
  saveMobilityMap(map.tree(), good);
  std::string bytes;
  {
    std::ifstream in(good, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  for (double frac : {0.99, 0.7, 0.3}) {
    const std::string cut = tempPath("cut.ot");
    std::ofstream(cut, std::ios::binary) << bytes.substr(0, static_cast<std::size_t>(bytes.size() * frac));
    const std::string e = loadError(cut);
    EXPECT_NE(e.find("cut.ot: "), std::string::npos) << e;
    EXPECT_NE(e.find("truncated"), std::string::npos) << e;
  }
  EXPECT_NE(loadError(tempPath("missing.ot")).find("no such file"), std::string::npos);
  const std::string junk = tempPath("junk.ot");
  std::ofstream(junk) << "hello\n";
  EXPECT_NE(loadError(junk).find("not an OctoMap .ot file"), std::string::npos);
  // A stock OcTree and a .bt are recognised as such.
  octomap::OcTree plain(0.1);
  plain.updateNode(octomap::point3d(0, 0, 0), true);
  const std::string other = tempPath("plain.ot");
  plain.write(other);
  EXPECT_NE(loadError(other).find("holds an OctoMap 'OcTree'"), std::string::npos) << loadError(other);
  const std::string bt = tempPath("occ.bt");
  saveOccupancyBt(map.tree(), bt);
  EXPECT_NE(loadError(bt).find(".bt"), std::string::npos);
  // A map from a future layout.
  std::string future = bytes;
  future.replace(future.find("MobilityOcTree_v1"), 17, "MobilityOcTree_v9");
  const std::string fut = tempPath("future.ot");
  std::ofstream(fut, std::ios::binary) << future;
  EXPECT_NE(loadError(fut).find("another version"), std::string::npos);
}

// A .ot whose tree is one chain from the root down to a single occupied leaf at `depth`:
// 9 bytes per node, a leaf that stands for (2^(16 - depth))^3 voxels.
std::string chainToLeaf(unsigned int depth, const std::string& res = "0.02") {
  std::string data;
  for (unsigned int d = 0; d <= depth; ++d) {
    const float log_odds = 2.0f;
    const std::uint32_t payload = 0;
    data.append(reinterpret_cast<const char*>(&log_odds), 4);
    data.append(reinterpret_cast<const char*>(&payload), 4);
    data.push_back(d < depth ? '\x01' : '\x00');
  }
  return "# Octomap OcTree file\nid MobilityOcTree_v1\nsize " + std::to_string(depth + 1) + "\nres " + res + "\ndata\n" + data;
}

// The map origin: a frame at UTM-sized coordinates fuses into the same voxels as the
// same frame at home when the origin moves with it, and the points beyond the map's
// extent are counted, equal to a brute-force count.
TEST(MobilityMap, TheOriginKeepsFarCoordinatesExactAndPointsOutsideAreCounted) {
  const perception::FrameResult frame = syntheticFrame();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() << 1, 0, 0, 0, 0, 1, 0, -1, 0;  // camera looking along +y, its y down
  T.translation() = Eigen::Vector3d(0.3, -0.2, 1.2);
  MobilityMap home;
  const IntegrationReport at_home = home.integrate(frame, T);
  EXPECT_EQ(at_home.points_fused, frame.points.size());
  EXPECT_EQ(at_home.points_outside_map, 0u);
  const Eigen::Vector3d far(2.0e6, 5.0e6, 300.0);
  Eigen::Isometry3d T_far = T;
  T_far.translation() += far;
  MobilityMap away(MapParams{}, Eigen::Matrix3d::Identity(), far);
  EXPECT_EQ(away.integrate(frame, T_far).points_fused, frame.points.size());
  away.finalize();
  home.finalize();
  std::ostringstream a, b;
  home.tree().write(a);
  away.tree().write(b);
  EXPECT_EQ(a.str(), b.str());
  EXPECT_EQ(away.worldToMap(far + Eigen::Vector3d(1, 2, 3)), Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(away.mapToWorld(Eigen::Vector3d(1, 2, 3)), far + Eigen::Vector3d(1, 2, 3));
  EXPECT_THROW(away.setOriginWorld(Eigen::Vector3d::Zero()), std::logic_error);
  // Without the origin the frame lies 2000 km outside: every point counted, none fused.
  MobilityMap lost;
  const IntegrationReport nothing = lost.integrate(frame, T_far);
  EXPECT_EQ(nothing.points_fused, 0u);
  EXPECT_EQ(nothing.points_outside_map, frame.points.size());
  EXPECT_EQ(lost.tree().size(), 0u);
  // Part way out: the camera 655 m from the origin, the map's edge through the frame.
  MobilityMap edge;
  EXPECT_DOUBLE_EQ(edge.extentM(), 655.36);
  Eigen::Isometry3d T_edge = T;
  T_edge.translation().y() = 655.36 - 1.4;
  std::size_t beyond = 0;
  for (const auto& p : frame.points) {
    const Eigen::Vector3d w = T_edge * p.cast<double>();
    beyond += w.cwiseAbs().maxCoeff() >= 655.36 ? 1 : 0;
  }
  ASSERT_GT(beyond, 0u);
  ASSERT_LT(beyond, frame.points.size());
  const IntegrationReport part = edge.integrate(frame, T_edge);
  EXPECT_EQ(part.points_outside_map, beyond);
  EXPECT_EQ(part.points_fused + part.points_outside_map, frame.points.size());
  EXPECT_THROW(MobilityMap(MapParams{}, Eigen::Matrix3d::Identity(), Eigen::Vector3d(std::nan(""), 0, 0)), std::invalid_argument);
}

TEST(MapFiles, ALeafStandingForMoreVoxelsThanTheFileCanHoldIsRefusedNotExpanded) {
  // The 73-byte root leaf (2^48 voxels) and a depth-9 leaf (2^21 voxels, ~140 MB of index)
  // used to be expanded voxel by voxel until memory ran out.
  for (unsigned int depth : {0u, 5u, 9u}) {
    const std::string path = tempPath("leaf" + std::to_string(depth) + ".ot");
    std::ofstream(path, std::ios::binary) << chainToLeaf(depth);
    if (depth == 0) {
      EXPECT_EQ(std::filesystem::file_size(path), 73u);
    }
    const std::string e = loadError(path);
    EXPECT_EQ(e.rfind(path + ": ", 0), 0u) << e;
    EXPECT_NE(e.find("stand for more than 1048576 occupied voxels"), std::string::npos) << e;
    EXPECT_NE(e.find("at depth " + std::to_string(depth)), std::string::npos) << e;
    // The library refuses the same tree handed to it directly.
    MobilityOcTree tree(0.02);
    std::istringstream in(chainToLeaf(depth).substr(chainToLeaf(depth).find("data\n") + 5));
    ASSERT_EQ(tree.readDataChecked(in, depth + 1), "");
    EXPECT_THROW(MobilityMap(std::make_unique<MobilityOcTree>(std::move(tree)), MapParams{}, Eigen::Matrix3d::Identity()),
                 std::invalid_argument);
  }
  // A depth-10 leaf (64^3 = 262144 voxels) is within the budget: the map opens, and every
  // voxel of the block answers as surface, none outside it.
  const std::string ok = tempPath("leaf10.ot");
  std::ofstream(ok, std::ios::binary) << chainToLeaf(10);
  auto tree = loadMobilityMap(ok);
  EXPECT_EQ(countOccupiedVoxels(*tree, ~std::uint64_t{0}), std::optional<std::uint64_t>(262144));
  const MobilityMap map = openMap(ok);
  // The chain takes child 0 at every level: the block's lowest corner is key 0.
  const octomap::point3d corner = map.tree().keyToCoord(octomap::OcTreeKey(0, 0, 0));
  const Eigen::Vector3d c(corner.x(), corner.y(), corner.z());
  EXPECT_EQ(map.query(c).state, VoxelState::kSurface);
  EXPECT_EQ(map.query(c + Eigen::Vector3d::Constant(63 * 0.02)).state, VoxelState::kSurface);
  EXPECT_EQ(map.query(c + Eigen::Vector3d::Constant(64 * 0.02)).state, VoxelState::kUnknown);
  EXPECT_EQ(map.query(c - Eigen::Vector3d::Constant(0.02)).state, VoxelState::kUnknown);
}

std::string lockError(const std::string& ot) {
  try {
    const MapLock lock(ot);
  } catch (const MapIoError& e) {
    return e.what();
  }
  return "no error";
}

TEST(MapLock, OneWriterAtATimeAndADeadHolderBlocksNobody) {
  const std::string dir = tempPath("lockdir");
  std::filesystem::create_directories(dir);
  const std::string ot = dir + "/m.ot";
  EXPECT_EQ(mapLockPath(ot), dir + "/m.lock");
  {
    const MapLock held(ot);
    EXPECT_TRUE(std::filesystem::exists(held.path()));
    const std::string e = lockError(ot);
    EXPECT_EQ(e.rfind(ot + ": is being written by another process (pid " + std::to_string(::getpid()) + " holds " +
                          dir + "/m.lock)", 0),
              0u)
        << e;
    EXPECT_EQ(lockError(dir + "/other.ot"), "no error");  // another map is another lock
  }
  EXPECT_FALSE(std::filesystem::exists(dir + "/m.lock"));  // removed on release
  // A lock file left behind by a writer that is gone (its pid inside, nobody holding it).
  std::ofstream(dir + "/m.lock") << "999999\n";
  EXPECT_EQ(lockError(ot), "no error");
  // A writer killed while it holds the lock: the system releases it. The child says
  // when it holds it through a pipe; no timing involved.
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(ready[0]);
    const MapLock held(ot);
    const char c = 'x';
    if (::write(ready[1], &c, 1) != 1) ::_exit(1);
    for (;;) ::pause();
  }
  ::close(ready[1]);
  char c = 0;
  ASSERT_EQ(::read(ready[0], &c, 1), 1);
  ::close(ready[0]);
  EXPECT_NE(lockError(ot).find("(pid " + std::to_string(child) + " holds"), std::string::npos) << lockError(ot);
  ::kill(child, SIGKILL);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  EXPECT_EQ(lockError(ot), "no error");
  std::filesystem::remove_all(dir);
}

TEST(MapFiles, AResolutionThatIsNotAUsableNumberIsNamed) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"nan", "res 'nan' is not a finite number"},     {"inf", "res 'inf' is not a finite number"},
      {"0.02x", "res '0.02x' is not a finite number"}, {"1e-300", "res 1e-300 m is outside"},
      {"20", "res 20 m is outside"},                   {"-0.02", "res -0.02 m is outside"}};
  for (const auto& [res, expected] : cases) {
    const std::string path = tempPath("res.ot");
    std::ofstream(path, std::ios::binary) << chainToLeaf(16, res);
    const std::string e = loadError(path);
    EXPECT_EQ(e.rfind(path + ": ", 0), 0u) << e;
    EXPECT_NE(e.find(expected), std::string::npos) << res << ": " << e;
  }
  const std::string no_res = tempPath("nores.ot");
  std::ofstream(no_res, std::ios::binary) << "# Octomap OcTree file\nid MobilityOcTree_v1\nsize 1\ndata\n";
  EXPECT_NE(loadError(no_res).find("header has no 'res'"), std::string::npos) << loadError(no_res);
  // A one-voxel map at the finest level is fine.
  const std::string fine = tempPath("fine.ot");
  std::ofstream(fine, std::ios::binary) << chainToLeaf(16);
  EXPECT_EQ(loadError(fine), "no error");
}

TEST(MapFiles, BtAndOctovisExportLoadInStockOctomapWithTheSameOccupiedVoxels) {
  const MobilityMap map = builtMap();
  std::set<octomap::OcTreeKey, bool (*)(const octomap::OcTreeKey&, const octomap::OcTreeKey&)> ours(
      [](const octomap::OcTreeKey& a, const octomap::OcTreeKey& b) {
        return std::tie(a[0], a[1], a[2]) < std::tie(b[0], b[1], b[2]);
      });
  for (auto it = map.tree().begin_leafs(); it != map.tree().end_leafs(); ++it) {
    if (map.tree().isNodeOccupied(*it)) ours.insert(it.getKey());
  }
  ASSERT_GT(ours.size(), 1000u);
  const std::string bt = tempPath("map.bt");
  saveOccupancyBt(map.tree(), bt);
  octomap::OcTree stock(0.1);
  ASSERT_TRUE(stock.readBinary(bt));
  EXPECT_DOUBLE_EQ(stock.getResolution(), map.tree().getResolution());
  std::size_t occupied = 0;
  for (auto it = stock.begin_leafs(); it != stock.end_leafs(); ++it) {
    if (!stock.isNodeOccupied(*it)) continue;
    ++occupied;
    EXPECT_TRUE(ours.count(it.getKey())) << "extra occupied voxel";
  }
  EXPECT_EQ(occupied, ours.size());

  const std::string ov = tempPath("map.octovis.ot");
  saveOctovisColorTree(map.tree(), ov);
  std::unique_ptr<octomap::AbstractOcTree> abstract(octomap::AbstractOcTree::read(ov));
  auto* colour = dynamic_cast<octomap::ColorOcTree*>(abstract.get());
  ASSERT_NE(colour, nullptr);
  std::size_t coloured = 0;
  for (auto it = colour->begin_leafs(); it != colour->end_leafs(); ++it) {
    if (!colour->isNodeOccupied(*it)) continue;
    ++coloured;
    ASSERT_TRUE(ours.count(it.getKey()));
    const auto q = map.query(Eigen::Vector3d(it.getX(), it.getY(), it.getZ()));
    const auto c = it->getColor();
    if (q.mobility > 0.99) {
      EXPECT_GT(c.g, 200);  // green
    }
    if (q.mobility < 0.01) {
      EXPECT_EQ(c.g, 0);  // red
    }
  }
  EXPECT_EQ(coloured, ours.size());
}

// A colour per voxel: a pruned block is written voxel by voxel, each in the colour its
// own key is given, and stock OctoMap reads every one back.
TEST(MapFiles, OctovisExportColoursEachVoxelByItsKeyAlsoInsidePrunedBlocks) {
  MobilityOcTree t(0.02);
  // An 8 x 8 x 8 block aligned to the tree's 8-voxel cells (keys from 32768), one value
  // throughout so it prunes, and one lone voxel with another mobility.
  std::set<std::tuple<int, int, int>> voxels;
  for (int i = 0; i < 8; ++i) {
    for (int j = 0; j < 8; ++j) {
      for (int k = 0; k < 8; ++k) {
        const octomap::OcTreeKey key(static_cast<octomap::key_type>(32768 + i), static_cast<octomap::key_type>(32768 + j),
                                     static_cast<octomap::key_type>(32768 + k));
        auto* n = t.updateNode(key, 2.0f);
        n->setMobility(0.8, 0.01, 2);
        voxels.insert({32768 + i, 32768 + j, 32768 + k});
      }
    }
  }
  auto* lone = t.updateNode(octomap::OcTreeKey(32800, 32800, 32800), 2.0f);
  lone->setMobility(0.1, 0.01, 2);
  voxels.insert({32800, 32800, 32800});
  t.updateInnerOccupancy();
  t.prune();
  std::size_t leaves = 0, widest = 0;
  for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) {
    ++leaves;
    widest = std::max<std::size_t>(widest, std::lround(it.getSize() / 0.02));
  }
  ASSERT_EQ(widest, 8u) << "the block did not prune";
  ASSERT_EQ(leaves, 2u);
  const auto code = [](const octomap::OcTreeKey& k) {
    return VoxelRgb{static_cast<std::uint8_t>(k[0] % 256), static_cast<std::uint8_t>(k[1] % 256),
                    static_cast<std::uint8_t>((k[2] * 7) % 256)};
  };
  const std::string ov = tempPath("keys.octovis.ot");
  saveOctovisColorTree(t, ov, [&](const octomap::OcTreeKey& k, const MobilityOcTreeNode& n) {
    // The node is the leaf holding the voxel: the block's or the lone voxel's.
    EXPECT_NEAR(n.mobility(), k[0] == 32800 ? 0.1 : 0.8, 1e-3);  // stored in 16 bits
    return code(k);
  });
  std::unique_ptr<octomap::AbstractOcTree> abstract(octomap::AbstractOcTree::read(ov));
  auto* colour = dynamic_cast<octomap::ColorOcTree*>(abstract.get());
  ASSERT_NE(colour, nullptr);
  std::set<std::tuple<int, int, int>> read;
  for (auto it = colour->begin_leafs(); it != colour->end_leafs(); ++it) {
    ASSERT_EQ(it.getDepth(), 16u);
    const octomap::OcTreeKey k = it.getKey();
    read.insert({k[0], k[1], k[2]});
    EXPECT_EQ(it->getColor(), octomap::ColorOcTreeNode::Color(code(k)[0], code(k)[1], code(k)[2]));
  }
  EXPECT_EQ(read, voxels);
  // The one-argument export is this with the mobility colours.
  EXPECT_EQ(mobilityRgb(*t.search(octomap::OcTreeKey(32800, 32800, 32800))), (VoxelRgb{255, 44, 0}));
  MobilityOcTreeNode unknown;
  EXPECT_EQ(mobilityRgb(unknown), (VoxelRgb{140, 140, 140}));
  std::remove(ov.c_str());
}

TEST(MapParams, RejectsAbsurdValuesNamingTheField) {
  MapParams p;
  p.resolution_m = -0.02;
  try {
    MobilityMap{p};
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("resolution_m"), std::string::npos);
  }
  p = {};
  p.prob_hit = 0.4;
  EXPECT_THROW(MobilityMap{p}, std::invalid_argument);
}

TEST(MobilityMap, MapFrameMustBeARotation) {
  Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
  r(2, 2) = 2.0;  // a stretch
  EXPECT_THROW((MobilityMap{MapParams{}, r}), std::invalid_argument);
  r(2, 2) = -1.0;  // a reflection
  EXPECT_THROW((MobilityMap{MapParams{}, r}), std::invalid_argument);
  r(2, 2) = std::nan("");
  EXPECT_THROW((MobilityMap{MapParams{}, r}), std::invalid_argument);
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const MobilityMap map(MapParams{}, turn);
  EXPECT_TRUE(map.worldToMap(Eigen::Vector3d(1, 0, 0)).isApprox(turn.col(0)));
}

TEST(Gravity, AlignmentSendsGravityToMinusZAndIsIdentityForZUp) {
  const Eigen::Vector3d g(-0.0089, 0.9044, 0.4265);  // 7-Scenes redkitchen
  const Eigen::Matrix3d r = gravityAlignment(g);
  EXPECT_LT((r * g.normalized() - Eigen::Vector3d(0, 0, -1)).norm(), 1e-12);
  EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
  EXPECT_LT((gravityAlignment({0, 0, -3}) - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_LT((gravityAlignment({0, 0, 1}) * Eigen::Vector3d(0, 0, 1) - Eigen::Vector3d(0, 0, -1)).norm(), 1e-12);
  EXPECT_THROW(gravityAlignment(Eigen::Vector3d::Zero()), std::invalid_argument);
}

// Floors seen in five frames, 1-2 degrees apart around a known "down", and two frames
// that took a wall for the floor (one of them heavier than any single floor).
TEST(Gravity, ConsensusOfFloorNormalsOutvotesWallsAndAveragesTheFloors) {
  const Eigen::Vector3d truth = Eigen::Vector3d(0.31, -0.93, 0.19).normalized();
  const Eigen::Vector3d side = truth.unitOrthogonal();
  const auto tilted = [&](double deg, const Eigen::Vector3d& axis) {
    return Eigen::AngleAxisd(deg * M_PI / 180.0, axis.cross(truth).normalized()) * truth;
  };
  std::vector<DownObservation> obs;
  for (double deg : {-1.5, -0.5, 0.0, 0.5, 1.5}) obs.push_back({tilted(deg, side), 1000.0});
  const Eigen::Vector3d wall = side;
  obs.push_back({wall, 3000.0});
  obs.push_back({truth.cross(wall), 500.0});  // another vertical plane
  obs.push_back({Eigen::Vector3d(std::nan(""), 0, 0), 1e9});            // ignored
  obs.push_back({Eigen::Vector3d::Zero(), 1e9});                         // ignored
  obs.push_back({truth, 0.0});                                            // no weight: ignored
  const auto c = consensusDown(obs, 5.0);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->agreeing, 5);
  EXPECT_NEAR(c->weight_share, 5000.0 / 8500.0, 1e-12);
  EXPECT_LT(std::acos(std::min(1.0, c->down.dot(truth))) * 180.0 / M_PI, 0.01);  // symmetric tilts cancel
  EXPECT_NEAR(c->spread_deg, 1.5, 1e-6);
  EXPECT_NEAR(c->down.norm(), 1.0, 1e-12);
  // Scale does not matter; only the weights do.
  std::vector<DownObservation> scaled = {{truth * 9.81, 1.0}, {-truth * 1e-3, 2.0}};
  const auto up_wins = consensusDown(scaled);
  ASSERT_TRUE(up_wins);
  EXPECT_LT((up_wins->down + truth).norm(), 1e-12);
  EXPECT_EQ(up_wins->agreeing, 1);
  EXPECT_FALSE(consensusDown({}));
  EXPECT_FALSE(consensusDown({{Eigen::Vector3d::Zero(), 1.0}}));
}

TEST(Gravity, CheckRigidNamesTheProblem) {
  Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
  EXPECT_FALSE(checkRigid(t));
  t(0, 0) = 1.1;
  EXPECT_NE(checkRigid(t)->find("orthonormal"), std::string::npos);
  t = Eigen::Matrix4d::Identity();
  t(3, 0) = 1;
  EXPECT_NE(checkRigid(t)->find("bottom row"), std::string::npos);
  t = Eigen::Matrix4d::Identity();
  t(1, 1) = std::nan("");
  EXPECT_NE(checkRigid(t)->find("NaN"), std::string::npos);
}

}  // namespace
}  // namespace mobmap::mapping
