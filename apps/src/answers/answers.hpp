#pragma once
// The answers of `mobmap query`, `query --foot`, `plan` and `info` as JSON: one function
// each, shared by the commands' --json output and `mobmap serve`, so that both say the
// same thing byte for byte.

#include "mobmap/mapping/levels.hpp"

#include "mobmap/mapping/footstep_planner.hpp"
#include "mobmap/mapping/map_metadata.hpp"
#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/mapping/reachability.hpp"

#include <nlohmann/json.hpp>

#include <Eigen/Core>

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace mobmap::app {

/// The frame a request's coordinates are in.
enum class InputFrame { kMap, kWorld };

/// A point's answer: the voxel at it, or (with a snap distance) the surface found within
/// that distance below it, and with a reachability run the place under it.
struct PointAnswer {
  Eigen::Vector3d query_map = Eigen::Vector3d::Zero();  ///< the point, map frame
  std::optional<mapping::PointQuery> voxel;             ///< empty: no surface within the snap distance
  double snap_m = -1;                                   ///< < 0: the voxel at the point, no search
  bool with_reach = false;
  const mapping::Place* place = nullptr;  ///< with_reach: the place under the point, if any
  double reach_drop_m = 0;                ///< how far below the point a place was looked for
  bool outside_map = false;               ///< beyond every voxel the map can hold (PointQuery::outside_map)
};
/// `reach` may be null (no reach answer). `p` must be finite.
PointAnswer answerPoint(const mapping::MobilityMap& map, const Eigen::Vector3d& p, InputFrame frame, double snap_m,
                        const mapping::Reachability* reach);
/// The JSON object `mobmap query --json` prints for it.
nlohmann::json toJson(const PointAnswer& a);

/// A sole's answer: what lies under it, and with a reachability run whether the robot can
/// stand there and get there.
struct FootAnswer {
  std::array<double, 6> sole{};  ///< as given: x y z yaw length width
  mapping::FootprintQuery footprint;
  Eigen::Vector3d support_point = Eigen::Vector3d::Zero();   ///< under the sole's centre, in the frame given
  Eigen::Vector3d support_normal = Eigen::Vector3d::UnitZ();  ///< in the frame given
  std::optional<mapping::SoleReach> reach;
};
/// std::invalid_argument "LENGTH and WIDTH must be in (0, 10] m" unless both are
/// (mapping::kMaxSoleSideM).
void checkSoleSize(double length_m, double width_m);
/// std::invalid_argument "LENGTH and WIDTH must be in (0, 10] m" for a sole of no size or
/// a larger one; the values must be finite. `snap_m` < 0: search 0.1 m below the sole.
FootAnswer answerFoot(const mapping::MobilityMap& map, const std::array<double, 6>& sole, InputFrame frame, double snap_m,
                      const mapping::Reachability* reach);
/// The JSON object `mobmap query --foot ... --json` prints for it.
nlohmann::json toJson(const FootAnswer& a);

/// A footstep in the frame the plan was asked in: the sole's centre and heading.
struct FootstepIn {
  Eigen::Vector3d centre;
  double yaw = 0;
};
FootstepIn footstepIn(const mapping::MobilityMap& map, const mapping::Footstep& f, InputFrame frame);
/// The JSON object `mobmap plan --json` prints.
nlohmann::json planJson(const mapping::MobilityMap& map, const mapping::Plan& plan, const mapping::PlanParams& params,
                        InputFrame frame);

/// The leaves of a map by kind, and the surface voxels' mobility in ten bins of 0.1.
struct LeafCounts {
  std::size_t surface = 0, free = 0, surface_without_mobility = 0;
  std::vector<std::size_t> histogram = std::vector<std::size_t>(10, 0);
};
LeafCounts countLeaves(const mapping::MobilityOcTree& tree);

using mapping::gatherLevels;
using mapping::Level;

/// Heights where walkable surfaces (mapping::walkableBins) gather: floors, landings, table
/// tops. In height order; a level holds at least 0.5 % of them (docs/MAPPING.md).
std::vector<Level> walkableLevels(const mapping::MobilityOcTree& tree);

/// The JSON object `mobmap info --json` prints: `map_label` is the "map" field, and the
/// metadata (null when `metadata` is null or not found) goes in whole.
nlohmann::json infoJson(const std::string& map_label, const mapping::MobilityMap& map,
                        const mapping::MapMetadata* metadata);

}  // namespace mobmap::app
