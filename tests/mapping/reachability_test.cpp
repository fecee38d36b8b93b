// Footholds, reachability and the footstep planner on analytic voxel scenes: soles on
// floors, edges, ramps and holes; which surfaces a robot walks to; monotone limits; plans.
#include "mobmap/mapping/footstep_planner.hpp"
#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/mapping/reachability.hpp"
#include "voxel_scene.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <tuple>

namespace mobmap::mapping {
namespace {

// The place in the column of (x, y) whose top face is at `top` (metres).
const Place& placeAt(const Reachability& r, double x, double y, double top) {
  const Place* p = r.placeBelow({x, y, top - kRes / 2}, 0.0);
  if (!p) throw std::runtime_error("no place at " + std::to_string(x) + " " + std::to_string(y) + " " + std::to_string(top));
  return *p;
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

// A floor of i x j in [0, ni) x [0, nj) with tops at 0.02 m, mobility 1.
void floorOf(MobilityOcTree& t, int ni, int nj) {
  for (int i = 0; i < ni; ++i) {
    for (int j = 0; j < nj; ++j) put(t, i, j, 0, 1.0);
  }
}

TEST(Footholds, WholeSolesOnFloorsRampsEdgesHolesAndObstacles) {
  MobilityOcTree t(kRes);
  for (int i = 0; i < 100; ++i) {
    for (int j = 0; j < 60; ++j) {
      if (!(i >= 20 && i < 25 && j < 15)) put(t, i, j, 0, 1.0);
    }
  }
  // A 16 cm block at x >= 1.0 (tops 0.18), a hole at x in [0.4, 0.5), y in [0, 0.3).
  for (int i = 50; i < 100; ++i) {
    for (int j = 0; j < 60; ++j) {
      for (int k = 1; k <= 8; ++k) put(t, i, j, k, 1.0);
    }
  }
  const SurfaceColumns cols(t);
  RobotParams robot;
  // On the open floor: the plane through the tops, level, no problem.
  const Foothold flat = evaluateFoothold(cols, 0.31, 0.91, 0.3, 0.02, robot);
  EXPECT_TRUE(flat.standable());
  EXPECT_NEAR(flat.z, 0.02, 1e-9);
  EXPECT_NEAR(flat.tilt_deg, 0.0, 1e-6);
  EXPECT_EQ(flat.samples, 78);
  // On the block, away from its edge: standable at 0.18.
  const Foothold top = evaluateFoothold(cols, 1.5, 0.6, 0.0, 0.18, robot);
  EXPECT_TRUE(top.standable());
  EXPECT_NEAR(top.z, 0.18, 1e-9);
  // Straddling the block's edge (x = 1.0) from the floor: half the sole has no surface
  // at the floor's height, and the block stands in its space.
  EXPECT_FALSE(evaluateFoothold(cols, 1.0, 0.6, 0.0, 0.02, robot).standable());
  EXPECT_EQ(evaluateFoothold(cols, 0.9, 0.6, 0.0, 0.02, robot).problem, FootholdProblem::kObstacle);
  // Hanging over the block's edge from its top: too little of the sole on surface.
  EXPECT_EQ(evaluateFoothold(cols, 1.0, 0.6, 0.0, 0.18, robot).problem, FootholdProblem::kNoSurface);
  // Half over the hole: 50 % known.
  const Foothold hole = evaluateFoothold(cols, 0.4, 0.1, 0.0, 0.02, robot);
  EXPECT_EQ(hole.problem, FootholdProblem::kNoSurface);
  EXPECT_NEAR(hole.support_fraction, 0.5, 0.1);
  // Mobility: a strip of 0.2 over a fifth of a sole fails it; a single voxel does not.
  put(t, 10, 30, 0, 0.2);
  for (int j = 40; j < 60; ++j) put(t, 30, j, 0, 0.2), put(t, 31, j, 0, 0.2), put(t, 32, j, 0, 0.2);
  const SurfaceColumns poor(t);
  EXPECT_TRUE(evaluateFoothold(poor, 0.21, 0.61, 0.0, 0.02, robot).standable());
  const Foothold strip = evaluateFoothold(poor, 0.63, 1.0, 0.0, 0.02, robot);
  EXPECT_EQ(strip.problem, FootholdProblem::kLowMobility);
  EXPECT_NEAR(strip.min_mobility, 0.2, 1e-4);  // stored as a float
  RobotParams lenient = robot;
  lenient.min_mobility = 0.2;
  EXPECT_TRUE(evaluateFoothold(poor, 0.63, 1.0, 0.0, 0.02, lenient).standable());
}

TEST(Footholds, RampTiltIsMeasuredAndLimited) {
  for (const double deg : {10.0, 30.0}) {
    MobilityOcTree t(kRes);
    const double g = std::tan(deg * M_PI / 180);
    // A ramp rising along +x: each column's top voxel holds the surface z = g x.
    for (int i = 0; i < 40; ++i) {
      for (int j = 0; j < 30; ++j) {
        const int k = static_cast<int>(std::floor(g * (i + 0.5) * kRes / kRes));
        put(t, i, j, k, 1.0);
      }
    }
    const SurfaceColumns cols(t);
    const double x = 0.4, z = g * x;
    const Foothold f = evaluateFoothold(cols, x, 0.3, 0.0, z, RobotParams{});
    ASSERT_TRUE(f.has_plane) << deg;
    EXPECT_NEAR(f.tilt_deg, deg, 3.0);  // voxel tops step: a few degrees over a 25 cm sole
    EXPECT_EQ(f.standable(), deg < 20) << deg << ": " << toString(f.problem);
    if (deg > 20) {
      EXPECT_EQ(f.problem, FootholdProblem::kTooSteep);
    }
  }
}

// The voxel-level rule reach had before soles: the top voxel of every run with mobility
// >= min_mobility is a place; places in neighbouring columns (8 around) join when their
// tops n voxels apart have n + 1 voxels within max_step. Flood fill from the run `start`;
// true if the run `goal` is reached.
bool voxelLevelReach(const SurfaceColumns& cols, std::size_t start, std::size_t goal, double max_step, double min_mobility) {
  const auto& runs = cols.runs();
  const int step = static_cast<int>(std::floor(max_step / cols.resolution() + 1e-6)) - 1;
  std::vector<bool> seen(runs.size(), false);
  std::vector<std::size_t> todo{start};
  seen[start] = true;
  while (!todo.empty()) {
    const std::size_t a = todo.back();
    todo.pop_back();
    if (a == goal) return true;
    const long col = static_cast<long>(cols.runColumn(a));
    const long kx = cols.keyX0() + col / cols.columnsY(), ky = cols.keyY0() + col % cols.columnsY();
    for (long dx = -1; dx <= 1; ++dx) {
      for (long dy = -1; dy <= 1; ++dy) {
        const long c = cols.columnIndex(kx + dx, ky + dy);
        for (std::size_t b = cols.runBegin(c); b < cols.runEnd(c); ++b) {
          if (seen[b] || !(runs[b].mobility >= min_mobility) || std::abs(runs[b].top - runs[a].top) > step) continue;
          seen[b] = true;
          todo.push_back(b);
        }
      }
    }
  }
  return false;
}

// The real failure: on a staircase the sensor's rounded edges leave voxels part way up
// each riser with the floor's or the tread's mobility. Voxel by voxel they are stepping
// stones 6 and 12 cm apart (the voxel-level rule climbs the 17 cm step with 15 cm steps);
// no sole rests on them.
TEST(Reachability, EdgeVoxelsPartWayUpARiserAreNoSteppingStones) {
  MobilityOcTree t(kRes);
  floorOf(t, 60, 50);
  // A 17 cm step (tops 0.18 m: voxels 1..8) from x = 0.6.
  for (int i = 30; i < 60; ++i) {
    for (int j = 0; j < 50; ++j) {
      for (int k = 1; k <= 8; ++k) put(t, i, j, k, k == 8 ? 1.0 : 0.0);
    }
  }
  // In front of the riser: a rounded corner, voxels at 6 cm and 12 cm with walkable mobility.
  for (int j = 0; j < 50; ++j) {
    for (int k = 1; k <= 2; ++k) put(t, 28, j, k, 0.9);
    for (int k = 1; k <= 5; ++k) put(t, 29, j, k, 0.9);
  }
  {
    const SurfaceColumns cols(t);
    const long floor_run = cols.runBelow(0.2, 0.5, 0.03, 0.0), tread_run = cols.runBelow(0.9, 0.5, 0.19, 0.1);
    ASSERT_GE(floor_run, 0);
    ASSERT_GE(tread_run, 0);
    EXPECT_TRUE(voxelLevelReach(cols, static_cast<std::size_t>(floor_run), static_cast<std::size_t>(tread_run), 0.15, 0.5));
    EXPECT_FALSE(voxelLevelReach(cols, static_cast<std::size_t>(floor_run), static_cast<std::size_t>(tread_run), 0.06, 0.5));
  }
  ReachParams p;
  p.robot.max_step_m = 0.15;
  const Reachability r = computeReachability(t, {0.2, 0.5, 0.02}, p);
  ASSERT_TRUE(r.start());
  EXPECT_TRUE(placeAt(r, 0.2, 0.5, 0.02).reachable);
  EXPECT_TRUE(placeAt(r, 0.9, 0.5, 0.18).standable);
  EXPECT_FALSE(placeAt(r, 0.9, 0.5, 0.18).reachable);
  EXPECT_FALSE(placeAt(r, 0.59, 0.5, 0.12).standable);  // the corner voxels 12 cm up carry no sole
  p.robot.max_step_m = 0.2;
  const Reachability up = computeReachability(t, {0.2, 0.5, 0.02}, p);
  EXPECT_TRUE(placeAt(up, 0.9, 0.5, 0.18).reachable);
  // A footstep plan says the same, and names the step.
  PlanParams plan;
  plan.robot.max_step_m = 0.15;
  const Plan no = planFootsteps(t, {0.2, 0.5, 0.02}, {0.9, 0.5, 0.18}, plan);
  EXPECT_FALSE(no.found);
  EXPECT_NE(no.reason.find("`max_step_m` 0.15"), std::string::npos) << no.reason;
  EXPECT_NE(no.reason.find("the step up"), std::string::npos) << no.reason;
  plan.robot.max_step_m = 0.2;
  const Plan yes = planFootsteps(t, {0.2, 0.5, 0.02}, {0.9, 0.5, 0.18}, plan);
  ASSERT_TRUE(yes.found) << yes.reason;
  EXPECT_NEAR(yes.footsteps.back().z, 0.18, 0.01);
}

TEST(Reachability, StepsLedgesTablesWallsHolesAndPoorFloor) {
  const Scene s;
  ReachParams p;
  const Reachability r = computeReachability(s.tree, {1.505, 0.8, 0.1}, p);
  ASSERT_TRUE(r.start());
  EXPECT_NEAR(r.footPlaces()[*r.start()].z, 0.02, 1e-6);
  // Open floor, both sides of the 4 cm hole, under the table (no clearance asked).
  EXPECT_TRUE(placeAt(r, 1.5, 1.0, 0.02).reachable);
  EXPECT_TRUE(placeAt(r, 0.1, 0.5, 0.02).reachable);
  EXPECT_TRUE(placeAt(r, 0.5, 1.5, 0.02).reachable);
  // Stairs of 10 cm risers and 30 cm treads, and the platform they lead to.
  EXPECT_TRUE(placeAt(r, 1.15, 0.3, 0.12).reachable);
  EXPECT_TRUE(placeAt(r, 1.7, 0.3, 0.32).reachable);
  // A 30 cm ledge, a table top, a walled room: standable, not reachable.
  for (const auto& [x, y, top] : {std::tuple{2.5, 0.3, 0.32}, {0.5, 1.5, 0.72}, {2.6, 1.6, 0.02}}) {
    const Place& q = placeAt(r, x, y, top);
    EXPECT_TRUE(q.standable) << x << " " << y;
    EXPECT_FALSE(q.reachable) << x << " " << y;
  }
  // The annex lies beyond a 10 cm strip of poor floor: a stride steps over it.
  EXPECT_TRUE(placeAt(r, 3.3, 0.4, 0.02).reachable);
  EXPECT_FALSE(placeAt(r, 3.05, 0.4, 0.02).standable);
  // A dais 10 x 10 cm carries no sole; the wall top neither.
  EXPECT_FALSE(placeAt(r, 0.25, 0.25, 0.18).standable);
  EXPECT_FALSE(placeAt(r, 2.21, 1.5, 1.0).standable);
  EXPECT_NEAR(placeAt(r, 0.5, 1.5, 0.02).headroom_m, 0.68, 1e-9);
  // Clearance: under the table is no longer standable.
  ReachParams tall = p;
  tall.robot.clearance_m = 1.0;
  const Reachability rt = computeReachability(s.tree, {1.505, 0.8, 0.1}, tall);
  EXPECT_FALSE(placeAt(rt, 0.5, 1.5, 0.02).standable);
  EXPECT_TRUE(placeAt(rt, 1.5, 1.0, 0.02).reachable);
  // Short strides do not cross the poor strip.
  ReachParams short_stride = p;
  short_stride.robot.max_stride_m = 0.1;
  short_stride.robot.stance_width_m = 0.1;
  EXPECT_FALSE(placeAt(computeReachability(s.tree, {1.505, 0.8, 0.1}, short_stride), 3.3, 0.4, 0.02).reachable);
  // Counting.
  std::size_t reachable = 0;
  for (const Place& q : r.places()) reachable += q.reachable;
  EXPECT_EQ(reachable, r.reachableCount());
}

// A random terraced map: blocks of random height (0..12 voxels) and mobility on a floor,
// some holes, some thin posts.
MobilityOcTree randomMap(std::mt19937& rng) {
  MobilityOcTree t(kRes);
  std::uniform_int_distribution<int> height(0, 12), coin(0, 9);
  std::uniform_real_distribution<double> mob(0.0, 1.0);
  for (int bi = 0; bi < 8; ++bi) {
    for (int bj = 0; bj < 6; ++bj) {
      const int h = coin(rng) < 4 ? 0 : height(rng);
      const double m = coin(rng) < 7 ? 0.6 + 0.4 * mob(rng) : mob(rng);
      const bool hole = coin(rng) == 0;
      for (int i = bi * 12; i < bi * 12 + 12; ++i) {
        for (int j = bj * 12; j < bj * 12 + 12; ++j) {
          if (hole) continue;
          for (int k = 0; k <= h; ++k) put(t, i, j, k, k == h ? m : 0.0);
        }
      }
    }
  }
  for (int n = 0; n < 20; ++n) {
    std::uniform_int_distribution<int> ci(0, 95), cj(0, 71);
    const int i = ci(rng), j = cj(rng);
    for (int k = 0; k < 20; ++k) put(t, i, j, k, 0.0);
  }
  return t;
}

TEST(Reachability, ReachableSetNeverShrinksWhenLimitsLoosen) {
  std::mt19937 rng(7);
  int grew = 0;
  for (int m = 0; m < 12; ++m) {
    const MobilityOcTree t = randomMap(rng);
    const auto columns = std::make_shared<const SurfaceColumns>(t);
    const Eigen::Vector3d start(0.9, 0.7, 0.5);
    std::vector<std::pair<double, double>> limits;  // (max_step, min_mobility), each looser than the last
    for (const double step : {0.06, 0.1, 0.15, 0.2, 0.3}) limits.emplace_back(step, 0.9 - step);
    std::optional<Reachability> before;
    for (const auto& [step, mob] : limits) {
      ReachParams p;
      p.robot.max_step_m = step, p.robot.min_mobility = mob;
      p.start_radius_m = 0.5;
      Reachability r = computeReachability(columns, start, p);
      if (before) {
        ASSERT_EQ(r.footPlaces().size(), before->footPlaces().size());
        for (std::size_t f = 0; f < r.footPlaces().size(); ++f) {
          if (before->footPlaces()[f].reachable) {
            ASSERT_TRUE(r.footPlaces()[f].reachable) << "map " << m << " step " << step;
          }
        }
        for (std::size_t q = 0; q < r.places().size(); ++q) {
          if (before->places()[q].reachable) {
            ASSERT_TRUE(r.places()[q].reachable) << "map " << m << " step " << step;
          }
        }
        grew += r.reachableCount() > before->reachableCount();
      }
      before = std::move(r);
    }
  }
  EXPECT_GT(grew, 5);  // the property is not vacuous: looser limits do reach more
}

// The walk against a brute-force closure: every pair of standable soles joined by canStep,
// iterated to a fixed point from the same start soles; and the same answer from the
// pruned tree (pruned blocks count voxel by voxel).
TEST(Reachability, EqualsABruteForceClosureOnRandomMapsWithPrunedBlocks) {
  std::mt19937 rng(11);
  for (int m = 0; m < 4; ++m) {
    MobilityOcTree t = randomMap(rng);
    ReachParams p;
    p.robot.max_step_m = 0.1 + 0.05 * m;
    const Reachability r = computeReachability(t, {0.9, 0.7, 0.5}, p);
    const auto& feet = r.footPlaces();
    std::vector<bool> reached(feet.size(), false);
    for (const std::size_t f : r.startFeet()) reached[f] = true;
    for (bool changed = true; changed;) {
      changed = false;
      for (std::size_t a = 0; a < feet.size(); ++a) {
        if (!reached[a]) continue;
        for (std::size_t b = 0; b < feet.size(); ++b) {
          if (reached[b] || !feet[b].isStandable()) continue;
          if (canStep(r.columns(), feet[a].x, feet[a].y, feet[a].z, feet[b].x, feet[b].y, feet[b].z, p.robot)) {
            reached[b] = changed = true;
          }
        }
      }
    }
    std::size_t n = 0;
    for (std::size_t f = 0; f < feet.size(); ++f) {
      EXPECT_EQ(feet[f].reachable, reached[f]) << "map " << m << " sole " << f;
      n += reached[f];
    }
    EXPECT_GT(n, 100u) << "map " << m;
    t.prune();
    const Reachability pruned = computeReachability(t, {0.9, 0.7, 0.5}, p);
    ASSERT_EQ(pruned.places().size(), r.places().size());
    for (std::size_t q = 0; q < r.places().size(); ++q) {
      EXPECT_EQ(pruned.places()[q].key, r.places()[q].key);
      EXPECT_EQ(pruned.places()[q].reachable, r.places()[q].reachable);
    }
  }
}

TEST(Reachability, RejectsInvalidParamsAndStartsNamingThem) {
  const Scene s;
  const auto fails = [&](const std::function<void(ReachParams&)>& change, const std::string& field) {
    ReachParams p;
    change(p);
    try {
      (void)computeReachability(s.tree, {1.5, 0.8, 0.1}, p);
      ADD_FAILURE() << field << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  fails([](ReachParams& p) { p.robot.max_step_m = -0.1; }, "max_step_m");
  fails([](ReachParams& p) { p.robot.max_step_m = 0.03; }, "max_step_m");  // under two voxels
  fails([](ReachParams& p) { p.robot.min_mobility = 1.5; }, "min_mobility");
  fails([](ReachParams& p) { p.robot.sole_length_m = 0; }, "sole_length_m");
  fails([](ReachParams& p) { p.robot.max_tilt_deg = std::nan(""); }, "max_tilt_deg");
  fails([](ReachParams& p) { p.start_radius_m = -1; }, "start_radius_m");
  EXPECT_THROW((void)computeReachability(s.tree, {std::nan(""), 0, 0}, {}), std::invalid_argument);
  // Far from any surface: no start, nothing reachable.
  const Reachability r = computeReachability(s.tree, {50, 50, 0}, {});
  EXPECT_FALSE(r.start());
  EXPECT_EQ(r.reachableCount(), 0u);
}

// A floor seen from far away: striped (one row of voxels in three), so it holds most of
// the walkable surface but no whole sole; a solid box top 0.4 m up holds fewer walkable
// voxels and many soles. The largest level is the floor, by walkable surface (as `info`
// measures it), and the start level says how little of it carries a sole; with the floor
// whole the walk starts on it.
TEST(Reachability, TheLargestLevelIsTheOneWithTheMostWalkableSurfaceEvenWhereItCarriesNoSole) {
  for (const bool striped : {true, false}) {
    SCOPED_TRACE(striped ? "striped floor" : "whole floor");
    MobilityOcTree tree(kRes);
    std::size_t floor = 0;
    for (int i = 0; i < 100; ++i) {
      for (int j = 0; j < 100; ++j) {
        const bool box = i >= 40 && i < 60 && j >= 40 && j < 60;
        if (box) {
          for (int k = 0; k <= 20; ++k) put(tree, i, j, k, k == 20 ? 1.0 : 0.0);
        } else if (!striped || j % 3 == 0) {
          put(tree, i, j, 0, 1.0);
          ++floor;
        }
      }
    }
    // Both levels as info counts them: the floor 0.02 m up, the box top 0.42 m.
    const auto bins = walkableBins(SurfaceColumns(tree));
    EXPECT_EQ(bins.size(), 2u);
    EXPECT_EQ(bins.at(1), floor);
    EXPECT_EQ(bins.at(21), 400u);
    ReachParams p;
    p.start_rule = ReachParams::Start::kLargestLevel;
    p.start_radius_m = 1.0;
    const Eigen::Vector3d from(0.5, 0.5, 1.5);  // a camera above the floor, the box within the radius
    const Reachability r = computeReachability(tree, from, p);
    ASSERT_TRUE(r.startLevel());
    const StartLevel& level = *r.startLevel();
    EXPECT_NEAR(level.z_m, 0.02, 1e-9);
    EXPECT_EQ(level.walkable, floor);
    EXPECT_NEAR(level.share, static_cast<double>(floor) / static_cast<double>(floor + 400), 1e-12);
    // Brute force: the floor's walkable columns within 1 m of (0.5, 0.5), and those
    // under a standable sole.
    std::size_t near = 0, carried = 0;
    for (const Place& pl : r.places()) {
      if (std::abs(pl.top_z - 0.02) > 1e-9 || std::hypot(pl.x - 0.5, pl.y - 0.5) > 1.0) continue;
      ++near;
      carried += pl.standable;
    }
    EXPECT_GT(near, 100u);
    EXPECT_EQ(level.walkable_near, near);
    EXPECT_EQ(level.standable_near, carried);
    if (striped) {
      EXPECT_EQ(carried, 0u);
      EXPECT_EQ(level.carriedShare(), 0.0);
      EXPECT_FALSE(r.start());  // no sole on the floor; never the box top
      EXPECT_EQ(r.reachableCount(), 0u);
    } else {
      EXPECT_GT(level.carriedShare(), 0.9);
      ASSERT_TRUE(r.start());
      EXPECT_NEAR(r.footPlaces()[*r.start()].z, 0.02, 1e-6);
    }
    // The nearest rule has no start level.
    p.start_rule = ReachParams::Start::kNearest;
    EXPECT_FALSE(computeReachability(tree, from, p).startLevel());
  }
}

// `query --foot` (MobilityMap::footprint) and `query --foot --reach` (a sole judged for
// the robot) count the same samples as known, with the same mobilities: on the scene's
// stairs, ledge, table, walls, hole and poor floor, plus a patch of floor whose top voxels
// have no mobility yet (the voxel under each has one) and a patch with none at all.
TEST(Reachability, FootprintAndFootholdCountTheSameKnownSurface) {
  Scene s;
  for (int i = 140; i < 150; ++i) {
    for (int j = 20; j < 30; ++j) s.tree.updateNode(octomap::point3d(static_cast<float>((i + 0.5) * kRes),
                                                                     static_cast<float>((j + 0.5) * kRes), 0.03f), true);
  }
  for (int i = 100; i < 110; ++i) {
    for (int j = 40; j < 50; ++j) {
      auto* n = s.tree.search(octomap::point3d(static_cast<float>((i + 0.5) * kRes), static_cast<float>((j + 0.5) * kRes), 0.01f));
      ASSERT_NE(n, nullptr);
      n->clearMobility();
    }
  }
  // The map gets a copy voxel by voxel (octomap's copy constructor drops the payload).
  auto copy = std::make_unique<MobilityOcTree>(kRes);
  for (auto it = s.tree.begin_leafs(); it != s.tree.end_leafs(); ++it) {
    ASSERT_NEAR(it.getSize(), kRes, 1e-9);
    copy->updateNode(it.getKey(), true)->copyData(*it);
  }
  MapParams mp;
  mp.resolution_m = kRes;
  const MobilityMap map(std::move(copy), mp, Eigen::Matrix3d::Identity());
  const Reachability r = computeReachability(s.tree, {0.5, 1.0, 0.1}, {});
  std::mt19937 rng(52);
  std::uniform_real_distribution<double> x(0.0, 3.5), y(0.0, 2.0), yaw(-M_PI, M_PI), dz(-0.05, 0.05);
  int partly_known = 0, fallback = 0;
  for (int k = 0; k < 3000; ++k) {
    const Eigen::Vector3d p(x(rng), y(rng), 0.0);
    const Place* under = r.placeBelow({p.x(), p.y(), 1.0}, 1.0);
    const Foot foot{p.x(), p.y(), (under ? under->top_z : 0.02) + dz(rng), yaw(rng), 0.25, 0.12};
    const FootprintQuery fp = map.footprint(foot);
    const Foothold fh = r.sole(foot).foothold;
    SCOPED_TRACE(std::to_string(foot.x) + " " + std::to_string(foot.y) + " " + std::to_string(foot.z) + " yaw " +
                 std::to_string(foot.yaw));
    ASSERT_EQ(fp.samples, fh.samples);
    ASSERT_NEAR(fp.known_fraction, fh.support_fraction, 1e-12);
    ASSERT_NEAR(fp.mean_mobility, fh.mean_mobility, 1e-6);
    ASSERT_NEAR(fp.min_mobility, fh.min_mobility, 1e-6);
    partly_known += fp.known_fraction > 0 && fp.known_fraction < 1;
    fallback += std::abs(p.x() - 2.9) < 0.1 && std::abs(p.y() - 0.5) < 0.1 && fp.known_fraction > 0.5;
  }
  EXPECT_GT(partly_known, 100);
  EXPECT_GT(fallback, 3);  // soles on the patch whose top voxels have no mobility count it known
}

// Limits in messages read as they were given, and read back to the same number.
TEST(Footholds, FormatLimitGivesTheShortestDecimalThatReadsBack) {
  EXPECT_EQ(formatLimit(0.155), "0.155");
  EXPECT_EQ(formatLimit(0.15), "0.15");
  EXPECT_EQ(formatLimit(100 * 0.1), "10");
  EXPECT_EQ(formatLimit(20), "20");
  for (const double v : {0.1 + 0.2, 1.0 / 3, 1e-300, -2.5e20, 123456.789}) {
    EXPECT_EQ(std::strtod(formatLimit(v).c_str(), nullptr), v) << formatLimit(v);
  }
}

// Parameters by name (Python's keyword arguments, serve's JSON): each name sets the field
// validate() names when that field is out of range (NaN), and no other.
TEST(FootstepPlanner, EachNamedParameterSetsTheFieldOfThatName) {
  const std::vector<std::string>& names = planParameterNames();
  EXPECT_EQ(std::set<std::string>(names.begin(), names.end()).size(), names.size());
  EXPECT_EQ(names.size(), robotParameterNames().size() + 9);
  for (const std::string& name : names) {
    PlanParams p;
    if (name == "max_expansions" || name == "map_bound_after") {
      EXPECT_THROW(setPlanParameter(p, name, std::nan("")), std::invalid_argument);
      EXPECT_THROW(setPlanParameter(p, name, 2.5), std::invalid_argument);
      EXPECT_THROW(setPlanParameter(p, name, -1), std::invalid_argument);
      ASSERT_TRUE(setPlanParameter(p, name, 1234));
      EXPECT_EQ(name == "max_expansions" ? p.max_expansions : p.map_bound_after, 1234u);
      continue;
    }
    ASSERT_TRUE(setPlanParameter(p, name, std::nan(""))) << name;
    try {
      validate(p);
      ADD_FAILURE() << name << " = NaN accepted: the name set no field validate() checks";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(": `" + name + "` is"), std::string::npos) << name << ": " << e.what();
    }
  }
  for (const std::string& name : robotParameterNames()) {
    RobotParams r;
    ASSERT_TRUE(setRobotParameter(r, name, std::nan(""))) << name;
    EXPECT_THROW(validate(r), std::invalid_argument) << name;
  }
  PlanParams p;
  EXPECT_FALSE(setPlanParameter(p, "max_steps", 1));
  EXPECT_FALSE(setRobotParameter(p.robot, "heuristic_weight", 1));  // the search's, not the robot's
}

TEST(FootstepPlanner, StairsOfTenCentimetresAcrossTheFloorAndBadInput) {
  const Scene s;
  PlanParams p;
  // Up the 10 cm stairs to the platform (tops 0.32).
  const Plan up = planFootsteps(s.tree, {0.7, 0.3, 0.02}, {1.8, 0.3, 0.32}, p);
  ASSERT_TRUE(up.found) << up.reason;
  EXPECT_NEAR(up.footsteps.back().z, 0.32, 0.01);
  for (std::size_t i = 1; i < up.footsteps.size(); ++i) {
    const Footstep& a = up.footsteps[i - 1];
    const Footstep& b = up.footsteps[i];
    EXPECT_NE(a.side, b.side) << i;
    EXPECT_LE(std::abs(b.z - a.z) + kRes, p.robot.max_step_m + 1e-9) << i;
    EXPECT_LE(std::hypot(b.x - a.x, b.y - a.y), p.robot.max_stride_m + 1e-9) << i;
    EXPECT_GE(b.min_mobility, 0.0);
  }
  // Every tread is stood on.
  for (const double tread : {0.12, 0.22}) {
    bool on = false;
    for (const Footstep& f : up.footsteps) on = on || std::abs(f.z - tread) < 0.01;
    EXPECT_TRUE(on) << tread;
  }
  // The ledge is 30 cm up: no plan, and the reason names the step.
  const Plan ledge = planFootsteps(s.tree, {2.0, 0.3, 0.02}, {2.55, 0.3, 0.32}, p);
  EXPECT_FALSE(ledge.found);
  EXPECT_NE(ledge.reason.find("`max_step_m`"), std::string::npos) << ledge.reason;
  // The goal on the wall top: cannot be stood on.
  const Plan wall = planFootsteps(s.tree, {1.5, 1.0, 0.02}, {2.21, 1.5, 1.0}, p);
  EXPECT_FALSE(wall.found);
  EXPECT_NE(wall.reason.find("cannot be stood on"), std::string::npos) << wall.reason;
  // Outside the map, NaN, absurd robots.
  EXPECT_THROW((void)planFootsteps(s.tree, {50, 50, 0}, {1, 1, 0}, p), PlanInputError);
  EXPECT_THROW((void)planFootsteps(s.tree, {1, 1, 0}, {1, std::nan(""), 0}, p), std::invalid_argument);
  PlanParams bad = p;
  bad.robot.sole_width_m = -1;
  EXPECT_THROW((void)planFootsteps(s.tree, {1, 1, 0}, {2, 1, 0}, bad), std::invalid_argument);
  bad = p;
  bad.time_limit_s = 0;
  EXPECT_THROW((void)planFootsteps(s.tree, {1, 1, 0}, {2, 1, 0}, bad), std::invalid_argument);
}

// A budget stops the long computations at their next check: a stop flag set (a server
// shutting down) or a deadline passed; the plan's own time limit bounds the whole call
// and is said in the answer. (The deadlines used are in the past, or a nanosecond: no
// computation ends before them, on any machine.)
TEST(Budget, StopsReachabilityAndPlansAndTheTimeLimitIsSaid) {
  const Scene s;
  std::atomic<bool> stop{true};
  Budget stopped;
  stopped.stop = &stop;
  ReachParams rp;
  EXPECT_THROW((void)computeReachability(s.tree, {0.7, 0.3, 0.02}, rp, stopped), BudgetExceeded);
  Budget past;
  past.deadline = std::chrono::steady_clock::now() - std::chrono::seconds(1);
  try {
    (void)computeReachability(s.tree, {0.7, 0.3, 0.02}, rp, past);
    ADD_FAILURE() << "a budget already spent let the computation end";
  } catch (const BudgetExceeded& e) {
    EXPECT_NE(std::string(e.what()).find("computeReachability: ran out of time"), std::string::npos) << e.what();
  }
  stop = false;
  EXPECT_NO_THROW((void)computeReachability(s.tree, {0.7, 0.3, 0.02}, rp, stopped));  // the flag clear: it ends

  PlanParams p;
  stop = true;
  EXPECT_THROW((void)planFootsteps(s.tree, {0.7, 0.3, 0.02}, {1.8, 0.3, 0.32}, p, stopped), BudgetExceeded);
  // The time limit: an answer, not an exception, and it says so.
  p.time_limit_s = 1e-9;
  const Plan cut = planFootsteps(s.tree, {0.7, 0.3, 0.02}, {1.8, 0.3, 0.32}, p);
  EXPECT_FALSE(cut.found);
  EXPECT_TRUE(cut.time_limit_reached);
  EXPECT_NE(cut.reason.find("no plan within the limits"), std::string::npos) << cut.reason;
  // Out of expansions is another limit: found = false, but not the time's.
  p.time_limit_s = 10;
  p.max_expansions = 3;
  const Plan few = planFootsteps(s.tree, {0.7, 0.3, 0.02}, {1.8, 0.3, 0.32}, p);
  EXPECT_FALSE(few.found);
  EXPECT_FALSE(few.time_limit_reached);
  p.max_expansions = PlanParams{}.max_expansions;
  const Plan whole = planFootsteps(s.tree, {0.7, 0.3, 0.02}, {1.8, 0.3, 0.32}, p);
  EXPECT_TRUE(whole.found) << whole.reason;
  EXPECT_FALSE(whole.time_limit_reached);
  EXPECT_THROW((void)Budget::within(0), std::invalid_argument);
}

TEST(Reachability, MemoryBytesCountsWhatTheResultHolds) {
  const Scene s;
  const Reachability r = computeReachability(s.tree, {0.7, 0.3, 0.02});
  // At least its places, its foot places and its columns' runs (a cache that counted
  // less would hold more than its bound).
  ASSERT_GT(r.footPlaces().size(), 100u);
  EXPECT_GE(r.columns().memoryBytes(), r.columns().runs().size() * sizeof(r.columns().runs()[0]));
  EXPECT_GE(r.memoryBytes(),
            r.places().size() * sizeof(Place) + r.footPlaces().size() * sizeof(FootPlace) + r.columns().memoryBytes());
}

// The surfaces marked reachable are exactly those under some standable sole of a
// reachable foot place, judged again here sole by sole; one Standability shared by walks
// from several starts gives what a whole computation gives from each.
TEST(Standability, SharedByWalksFromSeveralStartsEqualsWholeComputationsAndTheSolesUnderThem) {
  std::mt19937 rng(19);
  for (int m = 0; m < 4; ++m) {
    const MobilityOcTree t = randomMap(rng);
    const auto columns = std::make_shared<const SurfaceColumns>(t);
    ReachParams p;
    p.robot.max_step_m = 0.1 + 0.03 * m;
    p.start_radius_m = 0.5;
    const auto standing = computeStandability(columns, p.robot);
    std::uniform_real_distribution<double> ux(0.2, 1.7), uy(0.2, 1.3);
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d start(ux(rng), uy(rng), 0.5);
      const Reachability whole = computeReachability(columns, start, p);
      const Reachability shared = computeReachability(standing, start, p);
      ASSERT_EQ(whole.footPlaces().size(), shared.footPlaces().size());
      ASSERT_EQ(whole.start(), shared.start());
      for (std::size_t f = 0; f < whole.footPlaces().size(); ++f) {
        const FootPlace &a = whole.footPlaces()[f], &b = shared.footPlaces()[f];
        ASSERT_TRUE(a.x == b.x && a.y == b.y && a.z == b.z && a.place == b.place && a.standable == b.standable &&
                    a.geometry_ok == b.geometry_ok && a.reachable == b.reachable)
            << "map " << m << " foot " << f;
      }
      std::vector<bool> under(whole.places().size(), false);
      std::vector<std::size_t> supports;
      for (const FootPlace& f : whole.footPlaces()) {
        if (!f.reachable) continue;
        for (int h = 0; h < kHeadings / 2; ++h) {
          if (!(f.standable & (1u << h))) continue;
          (void)evaluateFoothold(*columns, f.x, f.y, headingYaw(h), columns->topFace(columns->runs()[f.place]), p.robot, &supports);
          for (const std::size_t r : supports) under[r] = true;
        }
      }
      std::size_t reachable = 0;
      for (std::size_t q = 0; q < whole.places().size(); ++q) {
        ASSERT_EQ(whole.places()[q].reachable, under[q]) << "map " << m << " place " << q;
        ASSERT_EQ(shared.places()[q].reachable, under[q]) << "map " << m << " place " << q;
        ASSERT_EQ(shared.places()[q].standable, whole.places()[q].standable);
        reachable += under[q];
      }
      EXPECT_EQ(whole.reachableCount(), reachable);
      EXPECT_EQ(shared.reachableCount(), reachable);
    }
    ReachParams other = p;
    other.robot.max_step_m += 0.01;
    EXPECT_THROW((void)computeReachability(standing, {0.9, 0.7, 0.5}, other), std::invalid_argument);
  }
}

TEST(ReachCache, KeepsOneResultPerMapRobotAndStartAndHoldsItsBound) {
  const Scene s;
  const auto columns = std::make_shared<const SurfaceColumns>(s.tree);
  ReachCache cache;
  ReachParams p;
  const Eigen::Vector3d start(0.7, 0.3, 0.02), elsewhere(2.5, 1.5, 0.02);
  const auto a = cache.reachability(columns, start, p);
  EXPECT_EQ(cache.reachability(columns, start, p), a);  // the same object, not worked out again
  EXPECT_EQ(cache.findReachability(columns, start, p), a);
  EXPECT_EQ(cache.findReachability(columns, elsewhere, p), nullptr);
  const auto b = cache.reachability(columns, elsewhere, p);
  EXPECT_NE(b, a);
  EXPECT_EQ(b->standability(), a->standability());  // the soles judged once for both
  ReachParams q = p;
  q.robot.max_step_m = 0.2;
  const auto c = cache.reachability(columns, start, q);
  EXPECT_NE(c->standability(), a->standability());
  // Each equals a computation of its own.
  for (const auto& [r, from, params] : {std::make_tuple(a, start, p), std::make_tuple(b, elsewhere, p), std::make_tuple(c, start, q)}) {
    const Reachability direct = computeReachability(columns, from, params);
    EXPECT_EQ(direct.reachableCount(), r->reachableCount());
    EXPECT_EQ(direct.start(), r->start());
  }
  const auto another_map = std::make_shared<const SurfaceColumns>(s.tree);  // equal, but another snapshot
  EXPECT_EQ(cache.findReachability(another_map, start, p), nullptr);
  ReachCache::Stats st = cache.stats();
  EXPECT_EQ(st.entries, 5u);  // two standabilities, three walks
  EXPECT_GE(st.bytes, a->standability()->memoryBytes() + c->standability()->memoryBytes());
  // A bound under one entry's bytes keeps the newest alone.
  ReachCache small(1);
  (void)small.reachability(columns, start, p);
  (void)small.reachability(columns, elsewhere, p);
  st = small.stats();
  EXPECT_EQ(st.entries, 1u);
  EXPECT_GE(st.evictions, 2u);
  EXPECT_NE(small.findReachability(columns, elsewhere, p), nullptr);
  EXPECT_EQ(small.findReachability(columns, start, p), nullptr);
  cache.clear();
  EXPECT_EQ(cache.stats().entries, 0u);
}

}  // namespace
}  // namespace mobmap::mapping
