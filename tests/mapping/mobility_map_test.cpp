// MobilityMap: fusion with poses, queries, free space, threads, the map frame and far
// coordinates.
#include "mapping_support.hpp"

#include <limits>

namespace mobmap::mapping {
namespace {

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
  // A sole across the foot of the wall: the wall rises above the 0.3 m searched, so its
  // columns hold nothing to rest on and the sole is partly unsupported (as a robot's
  // sole is judged); searched up over the wall's top, the sole touches untraversable
  // voxels there.
  const FootprintQuery edge = map.footprint({1.61, 0.0, 0.0, 0.0, 0.2, 0.1}, 0.3, 0.1);
  EXPECT_GT(edge.known_fraction, 0.2);
  EXPECT_LT(edge.known_fraction, 0.9);
  EXPECT_LE(edge.max_height_difference_m, 1e-6);
  const FootprintQuery over = map.footprint({1.61, 0.0, 0.0, 0.0, 0.2, 0.1}, 3.0, 0.1);
  EXPECT_GT(over.known_fraction, 0.0);
  EXPECT_NEAR(over.min_mobility, 0.0, 1e-3);
}

// Points beyond the map, however far (past float's range, where OctoMap's own key
// computation would be undefined), are unknown: no voxel, no surface, no sole support.
TEST(MobilityMap, PointsBeyondAnyMapAreUnknown) {
  const MobilityMap map = builtMap();
  const double inf = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(1e308, -1e308, 0), Eigen::Vector3d(1.3, 0, 1e39),
                                   Eigen::Vector3d(1.3, 4e9, 0), Eigen::Vector3d(-inf, 0, 0),
                                   Eigen::Vector3d(1.3, 0, 655.37 * 2)}) {
    EXPECT_EQ(map.query(p).state, VoxelState::kUnknown) << p.transpose();
    EXPECT_FALSE(map.snapDown(p, 0.5)) << p.transpose();
    const FootprintQuery f = map.footprint({p.x(), p.y(), p.z(), 0.0, 0.2, 0.1});
    EXPECT_EQ(f.known_fraction, 0.0) << p.transpose();
  }
  EXPECT_EQ(map.query({1.3, 0.0, 0.01}).state, VoxelState::kSurface);  // what is in the map still is
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

}  // namespace
}  // namespace mobmap::mapping
