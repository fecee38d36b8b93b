// Reachability: which standable places a robot gets to by steps and small gaps, against
// an analytic scene and a brute-force reference on random maps.
#include "mobmap/mapping/reachability.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <tuple>

namespace mobmap::mapping {
namespace {

constexpr double kRes = 0.02;

// Sets voxel (i, j, k) of a 2 cm tree (voxel centres at (i + 0.5) * kRes ...) occupied with a mobility.
void put(MobilityOcTree& t, int i, int j, int k, double mobility) {
  auto* n = t.updateNode(octomap::point3d(static_cast<float>((i + 0.5) * kRes), static_cast<float>((j + 0.5) * kRes),
                                          static_cast<float>((k + 0.5) * kRes)),
                         true);
  n->setMobility(mobility, 100.0, 3);
}

// A floor (tops at 0.02 m) with stairs up to a platform, a ledge, a table, a walled room,
// a hole across the floor, a dais beside a noisy floor voxel and a strip of poor floor
// in front of an annex. Every region
// is a rectangle of columns [i0, i1) x [j0, j1).
struct Scene {
  MobilityOcTree tree{kRes};
  Scene() {
    // Floor x in [0, 3.0), y in [0, 2.0), except a 2-column hole at x in [0.40, 0.44)
    // and the wall ring's footprint.
    for (int i = 0; i < 150; ++i) {
      for (int j = 0; j < 100; ++j) {
        if (i == 20 || i == 21) continue;
        if (inRing(i, j)) continue;
        put(tree, i, j, 0, 1.0);
      }
    }
    // Stairs on the floor, y in [0, 0.6): treads 0.10 m apart from x = 1.0, then a
    // platform at 0.32 m; solid columns, the top voxel walkable, the rest a riser.
    for (int i = 50; i < 100; ++i) {
      const int top = i < 65 ? 5 : i < 80 ? 10 : 15;  // tops 0.12, 0.22, 0.32
      for (int j = 0; j < 30; ++j) {
        for (int k = 1; k <= top; ++k) put(tree, i, j, k, k == top ? 1.0 : 0.0);
      }
    }
    // A ledge 0.30 m above the floor (top 0.32), x in [2.3, 2.8), y in [0, 0.6).
    for (int i = 115; i < 140; ++i) {
      for (int j = 0; j < 30; ++j) {
        for (int k = 1; k <= 15; ++k) put(tree, i, j, k, k == 15 ? 1.0 : 0.0);
      }
    }
    // A table top (one voxel thick, top 0.72 m) over the floor, no legs.
    for (int i = 10; i < 40; ++i) {
      for (int j = 60; j < 90; ++j) put(tree, i, j, 35, 1.0);
    }
    // A room with a 1 m wall one voxel thick around its floor.
    for (int i = 110; i < 150; ++i) {
      for (int j = 60; j < 100; ++j) {
        if (inRing(i, j)) {
          for (int k = 0; k < 50; ++k) put(tree, i, j, k, 0.0);
        }
      }
    }
    // A dais with its top 16 cm above the floor's (0.18 m), x and y in [0.2, 0.3), and
    // beside it one floor voxel a voxel too high (noise): 14 cm from the dais's top.
    for (int i = 10; i < 15; ++i) {
      for (int j = 10; j < 15; ++j) {
        for (int k = 1; k <= 8; ++k) put(tree, i, j, k, k == 8 ? 1.0 : 0.0);
      }
    }
    put(tree, 9, 12, 1, 1.0);
    // An annex, x in [3.1, 3.5), y in [0, 0.8), reached only over floor of mobility 0.2
    // 10 cm wide along its west side (x in [3.0, 3.1)) and its north side (y in [0.8, 0.9)).
    for (int i = 150; i < 175; ++i) {
      for (int j = 0; j < 45; ++j) put(tree, i, j, 0, i < 155 || j >= 40 ? 0.2 : 1.0);
    }
  }
  static bool inRing(int i, int j) {
    return i >= 110 && i < 150 && j >= 60 && j < 100 && (i == 110 || i == 149 || j == 60 || j == 99);
  }
};

// The place in the column of (x, y) whose top face is at `top` (metres).
const Place& placeAt(const Reachability& r, double x, double y, double top) {
  const Place* p = r.placeBelow({x, y, top - kRes / 2}, 0.0);
  if (!p) throw std::runtime_error("no place at " + std::to_string(x) + " " + std::to_string(y) + " " + std::to_string(top));
  return *p;
}

TEST(Reachability, StepsLedgesTablesWallsHolesAndPoorFloor) {
  const Scene s;
  const Eigen::Vector3d camera(1.505, 0.8, 1.3);  // above the open floor
  const Reachability r = computeReachability(s.tree, camera);
  ASSERT_TRUE(r.start());
  EXPECT_NEAR(r.places()[*r.start()].top_z, 0.02, 1e-9);
  EXPECT_NEAR(r.places()[*r.start()].x, 1.51, 1e-9);  // the column under the camera
  // Open floor, both sides of the 4 cm hole, under the table (no clearance asked).
  EXPECT_TRUE(placeAt(r, 1.5, 1.0, 0.02).reachable);
  EXPECT_TRUE(placeAt(r, 0.1, 0.5, 0.02).reachable);
  EXPECT_TRUE(placeAt(r, 0.5, 1.5, 0.02).reachable);
  // Stairs of 10 cm risers, and the platform they lead to.
  EXPECT_TRUE(placeAt(r, 1.1, 0.3, 0.12).reachable);
  EXPECT_TRUE(placeAt(r, 1.7, 0.3, 0.32).reachable);
  // A 30 cm ledge, a table top, a walled room, the annex beyond poor floor: not reachable,
  // though each can be stood on.
  for (const auto& [x, y, top] : {std::tuple{2.5, 0.3, 0.32}, {0.5, 1.5, 0.72}, {2.6, 1.6, 0.02}, {3.3, 0.4, 0.02}}) {
    const Place& p = placeAt(r, x, y, top);
    EXPECT_TRUE(p.standable) << x << " " << y;
    EXPECT_FALSE(p.reachable) << x << " " << y;
  }
  // The poor strip and the wall cannot be stood on at all.
  EXPECT_FALSE(placeAt(r, 3.05, 0.4, 0.02).standable);
  EXPECT_FALSE(placeAt(r, 2.21, 1.5, 1.0).standable);
  // Headroom under the table: 0.70 - 0.02 m.
  EXPECT_NEAR(placeAt(r, 0.5, 1.5, 0.02).headroom_m, 0.68, 1e-9);
  EXPECT_TRUE(std::isinf(placeAt(r, 0.5, 1.5, 0.72).headroom_m));

  // Counts: every standable place is one of the regions above.
  std::size_t reachable = 0;
  for (const Place& p : r.places()) reachable += p.reachable;
  EXPECT_EQ(reachable, r.reachableCount());

  // The dais: tops 7 voxels apart (the noisy floor voxel) may hide a step of nearly 8,
  // 16 cm, more than 15; within 20 cm it is reachable.
  EXPECT_TRUE(placeAt(r, 0.19, 0.25, 0.04).reachable);
  EXPECT_FALSE(placeAt(r, 0.25, 0.25, 0.18).reachable);

  // Each limit moves what is reachable, and only that.
  ReachParams p;
  p.max_step_m = 0.30;  // tops 15 voxels apart may hide a step of nearly 16: not enough
  EXPECT_FALSE(placeAt(computeReachability(s.tree, camera, p), 2.5, 0.3, 0.32).reachable);
  p.max_step_m = 0.32;
  EXPECT_TRUE(placeAt(computeReachability(s.tree, camera, p), 2.5, 0.3, 0.32).reachable);
  p.max_step_m = 0.20;
  EXPECT_TRUE(placeAt(computeReachability(s.tree, camera, p), 0.25, 0.25, 0.18).reachable);
  p.max_step_m = 0.09;  // the 10 cm stairs are too high now
  const Reachability low = computeReachability(s.tree, camera, p);
  EXPECT_FALSE(placeAt(low, 1.1, 0.3, 0.12).reachable);
  EXPECT_TRUE(placeAt(low, 0.1, 0.5, 0.02).reachable);
  p = {};
  p.max_gap_m = 0.02;  // the 4 cm hole is too wide
  EXPECT_FALSE(placeAt(computeReachability(s.tree, camera, p), 0.1, 0.5, 0.02).reachable);
  p.max_gap_m = 0.5;  // a wide gap still never crosses the room's wall or the poor strip
  const Reachability wide = computeReachability(s.tree, camera, p);
  EXPECT_FALSE(placeAt(wide, 2.6, 1.6, 0.02).reachable);
  EXPECT_FALSE(placeAt(wide, 3.3, 0.4, 0.02).reachable);
  p = {};
  p.min_mobility = 0.1;  // now the strip is floor too
  EXPECT_TRUE(placeAt(computeReachability(s.tree, camera, p), 3.3, 0.4, 0.02).reachable);
  p = {};
  p.clearance_m = 1.0;  // too tall to stand under the table; the open floor is fine
  const Reachability tall = computeReachability(s.tree, camera, p);
  EXPECT_FALSE(placeAt(tall, 0.5, 1.5, 0.02).standable);
  EXPECT_TRUE(placeAt(tall, 1.5, 1.0, 0.02).reachable);
  EXPECT_TRUE(placeAt(tall, 0.1, 0.5, 0.02).reachable);  // around the table

  // A start over the table (and below its top, so the table is excluded) starts on the floor.
  const Reachability under = computeReachability(s.tree, {0.5, 1.5, 0.5});
  ASSERT_TRUE(under.start());
  EXPECT_NEAR(under.places()[*under.start()].top_z, 0.02, 1e-9);
  // Starting on the table reaches the table alone.
  const Reachability on_table = computeReachability(s.tree, {0.5, 1.5, 1.5});
  ASSERT_TRUE(on_table.start());
  EXPECT_EQ(on_table.reachableCount(), 30u * 30u);
  // Unless the start is on the largest level near the point: the floor.
  ReachParams largest;
  largest.start_rule = ReachParams::Start::kLargestLevel;
  const Reachability floor = computeReachability(s.tree, {0.5, 1.5, 1.5}, largest);
  ASSERT_TRUE(floor.start());
  EXPECT_NEAR(floor.places()[*floor.start()].top_z, 0.02, 1e-9);
  EXPECT_EQ(floor.reachableCount(), r.reachableCount());
  // Nothing standable near the start: no start, nothing reachable.
  const Reachability nowhere = computeReachability(s.tree, {10.0, 10.0, 1.0});
  EXPECT_FALSE(nowhere.start());
  EXPECT_EQ(nowhere.reachableCount(), 0u);
}

TEST(SoleSamples, OnePerVoxelCellCentresTurnedWithTheYawAndNoneForInvalidSoles) {
  for (const double yaw : {0.0, 0.7, M_PI / 2}) {
    const Foot f{1.0, -2.0, 0.3, yaw, 0.25, 0.12};
    const std::vector<SoleSample> samples = soleSamples(f, kRes);
    ASSERT_EQ(samples.size(), 13u * 6u);  // ceil(0.25 / 0.02) x ceil(0.12 / 0.02)
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    std::set<std::pair<long, long>> cells;
    for (const SoleSample& s : samples) {
      // Cell centres of a 13 x 6 grid over the sole: a = (i + 0.5) * 0.25 / 13 - 0.125.
      const double i = (s.a + 0.125) / (0.25 / 13) - 0.5, j = (s.b + 0.06) / 0.02 - 0.5;
      EXPECT_NEAR(i, std::round(i), 1e-9);
      EXPECT_NEAR(j, std::round(j), 1e-9);
      cells.insert({std::lround(i), std::lround(j)});
      EXPECT_NEAR(s.x, 1.0 + std::cos(yaw) * s.a - std::sin(yaw) * s.b, 1e-12);
      EXPECT_NEAR(s.y, -2.0 + std::sin(yaw) * s.a + std::cos(yaw) * s.b, 1e-12);
      mean += Eigen::Vector2d(s.x, s.y);
    }
    EXPECT_EQ(cells.size(), samples.size());  // every cell once
    EXPECT_LT((mean / samples.size() - Eigen::Vector2d(1.0, -2.0)).norm(), 1e-12);
  }
  EXPECT_EQ(soleSamples({0, 0, 0, 0, 0.01, 0.01}, kRes).size(), 1u);  // smaller than a voxel: one
  EXPECT_TRUE(soleSamples({0, 0, 0, 0, 0.0, 0.1}, kRes).empty());
  EXPECT_TRUE(soleSamples({0, 0, 0, NAN, 0.2, 0.1}, kRes).empty());
  EXPECT_TRUE(soleSamples({INFINITY, 0, 0, 0, 0.2, 0.1}, kRes).empty());
  EXPECT_TRUE(soleSamples({0, 0, 0, 0, 1e6, 0.1}, kRes).empty());  // 5e7 voxels long
  EXPECT_TRUE(soleSamples({0, 0, 0, 0, 0.2, 0.1}, 0.0).empty());
}

TEST(Reachability, SoleCountsTheSamplesOnReachablePlaces) {
  const Scene s;
  const Reachability r = computeReachability(s.tree, {1.505, 0.8, 1.3});
  // 24 x 12 cm soles: 12 x 6 samples, one per column.
  const auto sole = [&](double x, double y, double z) { return r.sole({x, y, z, 0.0, 0.24, 0.12}, 0.1, 0.4); };
  const SoleReach open = sole(1.5, 1.0, 0.02);
  EXPECT_EQ(open.samples, 72);
  EXPECT_EQ(open.on_place, 72);
  EXPECT_EQ(open.reachable, 72);
  EXPECT_DOUBLE_EQ(open.reachableFraction(), 1.0);
  // On the ledge (30 cm up): every sample can be stood on, none reached.
  const SoleReach ledge = sole(2.5, 0.3, 0.32);
  EXPECT_EQ(ledge.standable, 72);
  EXPECT_EQ(ledge.reachable, 0);
  // Across the ledge's edge at x = 2.30, at the ledge's height: the 6 columns of samples
  // west of it find the floor 0.30 m down (within the 0.4 searched), the 6 east of it the ledge.
  const SoleReach edge = sole(2.30, 0.3, 0.32);
  EXPECT_EQ(edge.on_place, 72);
  EXPECT_EQ(edge.standable, 72);
  EXPECT_EQ(edge.reachable, 36);
  EXPECT_DOUBLE_EQ(edge.reachableFraction(), 0.5);
  // Searching only 0.1 m down, the floor is out of the band: the west half finds nothing.
  const SoleReach shallow = r.sole({2.30, 0.3, 0.32, 0.0, 0.24, 0.12}, 0.1, 0.1);
  EXPECT_EQ(shallow.on_place, 36);
  EXPECT_EQ(shallow.reachable, 0);
  // Over the 4 cm hole (x in [0.40, 0.44)): two of its 12 columns of samples have no place.
  const SoleReach hole = sole(0.42, 0.5, 0.02);
  EXPECT_EQ(hole.on_place, 60);
  EXPECT_EQ(hole.reachable, 60);
  EXPECT_NEAR(hole.reachableFraction(), 60.0 / 72.0, 1e-12);
  // The poor strip (mobility 0.2) is a place but cannot be stood on.
  const SoleReach poor = r.sole({3.05, 0.4, 0.02, 0.0, 0.08, 0.08}, 0.1, 0.1);
  EXPECT_EQ(poor.on_place, 16);
  EXPECT_EQ(poor.standable, 0);
  // Turned a quarter: the same sole across the edge now lies along it, on the floor side.
  const SoleReach along = r.sole({2.28, 0.3, 0.32, M_PI / 2, 0.24, 0.12}, 0.1, 0.4);
  EXPECT_EQ(along.samples, 72);
  EXPECT_EQ(along.reachable, 48);  // x = 2.23 ... 2.33: 4 of its 6 rows are west of 2.30
  EXPECT_EQ(Reachability().sole({0, 0, 0, 0, 0.2, 0.1}).samples, 0);
}

TEST(Reachability, RejectsInvalidParamsAndStartsNamingThem) {
  const MobilityOcTree t(kRes);
  for (const auto& [field, set] : std::vector<std::pair<std::string, std::function<void(ReachParams&)>>>{
           {"max_step_m", [](ReachParams& p) { p.max_step_m = -0.1; }},
           {"max_step_m", [](ReachParams& p) { p.max_step_m = 0.039; }},  // under two 2 cm voxels
           {"min_mobility", [](ReachParams& p) { p.min_mobility = 1.5; }},
           {"clearance_m", [](ReachParams& p) { p.clearance_m = NAN; }},
           {"max_gap_m", [](ReachParams& p) { p.max_gap_m = 2.0; }},
           {"start_radius_m", [](ReachParams& p) { p.start_radius_m = -1; }}}) {
    ReachParams p;
    set(p);
    try {
      (void)computeReachability(t, Eigen::Vector3d::Zero(), p);
      ADD_FAILURE() << field;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW((void)computeReachability(t, Eigen::Vector3d(0, NAN, 0)), std::invalid_argument);
}

// The same rule, written out from a set of voxels with no intervals, no pruning, no
// queue: places as the tops of runs in each column, edges by brute force over all pairs,
// connectivity by relaxing until nothing changes.
std::set<std::tuple<int, int, int>> bruteForceReachable(const std::set<std::tuple<int, int, int>>& occupied,
                                                       const std::map<std::tuple<int, int, int>, double>& mobility,
                                                       const ReachParams& p, const Eigen::Vector3d& start) {
  struct P {
    int i, j, k;
    bool standable;
  };
  std::vector<P> places;
  const int step = static_cast<int>(std::floor(p.max_step_m / kRes + 1e-6)) - 1;  // a voxel of margin
  const int gap = static_cast<int>(std::floor(p.max_gap_m / kRes + 1e-6));
  const int clear = static_cast<int>(std::ceil(p.clearance_m / kRes - 1e-6));
  for (const auto& [i, j, k] : occupied) {
    if (occupied.count({i, j, k + 1})) continue;  // not the top of its run
    // Mobility: the top voxel's, else the highest in the run with one.
    std::optional<double> m;
    for (int kk = k; occupied.count({i, j, kk}) && !m; --kk) {
      const auto f = mobility.find({i, j, kk});
      if (f != mobility.end()) m = f->second;
    }
    int above = 1;
    while (above <= clear && !occupied.count({i, j, k + above})) ++above;
    places.push_back({i, j, k, m && *m >= p.min_mobility && above > clear});
  }
  const auto occupiedIn = [&](int i, int j, int lo, int hi) {
    for (int k = lo; k <= hi; ++k) {
      if (occupied.count({i, j, k})) return true;
    }
    return false;
  };
  const auto edge = [&](const P& a, const P& b) {
    if (!a.standable || !b.standable || std::abs(a.k - b.k) > step) return false;
    const int di = b.i - a.i, dj = b.j - a.j;
    const int n = std::max(std::abs(di), std::abs(dj));
    if (n == 0 || n > 1 + gap) return false;
    if ((di != 0 && std::abs(di) != n) || (dj != 0 && std::abs(dj) != n)) return false;  // not on one of 8 lines
    for (int m = 1; m < n; ++m) {
      if (occupiedIn(a.i + m * di / n, a.j + m * dj / n, std::min(a.k, b.k) - step, std::max(a.k, b.k) + std::max(step, clear))) {
        return false;
      }
    }
    return true;
  };
  // Regions: every standable place starts in its own, joined along edges until stable.
  std::vector<std::size_t> label(places.size());
  for (std::size_t q = 0; q < places.size(); ++q) label[q] = q;
  for (bool changed = true; changed;) {
    changed = false;
    for (std::size_t a = 0; a < places.size(); ++a) {
      for (std::size_t b = 0; b < places.size(); ++b) {
        if (label[b] > label[a] && edge(places[a], places[b])) label[b] = label[a], changed = true;
      }
    }
  }
  // The largest level: the height with the most standable places within 2 voxels (4 cm), the lowest of equals.
  int level = 0;
  long most = 0;
  for (int k = -20; k < 40; ++k) {
    const long n = std::count_if(places.begin(), places.end(), [&](const P& o) { return o.standable && std::abs(o.k - k) <= 2; });
    if (n > most) most = n, level = k;
  }
  const bool largest = p.start_rule == ReachParams::Start::kLargestLevel;
  const auto regionSize = [&](std::size_t q) { return largest ? std::count(label.begin(), label.end(), label[q]) : 0L; };
  // Start: among the standable places within the radius with their top at or below the
  // start's z + step (and on the largest level, if asked), the largest region (if asked),
  // then the nearest column, then the highest.
  int best = -1;
  const auto d2 = [&](const P& c) {
    const double x = (c.i + 0.5) * kRes - start.x(), y = (c.j + 0.5) * kRes - start.y();
    return x * x + y * y;
  };
  for (std::size_t q = 0; q < places.size(); ++q) {
    const P& a = places[q];
    if (!a.standable || (a.k + 1) * kRes > start.z() + p.max_step_m + 1e-9 || d2(a) > p.start_radius_m * p.start_radius_m + 1e-12) {
      continue;
    }
    if (largest && std::abs(a.k - level) > 2) continue;
    if (best < 0) {
      best = static_cast<int>(q);
      continue;
    }
    const auto b = static_cast<std::size_t>(best);
    const long sa = regionSize(q), sb = regionSize(b);
    if (sa > sb || (sa == sb && (d2(a) < d2(places[b]) - 1e-12 || (d2(a) <= d2(places[b]) + 1e-12 && a.k > places[b].k)))) {
      best = static_cast<int>(q);
    }
  }
  std::vector<bool> reached(places.size(), false);
  for (std::size_t q = 0; q < places.size() && best >= 0; ++q) reached[q] = places[q].standable && label[q] == label[static_cast<std::size_t>(best)];
  std::set<std::tuple<int, int, int>> out;
  for (std::size_t q = 0; q < places.size(); ++q) {
    if (reached[q]) out.insert({places[q].i, places[q].j, places[q].k});
  }
  return out;
}

TEST(Reachability, EqualsABruteForceReferenceOnRandomMapsWithPrunedBlocks) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int nonempty = 0, pruned = 0;
  for (int trial = 0; trial < 40; ++trial) {
    SCOPED_TRACE(trial);
    MobilityOcTree t(kRes);
    std::set<std::tuple<int, int, int>> occupied;
    std::map<std::tuple<int, int, int>, double> mobility;
    const auto set = [&](int i, int j, int k, std::optional<double> m) {
      // One log-odds for all, so equal blocks prune.
      auto* n = t.setNodeValue(octomap::point3d(static_cast<float>((i + 0.5) * kRes), static_cast<float>((j + 0.5) * kRes),
                                                static_cast<float>((k + 0.5) * kRes)),
                               2.0f);
      if (m) {
        n->setMobility(*m, 50.0, 2);
        mobility[{i, j, k}] = *m;
      } else {
        n->clearMobility();
        mobility.erase({i, j, k});
      }
      occupied.insert({i, j, k});
    };
    // A terrain of 16 x 16 columns: a height field with holes, some columns stacked with
    // a second level, and 2 x 2 x 2 blocks of one value that prune into one node.
    for (int i = 0; i < 16; ++i) {
      for (int j = 0; j < 16; ++j) {
        if (u(rng) < 0.12) continue;  // a hole
        const int h = static_cast<int>(u(rng) * 6);
        const auto m = u(rng) < 0.1 ? std::nullopt : std::optional<double>(u(rng) < 0.25 ? 0.2 : 0.9);
        for (int k = std::max(0, h - 1); k <= h; ++k) set(i, j, k, m);
        if (u(rng) < 0.15) set(i, j, h + 3 + static_cast<int>(u(rng) * 8), 0.9);  // an overhang or second level
      }
    }
    for (int b = 0; b < 4; ++b) {  // aligned blocks, identical voxels
      const int i0 = 2 * static_cast<int>(u(rng) * 8), j0 = 2 * static_cast<int>(u(rng) * 8), k0 = 2 * static_cast<int>(u(rng) * 4);
      for (int di = 0; di < 2; ++di) {
        for (int dj = 0; dj < 2; ++dj) {
          for (int dk = 0; dk < 2; ++dk) set(i0 + di, j0 + dj, k0 + dk, 0.9);
        }
      }
    }
    t.updateInnerOccupancy();
    t.prune();
    for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) pruned += it.getSize() > 1.5 * kRes;
    ReachParams p;
    p.max_step_m = 0.02 * (2 + static_cast<int>(u(rng) * 3));
    p.max_gap_m = 0.02 * static_cast<int>(u(rng) * 3);
    p.clearance_m = u(rng) < 0.5 ? 0.0 : 0.02 * static_cast<int>(1 + u(rng) * 6);
    p.min_mobility = 0.5;
    p.start_radius_m = 0.1;
    p.start_rule = trial % 2 ? ReachParams::Start::kLargestLevel : ReachParams::Start::kNearest;
    const Eigen::Vector3d start(0.16, 0.16, 0.3);
    const Reachability r = computeReachability(t, start, p);
    std::set<std::tuple<int, int, int>> got;
    for (const Place& pl : r.places()) {
      if (pl.reachable) got.insert({pl.key[0] - 32768, pl.key[1] - 32768, pl.key[2] - 32768});
    }
    const auto want = bruteForceReachable(occupied, mobility, p, start);
    EXPECT_EQ(got, want);
    nonempty += want.size() > 20;
  }
  EXPECT_GT(nonempty, 10);  // the comparison was about something
  EXPECT_GT(pruned, 20);    // and pruned blocks were in it
}

}  // namespace
}  // namespace mobmap::mapping
