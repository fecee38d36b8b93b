#include "mobmap/mapping/footstep_planner.hpp"

#include "mobmap/mapping/reachability.hpp"
#include "param_error.hpp"
#include "reach_detail.hpp"
#include "surface_bound.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <deque>
#include <cmath>
#include <cstdio>
#include <limits>
#include <queue>
#include <optional>
#include <set>
#include <tuple>
#include <unordered_map>
#include <unordered_set>

namespace mobmap::mapping {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kSurfaceSearch = 2.0;  ///< how far below the start and goal points to look for a surface
constexpr double kLevelSlack = 0.1;     ///< a sole's support this close to a level counts as on it
/// How many foot places the look back from the goal may visit after `expansions` (0: no
/// look then): a few hundred after 2,048 (a goal on a ledge or a stair cut off from the
/// rest), eight times more at each doubling after, when the search has come far enough
/// to meet it or the goal's part of the map is larger (up to ~2 s of judging soles).
std::size_t lookBackFeet(std::size_t expansions) {
  switch (expansions) {
    case 2048: return 256;
    case 4096: return 2048;
    case 8192: return 16384;
    case 16384: return 131072;
    default: return 0;
  }
}
constexpr std::size_t kDiagnoseFeet = 40000;  ///< foot places the search for the step that blocks may visit
/// The map-aware bound settles the nodes up to this factor past the start's distance:
/// the footstep search strays that far from the bound's shortest way at little cost
/// (a factor of 1 left the 30 m trip across the building nine times as many expansions).
constexpr double kBoundBeyond = 1.1;

using detail::floorDiv;

std::string format(const char* fmt, double a = 0, double b = 0, double c = 0, double d = 0, double e = 0, double f = 0) {
  char buf[512];
  std::snprintf(buf, sizeof buf, fmt, a, b, c, d, e, f);
  return buf;
}

// Two soles (centre, heading, length, width) overlap: separating axis test of two rectangles.
bool solesOverlap(double xa, double ya, double ta, double xb, double yb, double tb, double length, double width) {
  const Eigen::Vector2d d(xb - xa, yb - ya);
  const std::array<Eigen::Vector2d, 4> axes = {Eigen::Vector2d(std::cos(ta), std::sin(ta)),
                                               Eigen::Vector2d(-std::sin(ta), std::cos(ta)),
                                               Eigen::Vector2d(std::cos(tb), std::sin(tb)),
                                               Eigen::Vector2d(-std::sin(tb), std::cos(tb))};
  const auto extent = [&](const Eigen::Vector2d& axis, double t) {
    const Eigen::Vector2d u(std::cos(t), std::sin(t)), v(-std::sin(t), std::cos(t));
    return 0.5 * length * std::abs(axis.dot(u)) + 0.5 * width * std::abs(axis.dot(v));
  };
  for (const auto& axis : axes) {
    if (std::abs(axis.dot(d)) > extent(axis, ta) + extent(axis, tb)) return false;
  }
  return true;
}

// Why a sole cannot be stood on, with its numbers and the option that sets the limit.
std::string describeProblem(const Foothold& f, const RobotParams& r) {
  switch (f.problem) {
    case FootholdProblem::kNoSurface:
      return format("only %.0f %% of a sole there rests on known surface (`min_support_fraction` ", 100 * f.support_fraction) +
             formatLimit(100 * r.min_support_fraction) + " %)";
    case FootholdProblem::kTooSteep:
      return format("its surface tilts %.1f degrees, over `max_tilt_deg` ", f.tilt_deg) + formatLimit(r.max_tilt_deg);
    case FootholdProblem::kUneven:
      return format("the surface under a sole is uneven by %.3f m, over `max_unevenness_m` ", f.unevenness_m) +
             formatLimit(r.max_unevenness_m);
    case FootholdProblem::kObstacle:
      return "something occupied stands inside the sole's space (within `swing_clearance_m` or `clearance_m` above it)";
    case FootholdProblem::kLowMobility:
      return format("%.0f %% of the surface under the sole has mobility under `min_mobility` ", 100 * f.poor_fraction) +
             formatLimit(r.min_mobility) + format(" (mean %.2f; at most ", f.mean_mobility) +
             formatLimit(100 * r.max_poor_fraction) + " % may: `max_poor_fraction`)";
    case FootholdProblem::kNone: break;
  }
  return "it can be stood on";
}

struct State {
  std::size_t run = 0;
  int heading = 0;
  Side side = Side::kLeft;
  [[nodiscard]] std::uint64_t key() const {
    return (static_cast<std::uint64_t>(run) << 5) | (static_cast<std::uint64_t>(heading) << 1) | (side == Side::kRight ? 1u : 0u);
  }
  [[nodiscard]] static State fromKey(std::uint64_t key) {
    return State{static_cast<std::size_t>(key >> 5), static_cast<int>((key >> 1) & 15u), (key & 1u) ? Side::kRight : Side::kLeft};
  }
};

// A state's search record: cost so far, the state it was reached from, whether expanded.
// g = infinity: not reached yet.
struct Node {
  double g = std::numeric_limits<double>::infinity();
  std::uint64_t parent = 0;
  bool closed = false;
  bool pulled = false;  ///< its sole judged and every expanded state that steps to it tried
  /// The lowest lower bound at which the state waits in the open list to be judged.
  double bound = std::numeric_limits<double>::infinity();
};

// What the search has learnt about one run it touched: its centre, its soles' verdicts
// (index into Search::footholds_ per heading modulo half a turn; a sole reads the same
// turned by 180 degrees) and its states' records. Made the first time the search asks
// for the run; ~0.8 KB each.
struct RunRecord {
  double x = 0, y = 0;
  /// The heuristic's bound on the strides' sum from here (metres), and what it holds:
  /// 0 nothing yet, 1 the straight line, 2 the straight line and the map-aware bound.
  double metres = 0;
  std::uint8_t metres_of = 0;
  std::array<std::int32_t, kHeadings / 2> foothold;
  std::array<Node, 2 * kHeadings> nodes;  ///< by heading * 2 + side
};

// A swing-foot placement relative to the stance foot: a lattice offset, its horizontal
// stride, and per change of heading (-1, 0, +1) whether the two soles overlap.
struct Move {
  long di = 0, dj = 0;
  double stride = 0;
  std::array<bool, 3> overlaps{};
};

class Search {
 public:
  Search(const SurfaceColumns& cols, const RobotParams& robot)
      : cols_(cols), r_(robot), res_(cols.resolution()), record_of_run_(cols.runs().size(), -1) {
    s_ = std::max(1L, std::lround(r_.lattice_m / res_));
    // Swing-foot placements relative to the stance foot, per heading and side, as distinct
    // lattice offsets: forward -2..9 lattice steps, sideways the stance width -1..+2
    // lattice steps. Offsets longer than a stride, after rounding to the lattice, are
    // dropped here rather than at every expansion.
    const double cell = s_ * res_;
    for (int k = 0; k < kHeadings; ++k) {
      const double t = headingYaw(k), c = std::cos(t), s = std::sin(t);
      for (int side = 0; side < 2; ++side) {
        const double sgn = side == 0 ? 1.0 : -1.0;  // the new foot is left (+) or right (-) of the stance
        std::set<std::pair<long, long>> seen;
        for (int fx = -2; fx <= 9; ++fx) {
          for (int fy = -1; fy <= 2; ++fy) {
            const double a = fx * cell, b = sgn * (r_.stance_width_m + fy * cell);
            if (std::hypot(a, b) > r_.max_stride_m + 1e-9) continue;
            const long di = std::lround((c * a - s * b) / cell), dj = std::lround((s * a + c * b) / cell);
            if (!seen.insert({di, dj}).second) continue;
            Move m;
            m.di = di, m.dj = dj;
            m.stride = std::hypot(di * cell, dj * cell);
            if (m.stride > r_.max_stride_m + 1e-6) continue;
            for (int dk = -1; dk <= 1; ++dk) {
              m.overlaps[static_cast<std::size_t>(dk + 1)] =
                  solesOverlap(0, 0, t, di * cell, dj * cell, headingYaw((k + dk + kHeadings) % kHeadings), r_.sole_length_m, r_.sole_width_m);
            }
            moves_[k][side].push_back(m);
          }
        }
      }
    }
  }

  RunRecord& record(std::size_t run) {
    std::int32_t& i = record_of_run_[run];
    if (i < 0) {
      i = static_cast<std::int32_t>(records_.size());
      RunRecord& r = records_.emplace_back();
      const long col = static_cast<long>(cols_.runColumn(run));
      r.x = cols_.centreOf(cols_.keyX0() + col / cols_.columnsY());
      r.y = cols_.centreOf(cols_.keyY0() + col % cols_.columnsY());
      r.foothold.fill(-1);
      return r;
    }
    return records_[static_cast<std::size_t>(i)];
  }

  /// The record of a run if the search has touched it, else null.
  [[nodiscard]] RunRecord* touched(std::size_t run) {
    const std::int32_t i = record_of_run_[run];
    return i < 0 ? nullptr : &records_[static_cast<std::size_t>(i)];
  }

  Node& node(const State& st) { return record(st.run).nodes[static_cast<std::size_t>(st.heading * 2 + (st.side == Side::kRight ? 1 : 0))]; }

  const Foothold& foothold(std::size_t run, int heading) { return foothold(run, record(run), heading); }
  const Foothold& foothold(std::size_t run, RunRecord& rec, int heading) {
    std::int32_t& i = rec.foothold[static_cast<std::size_t>(heading % (kHeadings / 2))];
    if (i < 0) {
      i = static_cast<std::int32_t>(footholds_.size());
      footholds_.push_back(evaluateFoothold(cols_, rec.x, rec.y, headingYaw(heading), cols_.topFace(cols_.runs()[run]), r_));
    }
    return footholds_[static_cast<std::size_t>(i)];
  }

  /// The sole of `heading` on a run if it has been judged, else null.
  [[nodiscard]] const Foothold* judged(const RunRecord& rec, int heading) const {
    const std::int32_t i = rec.foothold[static_cast<std::size_t>(heading % (kHeadings / 2))];
    return i < 0 ? nullptr : &footholds_[static_cast<std::size_t>(i)];
  }

  [[nodiscard]] std::pair<double, double> centre(std::size_t run) {
    const RunRecord& r = record(run);
    return {r.x, r.y};
  }

  /// Lattice column nearest (x, y): its key pair.
  [[nodiscard]] std::pair<long, long> latticeKey(double x, double y) const {
    const long kx = cols_.keyOf(x), ky = cols_.keyOf(y);
    return {s_ * floorDiv(kx + s_ / 2, s_), s_ * floorDiv(ky + s_ / 2, s_)};
  }

  /// Runs of the lattice column (kx, ky) whose top lies within `slack` of z.
  template <class F>
  void runsNear(long kx, long ky, double z, double slack, F&& visit) const {
    const long col = cols_.columnIndex(kx, ky);
    for (std::size_t r = cols_.runBegin(col); r < cols_.runEnd(col); ++r) {
      if (std::abs(cols_.topFace(cols_.runs()[r]) - z) <= slack) visit(r);
    }
  }

  /// A standable sole of `heading` as near (x, y) as possible within `radius`, on the
  /// level z; false if none.
  bool nearestStandable(double x, double y, double z, double radius, const std::vector<int>& headings, State& out) {
    const long rad = static_cast<long>(std::ceil(radius / (s_ * res_)));
    const auto [kx0, ky0] = latticeKey(x, y);
    double best = std::numeric_limits<double>::infinity();
    for (long di = -rad; di <= rad; ++di) {
      for (long dj = -rad; dj <= rad; ++dj) {
        const long kx = kx0 + di * s_, ky = ky0 + dj * s_;
        const double d = std::hypot(cols_.centreOf(kx) - x, cols_.centreOf(ky) - y);
        if (d > radius + 1e-9) continue;
        runsNear(kx, ky, z, kLevelSlack + r_.max_unevenness_m, [&](std::size_t run) {
          for (std::size_t i = 0; i < headings.size(); ++i) {
            const double score = d + 0.01 * static_cast<double>(i);
            if (score >= best || !foothold(run, headings[i]).standable()) continue;
            best = score;
            out.run = run, out.heading = headings[i];
          }
        });
      }
    }
    return std::isfinite(best);
  }

  const SurfaceColumns& cols_;
  const RobotParams& r_;
  double res_;
  long s_ = 1;
  std::array<std::array<std::vector<Move>, 2>, kHeadings> moves_;

 private:
  std::vector<std::int32_t> record_of_run_;  ///< per run, into records_ (-1: not touched)
  std::deque<RunRecord> records_;            ///< a deque: references stay valid as it grows
  std::deque<Foothold> footholds_;
};

// The surface height under a point: the highest top at most kLevelSlack above it, within
// kSurfaceSearch below, in its column or the nearest column within `radius` that has one.
std::optional<double> surfaceUnder(const SurfaceColumns& cols, const Eigen::Vector3d& p, double radius) {
  const long r = cols.runBelow(p.x(), p.y(), p.z() + kLevelSlack, p.z() - kSurfaceSearch);
  if (r >= 0) return cols.topFace(cols.runs()[static_cast<std::size_t>(r)]);
  const double res = cols.resolution();
  const long n = static_cast<long>(std::ceil(radius / res));
  double best_d = std::numeric_limits<double>::infinity();
  std::optional<double> z;
  for (long i = -n; i <= n; ++i) {
    for (long j = -n; j <= n; ++j) {
      const double d = std::hypot(i * res, j * res);
      if (d > radius || d >= best_d) continue;
      const long q = cols.runBelow(p.x() + i * res, p.y() + j * res, p.z() + kLevelSlack, p.z() - kSurfaceSearch);
      if (q >= 0) best_d = d, z = cols.topFace(cols.runs()[static_cast<std::size_t>(q)]);
    }
  }
  return z;
}

// The walk the planner checks a goal against: from the start stance.
ReachParams reachParamsOf(const PlanParams& p) {
  ReachParams rp;
  rp.robot = p.robot;
  rp.start_radius_m = p.start_radius_m + 0.5 * p.robot.stance_width_m;
  return rp;
}

// A standable foot place on the goal's level (with the goal tolerance around it: a sole the plan may end on).
bool atGoalLevel(const FootPlace& f, double z_goal, const RobotParams& robot) {
  return f.isStandable() && std::abs(f.z - z_goal) <= kLevelSlack + robot.max_unevenness_m;
}

// The standable foot places at the goal: within the goal tolerance, on the goal's level.
std::vector<std::size_t> goalFeet(const Reachability& reach, const Eigen::Vector3d& goal, double z_goal, const PlanParams& p) {
  std::vector<std::size_t> goals;
  for (const std::size_t f : reach.footPlacesNear(goal.x(), goal.y(), p.goal_tolerance_m)) {
    const FootPlace& fp = reach.footPlaces()[f];
    if (atGoalLevel(fp, z_goal, p.robot)) goals.push_back(f);
  }
  return goals;
}

bool goalReachable(const Reachability& reach, const std::vector<std::size_t>& goals) {
  return std::any_of(goals.begin(), goals.end(), [&](std::size_t g) { return reach.footPlaces()[g].reachable; });
}

std::string blockingStep(const std::vector<FootPlace>& path, const RobotParams& robot, double res);

std::string cutOff() {
  return "the goal is cut off from the start: every way there crosses a wall or an obstacle higher than "
         "`swing_clearance_m`, a stretch over `max_gap_m` without surface, or surface the robot cannot stand on "
         "(`min_mobility`, `max_tilt_deg`)";
}

// Why the goal cannot be reached over the soles and steps (the search found nothing).
std::string diagnose(const SurfaceColumns& cols, const Reachability& reach, const std::vector<std::size_t>& goals,
                     const PlanParams& p) {
  const RobotParams& robot = p.robot;
  const double res = cols.resolution();
  if (goalReachable(reach, goals)) {
    return "no footstep sequence found: the goal's surface can be reached, but not with the planner's strides and turns "
           "(a narrow passage or a tight turn); try a larger `max_stride_m` or `goal_tolerance_m`";
  }
  // The easiest way there: the smallest possible highest step (minimax Dijkstra over the
  // soles, every other limit kept).
  const auto& feet = reach.footPlaces();
  std::vector<double> worst(feet.size(), std::numeric_limits<double>::infinity());
  std::vector<std::size_t> parent(feet.size(), feet.size());
  using Item = std::pair<double, std::size_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> open;
  for (const std::size_t f : reach.startFeet()) worst[f] = 0, open.push({0.0, f});
  std::vector<bool> is_goal(feet.size(), false);
  for (const std::size_t g : goals) is_goal[g] = true;
  std::optional<std::size_t> reached;
  while (!open.empty()) {
    const auto [w, a] = open.top();
    open.pop();
    if (w > worst[a]) continue;
    if (is_goal[a]) {
      reached = a;
      break;
    }
    for (const std::size_t b : reach.footPlacesNear(feet[a].x, feet[a].y, robot.max_stride_m)) {
      if (!feet[b].isStandable()) continue;
      const double wb = std::max(w, std::abs(feet[a].z - feet[b].z));
      if (wb >= worst[b]) continue;
      if (swingProblem(cols, feet[a].x, feet[a].y, feet[a].z, feet[b].x, feet[b].y, feet[b].z, robot) != FootholdProblem::kNone) {
        continue;
      }
      worst[b] = wb, parent[b] = a;
      open.push({wb, b});
    }
  }
  if (!reached) return cutOff();
  std::vector<FootPlace> path;
  for (std::size_t b = *reached; b < feet.size(); b = parent[b]) path.push_back(feet[b]);
  std::reverse(path.begin(), path.end());
  return blockingStep(path, robot, res);
}

// The first step over the height limit on `path` (foot places from the start to the goal).
std::string blockingStep(const std::vector<FootPlace>& path, const RobotParams& robot, double res) {
  for (std::size_t i = 1; i < path.size(); ++i) {
    const FootPlace& from = path[i - 1];
    const FootPlace& to = path[i];
    if (stepHeightOk(from.z, to.z, robot, res)) continue;
    // The numbers add up as printed: the heights to a tenth of a millimetre, the rise and
    // what the step needs from those.
    const auto tenth = [](double v) { return std::round(v * 1e4) / 1e4; };
    const double z0 = tenth(from.z), z1 = tenth(to.z), rise = std::abs(z1 - z0);
    return std::string(to.z > from.z ? "the step up" : "the step down") +
           format(" on the easiest way there measures %.4f m, from a sole resting at z = %.4f m to one at z = %.4f m "
                  "(near x = %.2f, y = %.2f; each height known to one voxel, %g m); ",
                  rise, z0, z1, to.x, to.y, res) +
           "a step passes when its measured rise plus one voxel to spare is at most `max_step_m` " +
           formatLimit(robot.max_step_m) + format(": this one needs %.4f m", rise + res);
  }
  return "the goal is cut off from the start (no step over the limits found on the way; `max_gap_m` or `swing_clearance_m` "
         "may block it)";
}

// Foot places judged on demand, as computeStandability() judges them: for the planner's
// quick look around the goal, which must not cost a whole map's soles.
class LazyFeet {
 public:
  LazyFeet(const SurfaceColumns& cols, const RobotParams& robot)
      : cols_(cols),
        robot_(robot),
        s_(std::max(1L, std::lround(robot.lattice_m / cols.resolution()))),
        offsets_(detail::strideOffsets(robot, s_, cols.resolution())) {}

  /// The foot places (indices) of lattice cell (i, j): key (i s, j s).
  const std::vector<std::size_t>& cell(long i, long j) {
    const long col = cols_.columnIndex(i * s_, j * s_);
    if (col < 0) return none_;
    auto [it, fresh] = cells_.try_emplace(col);
    if (fresh) {
      for (std::size_t run = cols_.runBegin(col); run < cols_.runEnd(col); ++run) {
        const FootPlace fp = detail::judgeFootPlace(cols_, i * s_, j * s_, run, robot_);
        if (!fp.geometry_ok) continue;
        it->second.push_back(feet_.size());
        feet_.push_back(fp);
      }
    }
    return it->second;
  }

  const FootPlace& operator[](std::size_t f) const { return feet_[f]; }
  [[nodiscard]] std::size_t judged() const { return feet_.size(); }

  /// Foot places within `radius` of (x, y), in Standability::footPlacesNear()'s order.
  std::vector<std::size_t> near(double x, double y, double radius) {
    std::vector<std::size_t> out;
    const double cell_m = s_ * cols_.resolution();
    const long ci = floorDiv(cols_.keyOf(x), s_), cj = floorDiv(cols_.keyOf(y), s_);
    const long rad = static_cast<long>(std::ceil(radius / cell_m)) + 1;
    for (long i = ci - rad; i <= ci + rad; ++i) {
      for (long j = cj - rad; j <= cj + rad; ++j) {
        for (const std::size_t f : cell(i, j)) {
          if (std::hypot(feet_[f].x - x, feet_[f].y - y) <= radius + 1e-9) out.push_back(f);
        }
      }
    }
    return out;
  }

  /// Visits the foot places a stride or less from foot place `f` (lattice offsets).
  template <class F>
  void neighbours(std::size_t f, F&& visit) {
    const long ci = floorDiv(cols_.keyOf(feet_[f].x), s_), cj = floorDiv(cols_.keyOf(feet_[f].y), s_);
    for (const auto& [di, dj] : offsets_) {
      // cell() may grow feet_: copy the indices' list before visiting.
      const std::vector<std::size_t> there = cell(ci + di, cj + dj);
      for (const std::size_t g : there) visit(g);
    }
  }

  /// The start soles of a walk from `start` (the planner's: reachParamsOf), as
  /// computeReachability() picks them.
  std::vector<std::size_t> startFeet(const Eigen::Vector3d& start, const PlanParams& p) {
    const double res = cols_.resolution();
    return detail::nearestStartFeet(
        start, near(start.x(), start.y(), p.start_radius_m + 0.5 * robot_.stance_width_m),
        std::max(0.5 * robot_.sole_length_m, s_ * res), std::max(0.05, 2 * res),
        [&](double x, double y, double radius) { return near(x, y, radius); },
        [&](std::size_t f) -> const FootPlace& { return feet_[f]; });
  }

  /// The standable soles at the goal (goalFeet()'s rule).
  std::vector<std::size_t> goalFeet(const Eigen::Vector3d& goal, double z_goal, const PlanParams& p) {
    std::vector<std::size_t> out;
    for (const std::size_t f : near(goal.x(), goal.y(), p.goal_tolerance_m)) {
      if (atGoalLevel(feet_[f], z_goal, p.robot)) out.push_back(f);
    }
    return out;
  }

 private:
  const SurfaceColumns& cols_;
  const RobotParams& robot_;
  long s_;
  std::vector<std::pair<long, long>> offsets_;
  std::unordered_map<long, std::vector<std::size_t>> cells_;
  std::vector<FootPlace> feet_;
  const std::vector<std::size_t> none_;
};

enum class Verdict { kUnknown, kReachable, kUnreachable };

// A quick look from the goal back towards the start over foot places judged on demand:
// every foot place that can step, one step after another, to a standable sole at the
// goal (computeReachability()'s steps, walked backwards). kUnreachable when those run
// out, none of them a start sole (then whole-map reachability would say the same);
// kReachable when one of them is a sole the search has already reached from the start
// (`reached(run)`); kUnknown after `cap` of them.
template <class Reached>
Verdict lookBackFromGoal(LazyFeet& feet, const SurfaceColumns& cols, const Eigen::Vector3d& start, const Eigen::Vector3d& goal,
                         double z_goal, const PlanParams& p, std::size_t cap, Reached&& reached) {
  const RobotParams& robot = p.robot;
  std::unordered_set<std::size_t> seen;
  std::deque<std::size_t> queue;
  for (const std::size_t f : feet.goalFeet(goal, z_goal, p)) {
    if (seen.insert(f).second) queue.push_back(f);
  }
  while (!queue.empty()) {
    const std::size_t a = queue.front();
    queue.pop_front();
    if (reached(feet[a].place)) return Verdict::kReachable;
    if (seen.size() > cap) return Verdict::kUnknown;
    const FootPlace to = feet[a];
    feet.neighbours(a, [&](std::size_t b) {
      const FootPlace& from = feet[b];
      if (seen.count(b) || !from.isStandable() || !canStep(cols, from.x, from.y, from.z, to.x, to.y, to.z, robot)) return;
      seen.insert(b);
      queue.push_back(b);
    });
  }
  // Cut off: unless a start sole is among them.
  for (const std::size_t f : feet.startFeet(start, p)) {
    if (seen.count(f)) return Verdict::kReachable;
  }
  return Verdict::kUnreachable;
}

// diagnose() for a goal lookBackFromGoal() found cut off: the easiest way there (the
// lowest highest step), searched backwards from the goal, nearest the start first among
// equals; nullopt after `cap` foot places.
std::optional<std::string> diagnoseFromGoal(LazyFeet& feet, const SurfaceColumns& cols, const Eigen::Vector3d& start,
                                            const Eigen::Vector3d& goal, double z_goal, const PlanParams& p, std::size_t cap) {
  const RobotParams& robot = p.robot;
  const double res = cols.resolution();
  const auto starts = feet.startFeet(start, p);
  if (starts.empty()) return std::nullopt;
  const std::unordered_set<std::size_t> is_start(starts.begin(), starts.end());
  std::unordered_map<std::size_t, std::pair<double, std::size_t>> best;  // worst step so far, next foot towards the goal
  using Item = std::tuple<double, double, std::size_t>;               // worst, distance to the start, foot
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> open;
  const auto towardStart = [&](std::size_t f) { return std::hypot(feet[f].x - start.x(), feet[f].y - start.y()); };
  constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
  for (const std::size_t f : feet.goalFeet(goal, z_goal, p)) {
    best[f] = {0.0, kNone};
    open.push({0.0, towardStart(f), f});
  }
  std::unordered_set<std::size_t> done;
  while (!open.empty()) {
    // Plain variables: the lambda below captures them (clang refuses a structured binding).
    const double w = std::get<0>(open.top());
    const std::size_t a = std::get<2>(open.top());
    open.pop();
    if (!done.insert(a).second) continue;
    if (is_start.count(a)) {
      std::vector<FootPlace> path;
      for (std::size_t f = a; f != kNone; f = best[f].second) path.push_back(feet[f]);
      return blockingStep(path, robot, res);
    }
    if (done.size() > cap) return std::nullopt;
    const FootPlace to = feet[a];
    feet.neighbours(a, [&](std::size_t b) {
      const FootPlace& from = feet[b];
      if (done.count(b) || !from.isStandable()) return;
      const double wb = std::max(w, std::abs(from.z - to.z));
      const auto it = best.find(b);
      if (it != best.end() && wb >= it->second.first) return;
      if (swingProblem(cols, from.x, from.y, from.z, to.x, to.y, to.z, robot) != FootholdProblem::kNone) return;
      best[b] = {wb, a};
      open.push({wb, towardStart(b), b});
    });
  }
  return cutOff();
}

}  // namespace

void validate(const PlanParams& p) {
  validate(p.robot);
  if (!(p.goal_tolerance_m > 0 && p.goal_tolerance_m <= 10)) detail::failParam("PlanParams", "goal_tolerance_m", p.goal_tolerance_m, "must be in (0, 10]");
  if (!(p.step_cost_m >= 0 && p.step_cost_m <= 100)) detail::failParam("PlanParams", "step_cost_m", p.step_cost_m, "must be in [0, 100]");
  if (!(p.mobility_weight_m >= 0 && p.mobility_weight_m <= 100)) detail::failParam("PlanParams", "mobility_weight_m", p.mobility_weight_m, "must be in [0, 100]");
  if (!(p.variance_weight_m >= 0 && p.variance_weight_m <= 100)) detail::failParam("PlanParams", "variance_weight_m", p.variance_weight_m, "must be in [0, 100]");
  if (!(p.start_radius_m >= 0 && p.start_radius_m <= 10)) detail::failParam("PlanParams", "start_radius_m", p.start_radius_m, "must be in [0, 10]");
  if (!(p.heuristic_weight >= 1 && p.heuristic_weight <= 10)) detail::failParam("PlanParams", "heuristic_weight", p.heuristic_weight, "must be in [1, 10]");
  if (!(p.time_limit_s > 0 && p.time_limit_s <= 86400)) detail::failParam("PlanParams", "time_limit_s", p.time_limit_s, "must be in (0, 86400]");
  if (p.max_expansions < 1) detail::failParam("PlanParams", "max_expansions", static_cast<double>(p.max_expansions), "must be >= 1");
}

namespace {
struct PlanField {
  const char* name;
  double PlanParams::*field;
};
constexpr PlanField kPlanFields[] = {
    {"goal_tolerance_m", &PlanParams::goal_tolerance_m},
    {"step_cost_m", &PlanParams::step_cost_m},
    {"mobility_weight_m", &PlanParams::mobility_weight_m},
    {"variance_weight_m", &PlanParams::variance_weight_m},
    {"start_radius_m", &PlanParams::start_radius_m},
    {"heuristic_weight", &PlanParams::heuristic_weight},
    {"time_limit_s", &PlanParams::time_limit_s},
};
constexpr const char* kMaxExpansions = "max_expansions";
constexpr const char* kMapBoundAfter = "map_bound_after";
}  // namespace

bool setPlanParameter(PlanParams& params, const std::string& name, double value) {
  if (setRobotParameter(params.robot, name, value)) return true;
  for (const PlanField& f : kPlanFields) {
    if (name == f.name) {
      params.*f.field = value;
      return true;
    }
  }
  if (name == kMapBoundAfter) {
    if (!(value >= 0 && value <= 1e12 && value == std::floor(value))) {
      throw util::FieldError("map_bound_after", "must be a whole number >= 0", "PlanParams");
    }
    params.map_bound_after = static_cast<std::size_t>(value);
    return true;
  }
  if (name != kMaxExpansions) return false;
  if (!(value >= 1 && value <= 1e12 && value == std::floor(value))) {
    throw util::FieldError("max_expansions", "must be a whole number >= 1", "PlanParams");
  }
  params.max_expansions = static_cast<std::size_t>(value);
  return true;
}

const std::vector<std::string>& planParameterNames() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n = robotParameterNames();
    for (const PlanField& f : kPlanFields) n.emplace_back(f.name);
    n.emplace_back(kMaxExpansions);
    n.emplace_back(kMapBoundAfter);
    return n;
  }();
  return names;
}

const char* toString(Side side) { return side == Side::kLeft ? "left" : "right"; }

namespace {
Plan planWithin(std::shared_ptr<const SurfaceColumns> columns, const Eigen::Vector3d& start, const Eigen::Vector3d& goal,
          const PlanParams& params, const Budget& budget, std::chrono::steady_clock::time_point t0, ReachCache* cache);
}  // namespace

Plan planFootsteps(const MobilityOcTree& tree, const Eigen::Vector3d& start, const Eigen::Vector3d& goal, const PlanParams& params,
                   const Budget& budget) {
  const auto t0 = std::chrono::steady_clock::now();  // the columns count against the time limit too
  validate(params);
  return planWithin(std::make_shared<const SurfaceColumns>(tree), start, goal, params, budget, t0, nullptr);
}

Plan planFootsteps(std::shared_ptr<const SurfaceColumns> columns, const Eigen::Vector3d& start, const Eigen::Vector3d& goal,
                   const PlanParams& params, const Budget& budget, ReachCache* cache) {
  return planWithin(std::move(columns), start, goal, params, budget, std::chrono::steady_clock::now(), cache);
}

namespace {

Plan planWithin(std::shared_ptr<const SurfaceColumns> columns, const Eigen::Vector3d& start, const Eigen::Vector3d& goal,
          const PlanParams& params, const Budget& budget, std::chrono::steady_clock::time_point t0, ReachCache* cache) {
  validate(params);
  // The time limit bounds the whole call (the reachability worked out for a goal that
  // seems out of reach included); the caller's budget, when it runs out, ends the call
  // with BudgetExceeded instead of an answer.
  Budget limited;
  limited.deadline = t0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                              std::chrono::duration<double>(params.time_limit_s));
  limited = limited.tightenedBy(budget);
  if (!columns) throw std::invalid_argument("planFootsteps: no columns");
  if (!start.allFinite()) throw std::invalid_argument("planFootsteps: the start is not finite");
  if (!goal.allFinite()) throw std::invalid_argument("planFootsteps: the goal is not finite");
  const SurfaceColumns& cols = *columns;
  const RobotParams& robot = params.robot;
  const double res = cols.resolution();
  if (robot.max_step_m < 2 * res - 1e-9) {
    throw util::FieldError("max_step_m", format("is %g (must be at least two voxels, %g m in this map)", robot.max_step_m, 2 * res),
                           "PlanParams");
  }
  Plan plan;
  const auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  const auto finish = [&](std::string reason) {
    plan.reason = std::move(reason);
    plan.planning_time_s = elapsed();
    return plan;
  };
  const auto z_start = surfaceUnder(cols, start, params.start_radius_m);
  if (!z_start) {
    throw PlanInputError(format("the start (%.2f, %.2f, %.2f) has no surface within 2 m below it", start.x(), start.y(), start.z()) +
                         format(" or %.2f m around it: it lies outside the map, or in free or unknown space", params.start_radius_m));
  }
  const auto z_goal = surfaceUnder(cols, goal, params.goal_tolerance_m);
  if (!z_goal) {
    throw PlanInputError(format("the goal (%.2f, %.2f, %.2f) has no surface within 2 m below it", goal.x(), goal.y(), goal.z()) +
                         format(" or %.2f m around it: it lies outside the map, or in free or unknown space", params.goal_tolerance_m));
  }
  Search search(cols, robot);
  const double step_yaw = 2 * kPi / kHeadings;
  const double to_goal = std::atan2(goal.y() - start.y(), goal.x() - start.x());
  const int k0 = ((static_cast<int>(std::lround(to_goal / step_yaw)) % kHeadings) + kHeadings) % kHeadings;
  const auto headingsAround = [&](int k) {
    std::vector<int> hs;
    for (const int d : {0, 1, -1, 2, -2, 3, -3, 4, -4}) hs.push_back(((k + d) % kHeadings + kHeadings) % kHeadings);
    return hs;
  };

  // The goal must carry a sole.
  {
    State g;
    const std::vector<int> all = headingsAround(k0);
    if (!search.nearestStandable(goal.x(), goal.y(), *z_goal, params.goal_tolerance_m, all, g)) {
      const auto [gx, gy] = search.latticeKey(goal.x(), goal.y());
      Foothold f = evaluateFoothold(cols, cols.centreOf(gx), cols.centreOf(gy), headingYaw(k0), *z_goal, robot);
      return finish(format("the goal (%.2f, %.2f, %.2f) cannot be stood on: ", goal.x(), goal.y(), goal.z()) + describeProblem(f, robot));
    }
  }
  // The start stance: a left and a right sole either side of the start point, facing the goal.
  const double c0 = std::cos(headingYaw(k0)), s0 = std::sin(headingYaw(k0));
  const double half = 0.5 * robot.stance_width_m;
  State left, right;
  left.side = Side::kLeft, right.side = Side::kRight;
  const std::vector<int> near_k0 = headingsAround(k0);
  const bool have_left = search.nearestStandable(start.x() - s0 * half, start.y() + c0 * half, *z_start, params.start_radius_m, near_k0, left);
  const bool have_right = search.nearestStandable(start.x() + s0 * half, start.y() - c0 * half, *z_start, params.start_radius_m, near_k0, right);
  if (!have_left || !have_right) {
    const auto [sx, sy] = search.latticeKey(start.x(), start.y());
    Foothold f = evaluateFoothold(cols, cols.centreOf(sx), cols.centreOf(sy), headingYaw(k0), *z_start, robot);
    return finish(format("the robot cannot stand at the start (%.2f, %.2f, %.2f): no place for its ", start.x(), start.y(), start.z()) +
                  std::string(have_left ? "right" : "left") + format(" sole within %.2f m", params.start_radius_m) +
                  (f.standable() ? std::string() : ": " + describeProblem(f, robot)));
  }

  const auto footstepOf = [&](const State& st) {
    const Foothold& f = search.foothold(st.run, st.heading);
    Footstep fs;
    fs.side = st.side;
    std::tie(fs.x, fs.y) = search.centre(st.run);
    fs.z = f.z, fs.yaw = headingYaw(st.heading), fs.min_mobility = f.min_mobility, fs.tilt_deg = f.tilt_deg;
    fs.mean_mobility = f.mean_mobility, fs.poor_fraction = f.poor_fraction;
    if (fs.yaw > kPi) fs.yaw -= 2 * kPi;
    return fs;
  };
  // A step costs at least hypot(stride, rise) + step_cost_m * stride / max_stride_m, so
  // footsteps to the goal at least hypot(M, Z) + step_cost_m / max_stride_m * M for M at
  // most their strides' sum and Z at most their rises' sum. M: the straight line to the
  // goal, and once the search proves long (PlanParams::map_bound_after) the way around
  // what no swing passes and up only where soles can stand (detail::SurfaceBound), the
  // larger; Z: the height to the goal's level. A step lowers M by at most its stride and
  // Z by at most its rise: consistent.
  const double per_stride = params.step_cost_m / robot.max_stride_m;
  const double goal_slack = kLevelSlack + robot.max_unevenness_m;  // atGoal()'s
  const double sole_off_top = detail::soleOffTop(robot, res);
  std::optional<detail::SurfaceBound> bound;
  const auto heuristic = [&](const State& st) {
    RunRecord& rec = search.record(st.run);
    const std::uint8_t generation = bound ? 2 : 1;
    if (rec.metres_of != generation) {
      rec.metres = std::max(0.0, std::hypot(goal.x() - rec.x, goal.y() - rec.y) - params.goal_tolerance_m);
      if (bound) rec.metres = std::max(rec.metres, bound->metres(st.run));
      rec.metres_of = generation;
    }
    const double metres = rec.metres;
    // The sole's height if judged, else as low a bound as its surface's top allows.
    const Foothold* sole = search.judged(rec, st.heading);
    const double z = sole ? sole->z : cols.topFace(cols.runs()[st.run]);
    const double rise = std::max(0.0, std::abs(z - *z_goal) - goal_slack - (sole ? 0.0 : sole_off_top));
    return params.heuristic_weight * (std::hypot(metres, rise) + per_stride * metres);
  };
  const auto stepCost = [&](double stride, const Foothold& from, const Foothold& to) {
    return std::hypot(stride, to.z - from.z) + params.step_cost_m + params.mobility_weight_m * (1.0 - to.min_mobility) +
           params.variance_weight_m * to.mean_variance;
  };
  const auto atGoal = [&](const State& st) {
    const auto [x, y] = search.centre(st.run);
    return std::hypot(goal.x() - x, goal.y() - y) <= params.goal_tolerance_m + 1e-9 &&
           std::abs(search.foothold(st.run, st.heading).z - *z_goal) <= kLevelSlack + robot.max_unevenness_m;
  };
  constexpr std::uint64_t kNoParent = std::numeric_limits<std::uint64_t>::max();
  // Soles are judged lazily. A step to a state whose sole is judged is judged at once
  // (its cost, its swing); a step to a state whose sole is not judged yet puts the state
  // in the open list at a lower bound of the step's cost (stride and step cost: the other
  // terms are >= 0). When such an entry comes to the top, the state is judged and pulls
  // its cost from every expanded state that steps to it. Most soles the search looks at
  // are never judged, and the open list holds one waiting entry per state, not one per step.
  // Equal f: the deeper entry first (larger g), which keeps A* from widening over the
  // lattice's many paths of equal cost.
  struct Item {
    double f, neg_g;
    std::uint64_t key;
    bool waiting;  ///< the state waits to be judged (g is a lower bound)
    bool operator>(const Item& o) const { return std::tie(f, neg_g, key, waiting) > std::tie(o.f, o.neg_g, o.key, o.waiting); }
  };
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> open;
  // Either foot may step first: each start sole is a root, the other foot standing beside it.
  const auto root_of = [&](const State& stance) {
    Node& n = search.node(stance);
    n = Node{};
    n.g = 0.0, n.parent = kNoParent, n.pulled = true;
    open.push({heuristic(stance), 0.0, stance.key(), false});
  };
  root_of(left);
  root_of(right);
  const double slack = robot.max_step_m + robot.max_unevenness_m + res;  // of a step's rise, at a glance
  // The state `to` (its sole judged here) takes the cheapest step from the expanded states.
  const auto pull = [&](const State& to, RunRecord& to_rec, Node& to_node) {
    to_node.pulled = true;
    const Foothold& f = search.foothold(to.run, to_rec, to.heading);
    if (!f.standable()) return;
    const auto [kx, ky] = search.latticeKey(to_rec.x, to_rec.y);
    const double top = cols.topFace(cols.runs()[to.run]);
    const std::size_t side_index = to.side == Side::kLeft ? 0 : 1;
    const std::size_t from_side = 1 - side_index;
    bool improved = false;
    for (int dk = -1; dk <= 1; ++dk) {
      const int kq = ((to.heading - dk) % kHeadings + kHeadings) % kHeadings;
      for (const Move& m : search.moves_[static_cast<std::size_t>(kq)][side_index]) {
        if (m.overlaps[static_cast<std::size_t>(dk + 1)]) continue;
        const long col = cols.columnIndex(kx - m.di * search.s_, ky - m.dj * search.s_);
        for (std::size_t r = cols.runBegin(col); r < cols.runEnd(col); ++r) {
          RunRecord* from_rec = search.touched(r);
          if (!from_rec) continue;
          const Node& from_node = from_rec->nodes[static_cast<std::size_t>(kq) * 2 + from_side];
          if (!from_node.closed) continue;
          const Foothold& from = search.foothold(r, *from_rec, kq);
          if (std::abs(top - from.z) > slack || !stepHeightOk(from.z, f.z, robot, res)) continue;
          const double stride = std::hypot(to_rec.x - from_rec->x, to_rec.y - from_rec->y);
          if (stride > robot.max_stride_m + 1e-9) continue;
          const double g_to = from_node.g + stepCost(stride, from, f);
          if (g_to >= to_node.g) continue;
          if (swingProblem(cols, from_rec->x, from_rec->y, from.z, to_rec.x, to_rec.y, f.z, robot) != FootholdProblem::kNone) continue;
          to_node.g = g_to;
          to_node.parent = State{r, kq, to.side == Side::kLeft ? Side::kRight : Side::kLeft}.key();
          improved = true;
        }
      }
    }
    if (improved) open.push({to_node.g + heuristic(to), -to_node.g, to.key(), false});
  };
  std::optional<std::uint64_t> goal_key;
  bool expansions_spent = false;
  // A goal the robot cannot get to at all would have the search expand every state it
  // can reach (seconds). After 2,048 expansions and at each doubling up to 16,384 a look
  // back from the goal (lookBackFeet) settles such cases (a goal on a ledge or a stair
  // cut off from the rest, a room without a door) or meets the search. Whole-map
  // reachability is used when a cache keeps it for this start; it is worked out only to
  // say why a search that has run out found nothing (on a building of 40 x 40 m it
  // takes tens of seconds).
  std::shared_ptr<const Reachability> reach;
  std::vector<std::size_t> goal_feet;
  const ReachParams reach_params = reachParamsOf(params);
  // False when the time ran out first.
  const auto checkReach = [&] {
    if (reach) return true;
    try {
      reach = cache ? cache->reachability(columns, start, reach_params, limited)
                    : std::make_shared<const Reachability>(computeReachability(columns, start, reach_params, limited));
    } catch (const BudgetExceeded&) {
      budget.check("planFootsteps");  // the caller's budget: its exception
      return false;                   // the time limit
    }
    goal_feet = goalFeet(*reach, goal, *z_goal, params);
    return true;
  };
  if (cache) {
    reach = cache->findReachability(columns, start, reach_params);
    if (reach) goal_feet = goalFeet(*reach, goal, *z_goal, params);
  }
  Verdict verdict = reach ? (goalReachable(*reach, goal_feet) ? Verdict::kReachable : Verdict::kUnreachable) : Verdict::kUnknown;
  std::optional<LazyFeet> lazy;
  const auto reachedFromStart = [&](std::size_t run) {
    const RunRecord* rec = search.touched(run);
    return rec && std::any_of(rec->nodes.begin(), rec->nodes.end(), [](const Node& n) { return n.closed; });
  };
  if (verdict == Verdict::kUnreachable) {
    // The easiest way there, looked for from the goal (the whole-map search floods all
    // the start's level first).
    lazy.emplace(cols, robot);
    if (auto why = diagnoseFromGoal(*lazy, cols, start, goal, *z_goal, params, kDiagnoseFeet)) return finish(std::move(*why));
    return finish(diagnose(cols, *reach, goal_feet, params));
  }
  const auto outOfTime = [&] {
    plan.time_limit_reached = plan.expansions < params.max_expansions;
    return finish(format("no plan within the limits (%.1f s, ", params.time_limit_s) + std::to_string(plan.expansions) +
                  " states expanded); raise `time_limit_s`, or `heuristic_weight` to search faster for a costlier plan");
  };
  // The map-aware bound, worked out once: nullopt to go on searching, else the answer (a
  // goal the bound shows cut off, or the time limit).
  const auto addMapBound = [&]() -> std::optional<Plan> {
    if (!detail::SurfaceBound::handles(search.s_)) return std::nullopt;
    try {
      bound.emplace(cols, robot, search.s_, goal, *z_goal, params.goal_tolerance_m, kLevelSlack + robot.max_unevenness_m,
                    std::vector<std::size_t>{left.run, right.run}, kBoundBeyond, limited);
    } catch (const BudgetExceeded&) {
      budget.check("planFootsteps");
      return outOfTime();
    }
    if (bound->startCutOff()) {
      // No footstep sequence joins the start and the goal: why.
      if (!lazy) lazy.emplace(cols, robot);
      if (auto why = diagnoseFromGoal(*lazy, cols, start, goal, *z_goal, params, kDiagnoseFeet)) return finish(std::move(*why));
      if (!checkReach()) return outOfTime();
      return finish(diagnose(cols, *reach, goal_feet, params));
    }
    // The open list again under the larger heuristic (still consistent: the states
    // closed so far keep their costs).
    std::vector<Item> items;
    items.reserve(open.size());
    for (; !open.empty(); open.pop()) items.push_back(open.top());
    for (Item& it : items) it.f = -it.neg_g + heuristic(State::fromKey(it.key));
    open = decltype(open)(std::greater<Item>(), std::move(items));
    return std::nullopt;
  };
  if (params.map_bound_after == 0) {
    if (auto answer = addMapBound()) return std::move(*answer);
  }
  while (!open.empty()) {
    // Plain variables, not structured bindings: the lambda below captures them (C++17
    // does not let a lambda capture a structured binding; clang refuses it).
    const Item item = open.top();
    open.pop();
    const std::uint64_t key = item.key;
    const State st = State::fromKey(key);
    RunRecord& rec = search.record(st.run);
    Node& node = rec.nodes[static_cast<std::size_t>(st.heading * 2 + (st.side == Side::kRight ? 1 : 0))];
    if (node.closed) continue;
    if (item.waiting) {
      if (!node.pulled) pull(st, rec, node);
      continue;
    }
    if (-item.neg_g != node.g) continue;  // superseded by a cheaper way here
    node.closed = true;
    const double g = node.g;
    if (atGoal(st)) {
      goal_key = key;
      break;
    }
    // The limits, at the first expansion and every 256th after.
    if ((plan.expansions & 255u) == 0) {
      budget.check("planFootsteps");
      if (elapsed() > params.time_limit_s) return outOfTime();
    }
    if (++plan.expansions >= params.max_expansions) {
      expansions_spent = true;
      break;
    }
    if (plan.expansions == params.map_bound_after) {
      if (auto answer = addMapBound()) return std::move(*answer);
    }
    if (lookBackFeet(plan.expansions) && verdict == Verdict::kUnknown) {
      if (!lazy) lazy.emplace(cols, robot);
      verdict = lookBackFromGoal(*lazy, cols, start, goal, *z_goal, params, lookBackFeet(plan.expansions), reachedFromStart);
      if (verdict == Verdict::kUnreachable) {
        if (auto why = diagnoseFromGoal(*lazy, cols, start, goal, *z_goal, params, kDiagnoseFeet)) return finish(std::move(*why));
        break;  // diagnosed below, over the whole map
      }
    }
    const Foothold& from = search.foothold(st.run, rec, st.heading);
    const double x = rec.x, y = rec.y;
    const auto lattice = search.latticeKey(x, y);
    const long kx = lattice.first, ky = lattice.second;
    const Side next = st.side == Side::kLeft ? Side::kRight : Side::kLeft;
    const int side_index = next == Side::kLeft ? 0 : 1;
    for (const Move& m : search.moves_[static_cast<std::size_t>(st.heading)][static_cast<std::size_t>(side_index)]) {
      const long nkx = kx + m.di * search.s_, nky = ky + m.dj * search.s_;
      const long col = cols.columnIndex(nkx, nky);
      if (cols.runBegin(col) == cols.runEnd(col)) continue;
      const double nx = cols.centreOf(nkx), ny = cols.centreOf(nky);
      const double stride = std::hypot(nx - x, ny - y);
      if (stride > robot.max_stride_m + 1e-9) continue;
      search.runsNear(nkx, nky, from.z, slack, [&](std::size_t run) {
        RunRecord& to_rec = search.record(run);
        for (int dk = -1; dk <= 1; ++dk) {
          if (m.overlaps[static_cast<std::size_t>(dk + 1)]) continue;
          const int k = ((st.heading + dk) % kHeadings + kHeadings) % kHeadings;
          const State to{run, k, next};
          Node& to_node = to_rec.nodes[static_cast<std::size_t>(k * 2 + side_index)];
          if (to_node.closed) continue;
          const Foothold* f = search.judged(to_rec, k);
          if (!f) {
            // Not judged yet: the state waits (once, at its lowest bound) to be judged.
            const double g_bound = g + stride + params.step_cost_m;
            if (g_bound >= to_node.g || g_bound >= to_node.bound) continue;
            to_node.bound = g_bound;
            open.push({g_bound + heuristic(to), -g_bound, to.key(), true});
            continue;
          }
          if (!f->standable() || !stepHeightOk(from.z, f->z, robot, res)) continue;
          const double g_to = g + stepCost(stride, from, *f);
          if (g_to >= to_node.g) continue;
          if (swingProblem(cols, x, y, from.z, nx, ny, f->z, robot) != FootholdProblem::kNone) continue;
          to_node.g = g_to, to_node.parent = key;
          open.push({g_to + heuristic(to), -g_to, to.key(), false});
        }
      });
    }
  }
  if (!goal_key) {
    if (expansions_spent || !checkReach()) return outOfTime();
    return finish(diagnose(cols, *reach, goal_feet, params));
  }
  // The footsteps: the other start sole, then the chain from the root.
  std::vector<State> chain;
  for (std::uint64_t k = *goal_key; k != kNoParent; k = search.node(State::fromKey(k)).parent) chain.push_back(State::fromKey(k));
  std::reverse(chain.begin(), chain.end());
  plan.footsteps.push_back(footstepOf(chain.front().side == Side::kLeft ? right : left));
  for (const State& st : chain) plan.footsteps.push_back(footstepOf(st));
  plan.cost = search.node(State::fromKey(*goal_key)).g;
  // Square up at the goal: the other foot beside the last one, if it can stand there.
  {
    const State& last = chain.back();
    const Footstep lf = footstepOf(last);
    const double t = headingYaw(last.heading);
    const double sgn = last.side == Side::kLeft ? -1.0 : 1.0;  // the other foot's side
    const auto [kx, ky] = search.latticeKey(lf.x - std::sin(t) * sgn * robot.stance_width_m, lf.y + std::cos(t) * sgn * robot.stance_width_m);
    const double nx = cols.centreOf(kx), ny = cols.centreOf(ky);
    bool placed = false;
    search.runsNear(kx, ky, lf.z, robot.max_step_m, [&](std::size_t run) {
      if (placed) return;
      const Foothold& f = search.foothold(run, last.heading);
      if (!f.standable() || !stepHeightOk(lf.z, f.z, robot, res) ||
          solesOverlap(lf.x, lf.y, t, nx, ny, t, robot.sole_length_m, robot.sole_width_m) ||
          swingProblem(cols, lf.x, lf.y, lf.z, nx, ny, f.z, robot) != FootholdProblem::kNone) {
        return;
      }
      placed = true;
      plan.footsteps.push_back(footstepOf(State{run, last.heading, last.side == Side::kLeft ? Side::kRight : Side::kLeft}));
    });
  }
  for (std::size_t i = 1; i < plan.footsteps.size(); ++i) {
    const Footstep& a = plan.footsteps[i - 1];
    const Footstep& b = plan.footsteps[i];
    plan.length_m += std::hypot(std::hypot(b.x - a.x, b.y - a.y), b.z - a.z);
    plan.max_step_height_m = std::max(plan.max_step_height_m, std::abs(b.z - a.z));
  }
  plan.found = true;
  plan.planning_time_s = elapsed();
  return plan;
}

}  // namespace
}  // namespace mobmap::mapping
