#pragma once
/// @file footstep_planner.hpp
/// A reference footstep planner: alternating left and right footsteps from a start stance
/// to a goal over the soles and steps of footholds.hpp, found by weighted A* with an
/// admissible heuristic (PlanParams::heuristic_weight 1: the cheapest plan for the cost
/// below on the lattice of sole centres and headings).

#include "mobmap/mapping/budget.hpp"
#include "mobmap/mapping/footholds.hpp"
#include "mobmap/mapping/mobility_octree.hpp"
#include "mobmap/mapping/reachability.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace mobmap::mapping {

/// What the planner optimises and how long it may take, units in the names. A step's
/// cost is its length (3D, between successive sole centres) + step_cost_m +
/// mobility_weight_m * (1 - the new sole's lowest mobility) + variance_weight_m * its
/// mean mobility variance, all in metres of walking.
struct PlanParams {
  RobotParams robot;
  double goal_tolerance_m = 0.1;  ///< a footstep whose centre lies this close to the goal (horizontally) ends the plan
  double step_cost_m = 0.1;
  double mobility_weight_m = 0.5;
  double variance_weight_m = 1.0;
  /// The start stance: soles are looked for this far around the positions of a square
  /// stance (stance_width_m apart, facing the goal) at the start point.
  double start_radius_m = 0.3;
  /// f = g + heuristic_weight * h. The heuristic is admissible: 1 finds the cheapest plan
  /// on the lattice; w > 1 finds a plan at most w times as costly as that, much faster.
  /// On the corridor's 7-10 m plans 1.25 expanded 18-140 times fewer states than 1, for
  /// plans 3-6 % costlier (docs/PERFORMANCE.md, "Footstep planning").
  double heuristic_weight = 1.25;
  double time_limit_s = 10.0;            ///< then the search gives up (found = false, with the reason)
  std::size_t max_expansions = 5000000;  ///< likewise
  /// After this many expansions the search adds a bound that knows the map to its
  /// heuristic (a lower bound on the walk around walls and drops, up only where soles
  /// can stand; docs/MAPPING.md, "Footstep planning"), and a goal it shows cut off is
  /// refused then. 0: from the start. Working it out costs about as much as a few
  /// thousand expansions on a 12 m corridor, so the default leaves short plans without it.
  std::size_t map_bound_after = 4096;
};

/// std::invalid_argument naming the field.
void validate(const PlanParams& params);

/// PlanParams' numbers by name: the robot's (setRobotParameter) and the search's
/// (goal_tolerance_m, step_cost_m, mobility_weight_m, variance_weight_m, start_radius_m,
/// heuristic_weight, time_limit_s, max_expansions, map_bound_after). False for a name
/// that is none of them; std::invalid_argument for a max_expansions that is not a whole
/// number >= 1 or a map_bound_after that is not one >= 0. The
/// rest is checked by validate().
bool setPlanParameter(PlanParams& params, const std::string& name, double value);
/// The names setPlanParameter() takes: the robot's, then the search's.
const std::vector<std::string>& planParameterNames();

enum class Side { kLeft, kRight };
const char* toString(Side side);

/// One footstep: the sole's centre on its support and its heading (map frame).
struct Footstep {
  Side side = Side::kLeft;
  double x = 0, y = 0, z = 0, yaw = 0;
  double min_mobility = 0;   ///< lowest mobility under the sole
  /// What the standability rule checks: the mean mobility under the sole and the share
  /// of it under RobotParams::min_mobility (at most max_poor_fraction).
  double mean_mobility = 0;
  double poor_fraction = 0;
  double tilt_deg = 0;       ///< of its support plane
};

/// The planner's answer.
struct Plan {
  bool found = false;
  /// Why there is no plan, in words a person can act on (empty when found).
  std::string reason;
  /// The start stance (two soles), then one footstep after another, alternating feet,
  /// the last two side by side at the goal when they fit there.
  std::vector<Footstep> footsteps;
  double cost = 0;              ///< sum of the steps' costs (PlanParams)
  double length_m = 0;          ///< sum of the distances between successive footsteps
  double max_step_height_m = 0; ///< largest height difference between successive footsteps
  std::size_t expansions = 0;   ///< states expanded by the search
  double planning_time_s = 0;
  /// PlanParams::time_limit_s ended the call before a plan was found (found = false).
  bool time_limit_reached = false;
};

/// The start or goal lies where no surface is (outside the map, in free or unknown space):
/// the message names which and where.
class PlanInputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Plans from `start_map` (a point on or above the surface the robot stands on) to
/// `goal_map` (likewise), map frame. No plan (the goal cannot be stood on, a step is too
/// high, params.time_limit_s): found = false and the reason. The time limit bounds the
/// whole call, the map's columns and the reachability worked out for a goal that seems
/// out of reach included. std::invalid_argument for invalid params or a non-finite point;
/// PlanInputError when no surface lies within 2 m below the start or the goal;
/// std::length_error for a map too large (SurfaceColumns); BudgetExceeded when the
/// caller's `budget` runs out (or is stopped) first.
[[nodiscard]] Plan planFootsteps(const MobilityOcTree& tree, const Eigen::Vector3d& start_map,
                                 const Eigen::Vector3d& goal_map, const PlanParams& params = {},
                                 const Budget& budget = {});
/// The same over columns already made from the map. With a `cache`, whole-map
/// reachability from the start (the check of a goal that may be out of reach) is taken
/// from it when kept there, and kept there when worked out: a caller that plans to
/// several goals, or again on the same map snapshot, pays for it once.
[[nodiscard]] Plan planFootsteps(std::shared_ptr<const SurfaceColumns> columns, const Eigen::Vector3d& start_map,
                                 const Eigen::Vector3d& goal_map, const PlanParams& params = {},
                                 const Budget& budget = {}, ReachCache* cache = nullptr);

}  // namespace mobmap::mapping
