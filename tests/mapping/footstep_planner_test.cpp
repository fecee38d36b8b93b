// The footstep planner against a reference: a plain Dijkstra search over the same
// lattice of soles and steps, written from the planner's documented rules with the
// library's sole and swing checks, on random rough scenes and random start/goal pairs.
// Weight 1 must find the reference's cheapest cost; a larger weight at most that times
// the weight.
#include "mobmap/mapping/footstep_planner.hpp"
#include "building_scene.hpp"
#include "voxel_scene.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <functional>
#include <map>
#include <queue>
#include <random>
#include <set>
#include <tuple>
#include <vector>

namespace mobmap::mapping {
namespace {

constexpr double kPi = 3.14159265358979323846;

// A floor 2.4 x 1.6 m of random mobility (some of it poor), with random blocks 4-20 cm
// tall, a few holes and a 40 cm wall segment; every voxel at 2 cm.
struct RoughScene {
  MobilityOcTree tree{kRes};
  explicit RoughScene(unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> mob(0.55, 1.0), weight(20.0, 400.0);
    std::vector<std::vector<int>> top(120, std::vector<int>(80, 0));
    std::uniform_int_distribution<int> ui(0, 119), uj(0, 79), size(3, 9), rise(2, 10);
    for (int b = 0; b < 6; ++b) {  // blocks
      const int i0 = ui(rng), j0 = uj(rng), w = size(rng), h = size(rng), k = rise(rng);
      for (int i = i0; i < std::min(120, i0 + w); ++i) {
        for (int j = j0; j < std::min(80, j0 + h); ++j) top[i][j] = k;
      }
    }
    for (int b = 0; b < 3; ++b) {  // holes
      const int i0 = ui(rng), j0 = uj(rng);
      for (int i = i0; i < std::min(120, i0 + 3); ++i) {
        for (int j = j0; j < std::min(80, j0 + 4); ++j) top[i][j] = -1;
      }
    }
    const int wall_i = 40 + ui(rng) / 3, wall_j = uj(rng) / 2;  // a wall segment across y
    for (int j = wall_j; j < wall_j + 30 && j < 80; ++j) top[wall_i][j] = 20;
    for (int i = 0; i < 120; ++i) {
      for (int j = 0; j < 80; ++j) {
        if (top[i][j] < 0) continue;
        for (int k = 0; k <= top[i][j]; ++k) {
          auto* n = tree.updateNode(octomap::point3d(static_cast<float>((i + 0.5) * kRes), static_cast<float>((j + 0.5) * kRes),
                                                     static_cast<float>((k + 0.5) * kRes)),
                                    true);
          n->setMobility(k == top[i][j] ? mob(rng) : 0.0, weight(rng), 3);
        }
      }
    }
  }
};

// Two rectangles (centre, heading, length, width) share a point: a corner of one lies in
// the other or two of their sides cross.
bool rectanglesMeet(double xa, double ya, double ta, double xb, double yb, double tb, double length, double width) {
  using P = Eigen::Vector2d;
  const auto corners = [&](double x, double y, double t) {
    const P u(std::cos(t) * length / 2, std::sin(t) * length / 2), v(-std::sin(t) * width / 2, std::cos(t) * width / 2);
    return std::array<P, 4>{P(x, y) + u + v, P(x, y) - u + v, P(x, y) - u - v, P(x, y) + u - v};
  };
  const auto inside = [&](const P& q, double x, double y, double t) {
    const P d = q - P(x, y);
    return std::abs(std::cos(t) * d.x() + std::sin(t) * d.y()) <= length / 2 && std::abs(-std::sin(t) * d.x() + std::cos(t) * d.y()) <= width / 2;
  };
  const auto cross = [](const P& a, const P& b) { return a.x() * b.y() - a.y() * b.x(); };
  const auto a = corners(xa, ya, ta), b = corners(xb, yb, tb);
  for (int i = 0; i < 4; ++i) {
    if (inside(a[i], xb, yb, tb) || inside(b[i], xa, ya, ta)) return true;
    for (int j = 0; j < 4; ++j) {
      const P p = a[i], r = a[(i + 1) % 4] - a[i], q = b[j], s = b[(j + 1) % 4] - b[j];
      const double d = cross(r, s);
      if (d == 0) continue;
      const double t = cross(q - p, s) / d, u = cross(q - p, r) / d;
      if (t >= 0 && t <= 1 && u >= 0 && u <= 1) return true;
    }
  }
  return false;
}

// The reference: Dijkstra over (run, heading, side) states with the planner's moves
// (forward -2..9 lattice steps and sideways the stance width -1..+2 lattice steps in the
// stance's frame, rounded to the lattice, a stride at most max_stride_m; the new heading
// the stance's or one step either way; soles that do not overlap), its step rules
// (standable sole, step height, swing) and its cost. Returns the cheapest cost from the
// two start soles to a sole within the goal tolerance on the goal's level, or infinity.
double referenceCost(const SurfaceColumns& cols, const Plan& plan, const Eigen::Vector3d& goal, double z_goal, const PlanParams& p) {
  const RobotParams& r = p.robot;
  const double res = cols.resolution();
  const long s = std::max(1L, std::lround(r.lattice_m / res));
  const double cell = s * res;
  struct St {
    std::size_t run;
    int heading, side;  // side 0 left, 1 right
    bool operator<(const St& o) const { return std::tie(run, heading, side) < std::tie(o.run, o.heading, o.side); }
  };
  const auto centre = [&](std::size_t run) {
    const long col = cols.runColumn(run);
    return std::pair<long, long>{cols.keyX0() + col / cols.columnsY(), cols.keyY0() + col % cols.columnsY()};
  };
  std::map<std::pair<std::size_t, int>, Foothold> soles;
  const auto sole = [&](std::size_t run, int heading) -> const Foothold& {
    const auto key = std::make_pair(run, heading % (kHeadings / 2));
    auto it = soles.find(key);
    if (it == soles.end()) {
      const auto [kx, ky] = centre(run);
      it = soles.emplace(key, evaluateFoothold(cols, cols.centreOf(kx), cols.centreOf(ky), headingYaw(heading),
                                                cols.topFace(cols.runs()[run]), r))
               .first;
    }
    return it->second;
  };
  // The start soles: the plan's first two footsteps.
  const auto stateOf = [&](const Footstep& f) {
    const long col = cols.columnIndex(cols.keyOf(f.x), cols.keyOf(f.y));
    std::size_t best = cols.runBegin(col);
    for (std::size_t q = cols.runBegin(col); q < cols.runEnd(col); ++q) {
      if (std::abs(cols.topFace(cols.runs()[q]) - f.z) < std::abs(cols.topFace(cols.runs()[best]) - f.z)) best = q;
    }
    const double yaw = f.yaw < 0 ? f.yaw + 2 * kPi : f.yaw;
    return St{best, static_cast<int>(std::lround(yaw / (2 * kPi / kHeadings))) % kHeadings, f.side == Side::kLeft ? 0 : 1};
  };
  std::map<St, double> dist;
  std::set<St> done;
  using Item = std::pair<double, St>;
  std::priority_queue<Item, std::vector<Item>, std::function<bool(const Item&, const Item&)>> open(
      [](const Item& a, const Item& b) { return a.first > b.first; });
  for (int i = 0; i < 2; ++i) {
    const St st = stateOf(plan.footsteps[static_cast<std::size_t>(i)]);
    dist[st] = 0;
    open.push({0.0, st});
  }
  while (!open.empty()) {
    const auto [g, st] = open.top();
    open.pop();
    if (!done.insert(st).second) continue;
    const auto [kx, ky] = centre(st.run);
    const double x = cols.centreOf(kx), y = cols.centreOf(ky);
    const Foothold& from = sole(st.run, st.heading);
    if (std::hypot(goal.x() - x, goal.y() - y) <= p.goal_tolerance_m + 1e-9 && std::abs(from.z - z_goal) <= 0.1 + r.max_unevenness_m) {
      return g;
    }
    const double t = headingYaw(st.heading), c = std::cos(t), sn = std::sin(t);
    const double sgn = st.side == 1 ? 1.0 : -1.0;  // the new foot's side: left (+) after a right stance
    std::set<std::pair<long, long>> offsets;
    for (int fx = -2; fx <= 9; ++fx) {
      for (int fy = -1; fy <= 2; ++fy) {
        const double a = fx * cell, b = sgn * (r.stance_width_m + fy * cell);
        if (std::hypot(a, b) > r.max_stride_m + 1e-9) continue;
        offsets.insert({std::lround((c * a - sn * b) / cell), std::lround((sn * a + c * b) / cell)});
      }
    }
    for (const auto& [di, dj] : offsets) {
      const long nkx = kx + di * s, nky = ky + dj * s;
      const double nx = cols.centreOf(nkx), ny = cols.centreOf(nky);
      const double stride = std::hypot(nx - x, ny - y);
      if (stride > r.max_stride_m + 1e-9) continue;
      const long col = cols.columnIndex(nkx, nky);
      for (std::size_t run = cols.runBegin(col); run < cols.runEnd(col); ++run) {
        for (int dk = -1; dk <= 1; ++dk) {
          const St to{run, (st.heading + dk + kHeadings) % kHeadings, 1 - st.side};
          const Foothold& f = sole(run, to.heading);
          if (!f.standable() || !stepHeightOk(from.z, f.z, r, res)) continue;
          if (rectanglesMeet(x, y, t, nx, ny, headingYaw(to.heading), r.sole_length_m, r.sole_width_m)) continue;
          const double cost = std::hypot(stride, f.z - from.z) + p.step_cost_m + p.mobility_weight_m * (1.0 - f.min_mobility) +
                              p.variance_weight_m * f.mean_variance;
          const auto it = dist.find(to);
          if (it != dist.end() && it->second <= g + cost) continue;
          if (swingProblem(cols, x, y, from.z, nx, ny, f.z, r) != FootholdProblem::kNone) continue;
          dist[to] = g + cost;
          open.push({g + cost, to});
        }
      }
    }
  }
  return std::numeric_limits<double>::infinity();
}

// Run twice: as planFootsteps() runs by default (short plans end before the map-aware
// bound is added) and with the bound from the first expansion (map_bound_after 0), so
// that its admissibility and consistency are what the optimality rests on.
TEST(FootstepPlanner, WeightOneFindsTheReferenceCostAndLargerWeightsStayWithinTheirBound) {
  for (const std::size_t bound_after : {PlanParams{}.map_bound_after, std::size_t{0}}) {
  SCOPED_TRACE("map_bound_after " + std::to_string(bound_after));
  int compared = 0;
  for (unsigned seed = 1; seed <= 4; ++seed) {
    const RoughScene scene(seed);
    const auto cols = std::make_shared<const SurfaceColumns>(scene.tree);
    std::mt19937 rng(100 + seed);
    std::uniform_real_distribution<double> ux(0.2, 2.2), uy(0.2, 1.4);
    for (int pair = 0; pair < 3; ++pair) {
      const Eigen::Vector3d start(ux(rng), uy(rng), 0.3), goal(ux(rng), uy(rng), 0.3);
      PlanParams p;
      p.heuristic_weight = 1.0;
      p.map_bound_after = bound_after;
      Plan optimal;
      try {
        optimal = planFootsteps(cols, start, goal, p);
      } catch (const PlanInputError&) {
        continue;  // the point lies over a hole
      }
      if (!optimal.found) continue;
      const long below = cols->runBelow(goal.x(), goal.y(), goal.z() + 0.1, goal.z() - 2.0);
      if (below < 0) continue;  // the goal's surface lies beside its column: not the reference's rule
      const double z_goal = cols->topFace(cols->runs()[static_cast<std::size_t>(below)]);
      const double reference = referenceCost(*cols, optimal, goal, z_goal, p);
      SCOPED_TRACE("seed " + std::to_string(seed) + " pair " + std::to_string(pair));
      EXPECT_NEAR(optimal.cost, reference, 1e-9 * reference);
      for (const double w : {1.25, 2.0}) {
        p.heuristic_weight = w;
        const Plan fast = planFootsteps(cols, start, goal, p);
        ASSERT_TRUE(fast.found) << fast.reason;
        EXPECT_GE(fast.cost, reference - 1e-9);
        EXPECT_LE(fast.cost, w * reference + 1e-9);
      }
      ++compared;
    }
  }
  EXPECT_GE(compared, 6);  // enough pairs had a plan to compare
  }
}

// A refusal for a goal out of reach (the look back from the goal, or whole-map
// reachability) agrees with whole-map reachability worked out here; with a cache the
// planner answers the same, plan for plan and reason for reason.
TEST(FootstepPlanner, RefusesOnlyGoalsWholeMapReachabilitySaysAreOutOfReachWithOrWithoutACache) {
  for (const std::size_t bound_after : {PlanParams{}.map_bound_after, std::size_t{0}}) {
  SCOPED_TRACE("map_bound_after " + std::to_string(bound_after));
  int refused = 0, found = 0;
  // voxel_scene.hpp's floor, stairs to a platform, ledge, walled room and annex.
  const Scene scene;
  const auto cols = std::make_shared<const SurfaceColumns>(scene.tree);
  ReachCache cache;
  const std::vector<Eigen::Vector3d> starts = {{0.7, 0.3, 0.05}, {1.0, 1.5, 0.05}, {0.6, 1.0, 0.05}};
  const std::vector<Eigen::Vector3d> goals = {{1.8, 0.3, 0.35}, {2.55, 0.3, 0.35}, {2.6, 1.6, 0.05},
                                              {3.3, 0.4, 0.05}, {1.5, 1.2, 0.05}, {1.2, 0.3, 0.15}};
  for (std::size_t si = 0; si < starts.size(); ++si) {
    for (std::size_t gi = 0; gi < goals.size(); ++gi) {
      const Eigen::Vector3d start = starts[si], goal = goals[gi];
      PlanParams p;
      p.heuristic_weight = (si + gi) % 2 ? 1.0 : 1.25;
      p.robot.max_step_m = 0.06 + 0.045 * static_cast<double>((si + gi) % 3);
      p.map_bound_after = bound_after;
      Plan plan, cached;
      try {
        plan = planFootsteps(cols, start, goal, p);
        cached = planFootsteps(cols, start, goal, p, {}, &cache);
      } catch (const PlanInputError&) {
        continue;
      }
      SCOPED_TRACE("start " + std::to_string(si) + " goal " + std::to_string(gi) + ": " + plan.reason);
      ASSERT_EQ(plan.found, cached.found);
      EXPECT_EQ(plan.reason, cached.reason);
      EXPECT_EQ(plan.cost, cached.cost);
      ASSERT_EQ(plan.footsteps.size(), cached.footsteps.size());
      if (plan.found) {
        ++found;
        continue;
      }
      if (plan.time_limit_reached || plan.reason.find("narrow passage") != std::string::npos) continue;
      // Out of reach, says the planner: no standable sole at the goal is reachable.
      ReachParams rp;
      rp.robot = p.robot;
      rp.start_radius_m = p.start_radius_m + 0.5 * p.robot.stance_width_m;
      const Reachability reach = computeReachability(cols, start, rp);
      const long below = cols->runBelow(goal.x(), goal.y(), goal.z() + 0.1, goal.z() - 2.0);
      if (below < 0) continue;
      const double z_goal = cols->topFace(cols->runs()[static_cast<std::size_t>(below)]);
      for (const std::size_t f : reach.footPlacesNear(goal.x(), goal.y(), p.goal_tolerance_m)) {
        const FootPlace& fp = reach.footPlaces()[f];
        if (fp.isStandable() && std::abs(fp.z - z_goal) <= 0.1 + p.robot.max_unevenness_m) {
          EXPECT_FALSE(fp.reachable) << plan.reason;
        }
      }
      ++refused;
    }
  }
  std::printf("[ info ] %d plans found, %d refused as out of reach\n", found, refused);
  EXPECT_GE(refused, 3);  // both kinds of answer were compared
  EXPECT_GE(found, 3);
  }
}

// A building of 20 x 20 m (tests/mapping/building_scene.hpp), its room-to-room trip
// (~21 m of footsteps through two doors and the corridors' crossing): with the map-aware
// bound the search finds it within 100,000 expansions; with the straight line alone it
// does not (it floods the rooms beside the way). Every step of the plan keeps the rules.
TEST(FootstepPlanner, TheMapAwareBoundFindsATripThroughDoorsTheStraightLineDoesNot) {
  building::Params bp;
  bp.size_m = 20;
  const building::Scene scene(bp);
  const auto cols = std::make_shared<const SurfaceColumns>(scene.tree);
  const building::Trip& trip = scene.trips[1];
  PlanParams p;
  p.max_expansions = 100000;
  p.time_limit_s = 3600;  // the expansions end the search, not the clock
  const Plan with = planFootsteps(cols, trip.from, trip.to, p);
  ASSERT_TRUE(with.found) << with.reason;
  EXPECT_LT(with.expansions, p.max_expansions);
  const RobotParams& r = p.robot;
  const double res = cols->resolution();
  ASSERT_GE(with.footsteps.size(), 3u);
  for (std::size_t i = 1; i < with.footsteps.size(); ++i) {
    const Footstep& a = with.footsteps[i - 1];
    const Footstep& b = with.footsteps[i];
    SCOPED_TRACE("footstep " + std::to_string(i));
    EXPECT_NE(a.side, b.side);
    EXPECT_LE(std::hypot(b.x - a.x, b.y - a.y), r.max_stride_m + 1e-9);
    EXPECT_TRUE(stepHeightOk(a.z, b.z, r, res));
    EXPECT_EQ(swingProblem(*cols, a.x, a.y, a.z, b.x, b.y, b.z, r), FootholdProblem::kNone);
    EXPECT_TRUE(evaluateFoothold(*cols, b.x, b.y, b.yaw, b.z, r).standable());
  }
  const Footstep& last = with.footsteps.back();
  EXPECT_LE(std::hypot(last.x - trip.to.x(), last.y - trip.to.y()), p.goal_tolerance_m + std::hypot(r.stance_width_m, 0.0) + 1e-9);
  p.map_bound_after = p.max_expansions;  // never
  const Plan without = planFootsteps(cols, trip.from, trip.to, p);
  EXPECT_FALSE(without.found);
  EXPECT_EQ(without.expansions, p.max_expansions);
}

}  // namespace
}  // namespace mobmap::mapping
