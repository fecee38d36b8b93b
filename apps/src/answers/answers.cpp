#include "answers/answers.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

namespace mobmap::app {
namespace {

nlohmann::json voxelJson(const mapping::PointQuery& q) {
  nlohmann::json j{{"state", mapping::toString(q.state)},
                   {"voxel_centre", {q.centre.x(), q.centre.y(), q.centre.z()}},
                   {"voxel_size_m", q.size_m},
                   {"count", q.count},
                   {"occupancy", q.occupancy}};
  j["mobility"] = q.has_mobility ? nlohmann::json(q.mobility) : nlohmann::json(nullptr);
  j["variance"] = q.has_mobility ? nlohmann::json(q.variance) : nlohmann::json(nullptr);
  return j;
}

// A place's own facts: its mobility (null if unknown) and the free or unseen height
// above it (null: nothing above it in the map).
nlohmann::json placeJson(const mapping::Place* p) {
  if (!p) return {{"place", nullptr}, {"standable", false}, {"reachable", false}};
  return {{"place", {p->x, p->y, p->top_z}},
          {"standable", p->standable},
          {"reachable", p->reachable},
          {"mobility", p->has_mobility ? nlohmann::json(p->mobility) : nlohmann::json(nullptr)},
          {"headroom_m", std::isfinite(p->headroom_m) ? nlohmann::json(p->headroom_m) : nlohmann::json(nullptr)}};
}

nlohmann::json soleReachJson(const mapping::SoleReach& r) {
  const mapping::Foothold& f = r.foothold;
  nlohmann::json j{{"standable", r.standable},
                   {"reachable", r.reachable},
                   {"support_fraction", f.support_fraction},
                   {"min_mobility", f.min_mobility},
                   {"tilt_deg", f.tilt_deg},
                   {"unevenness_m", f.unevenness_m}};
  j["support_z"] = f.has_plane ? nlohmann::json(f.z) : nlohmann::json(nullptr);
  j["problem"] = r.standable ? nlohmann::json(nullptr) : nlohmann::json(mapping::toString(f.problem));
  return j;
}

}  // namespace

PointAnswer answerPoint(const mapping::MobilityMap& map, const Eigen::Vector3d& p, InputFrame frame, double snap_m,
                        const mapping::Reachability* reach) {
  PointAnswer a;
  a.query_map = frame == InputFrame::kWorld ? map.worldToMap(p) : p;
  a.snap_m = snap_m;
  a.outside_map = map.query(a.query_map).outside_map;
  if (snap_m >= 0) {
    a.voxel = map.snapDown(a.query_map, snap_m);
  } else {
    a.voxel = map.query(a.query_map);
  }
  if (reach) {
    a.with_reach = true;
    a.reach_drop_m = snap_m >= 0 ? snap_m : map.tree().getResolution();
    a.place = reach->placeBelow(a.query_map, a.reach_drop_m);
  }
  return a;
}

nlohmann::json toJson(const PointAnswer& a) {
  nlohmann::json j = a.voxel ? voxelJson(*a.voxel) : nlohmann::json{{"state", "no surface within snap distance"}};
  j["query"] = {a.query_map.x(), a.query_map.y(), a.query_map.z()};
  j["outside_map"] = a.outside_map;
  if (a.with_reach) j["reach"] = placeJson(a.place);
  return j;
}

void checkSoleSize(double length_m, double width_m) {
  if (!mapping::soleSizeAllowed(length_m, width_m)) {
    throw std::invalid_argument("LENGTH and WIDTH must be in (0, 10] m");
  }
}

FootAnswer answerFoot(const mapping::MobilityMap& map, const std::array<double, 6>& s, InputFrame frame, double snap_m,
                      const mapping::Reachability* reach) {
  checkSoleSize(s[4], s[5]);
  const bool world = frame == InputFrame::kWorld;
  const Eigen::Vector3d c = world ? map.worldToMap(Eigen::Vector3d(s[0], s[1], s[2])) : Eigen::Vector3d(s[0], s[1], s[2]);
  const double yaw = world ? map.worldYawToMap(s[3]) : s[3];  // the heading turns with the frame
  const mapping::Foot sole{c.x(), c.y(), c.z(), yaw, s[4], s[5]};
  const double down = snap_m >= 0 ? snap_m : 0.1;
  FootAnswer a;
  a.sole = s;
  a.footprint = map.footprint(sole, 0.1, down);
  if (reach) a.reach = reach->sole(sole, 0.1, down);
  // The support plane's point under the sole's centre and its normal, in the frame given.
  const Eigen::Vector3d under(c.x(), c.y(), a.footprint.support_height_m);
  a.support_point = world ? map.mapToWorld(under) : under;
  a.support_normal = world ? Eigen::Vector3d(map.rotationMapWorld().transpose() * a.footprint.support_normal)
                           : a.footprint.support_normal;
  return a;
}

nlohmann::json toJson(const FootAnswer& a) {
  const mapping::FootprintQuery& f = a.footprint;
  nlohmann::json j{{"foot", a.sole},
                   {"min_mobility", f.min_mobility},
                   {"mean_mobility", f.mean_mobility},
                   {"known_fraction", f.known_fraction},
                   {"max_height_difference_m", f.max_height_difference_m},
                   {"samples", f.samples}};
  const Eigen::Vector3d& p = a.support_point;
  const Eigen::Vector3d& n = a.support_normal;
  j["support_plane"] = f.has_support_plane ? nlohmann::json{{"point", {p.x(), p.y(), p.z()}},
                                                            {"normal", {n.x(), n.y(), n.z()}},
                                                            {"tilt_deg", f.support_tilt_deg},
                                                            {"rms_m", f.support_rms_m}}
                                           : nlohmann::json();
  if (a.reach) j["reach"] = soleReachJson(*a.reach);
  return j;
}

FootstepIn footstepIn(const mapping::MobilityMap& map, const mapping::Footstep& f, InputFrame frame) {
  if (frame == InputFrame::kMap) return {Eigen::Vector3d(f.x, f.y, f.z), f.yaw};
  return {map.mapToWorld(Eigen::Vector3d(f.x, f.y, f.z)), map.mapYawToWorld(f.yaw)};
}

nlohmann::json planJson(const mapping::MobilityMap& map, const mapping::Plan& plan, const mapping::PlanParams& params,
                        InputFrame frame) {
  nlohmann::json j{{"found", plan.found}, {"frame", frame == InputFrame::kWorld ? "world" : "map"}};
  if (!plan.found) j["reason"] = plan.reason;
  j["time_limit_reached"] = plan.time_limit_reached;
  j["footsteps"] = nlohmann::json::array();
  for (const auto& f : plan.footsteps) {
    const FootstepIn s = footstepIn(map, f, frame);
    j["footsteps"].push_back({{"foot", mapping::toString(f.side)},
                              {"x", s.centre.x()},
                              {"y", s.centre.y()},
                              {"z", s.centre.z()},
                              {"yaw", s.yaw},
                              {"min_mobility", f.min_mobility},
                              {"mean_mobility", f.mean_mobility},
                              {"poor_fraction", f.poor_fraction},
                              {"tilt_deg", f.tilt_deg}});
  }
  j["steps"] = plan.footsteps.size() >= 2 ? plan.footsteps.size() - 2 : 0;
  j["cost"] = plan.cost;
  j["length_m"] = plan.length_m;
  j["max_step_height_m"] = plan.max_step_height_m;
  j["expansions"] = plan.expansions;
  j["cost_bound"] = params.heuristic_weight;  // the plan costs at most this times the cheapest
  j["planning_time_s"] = plan.planning_time_s;
  const auto& r = params.robot;
  j["robot"] = {{"sole_length_m", r.sole_length_m},         {"sole_width_m", r.sole_width_m},
                {"max_step_m", r.max_step_m},               {"min_mobility", r.min_mobility},
                {"max_stride_m", r.max_stride_m},           {"max_tilt_deg", r.max_tilt_deg},
                {"swing_clearance_m", r.swing_clearance_m}, {"stance_width_m", r.stance_width_m}};
  return j;
}

LeafCounts countLeaves(const mapping::MobilityOcTree& t) {
  LeafCounts c;
  for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) {
    if (!t.isNodeOccupied(*it)) {
      ++c.free;
      continue;
    }
    ++c.surface;
    if (!it->hasMobility()) {
      ++c.surface_without_mobility;
      continue;
    }
    ++c.histogram[static_cast<std::size_t>(std::clamp(static_cast<int>(it->mobility() * 10), 0, 9))];
  }
  return c;
}

namespace {
// A walkable level holds at least this share of the walkable voxels (docs/MAPPING.md).
constexpr double kMinLevelShare = 0.005;
}  // namespace

std::vector<Level> walkableLevels(const mapping::MobilityOcTree& t) {
  // Every level, however many: a staircase of 7 treads has 8.
  std::vector<Level> levels = gatherLevels(mapping::walkableBins(mapping::SurfaceColumns(t)), t.getResolution(),
                                           std::numeric_limits<std::size_t>::max(), kMinLevelShare);
  std::sort(levels.begin(), levels.end(), [](const Level& a, const Level& b) { return a.z_m < b.z_m; });
  return levels;
}

nlohmann::json infoJson(const std::string& map_label, const mapping::MobilityMap& map, const mapping::MapMetadata* metadata) {
  const auto& t = map.tree();
  const LeafCounts c = countLeaves(t);
  nlohmann::json j{{"map", map_label},
                   {"tree_type", t.getTreeType()},
                   {"resolution_m", t.getResolution()},
                   {"nodes", t.size()},
                   {"leaves", t.getNumLeafNodes()},
                   {"surface_leaves", c.surface},
                   {"free_leaves", c.free},
                   {"surface_leaves_without_mobility", c.surface_without_mobility},
                   {"mobility_histogram", c.histogram},
                   {"memory_bytes", t.memoryUsage()}};
  j["walkable_levels"] = nlohmann::json::array();
  for (const Level& l : walkableLevels(t)) {
    j["walkable_levels"].push_back({{"z_m", l.z_m}, {"voxels", l.count}, {"share", l.share}});
  }
  // An empty tree has no bounds (OctoMap reports its key range's limits).
  if (c.surface + c.free > 0) {
    double x0, y0, z0, x1, y1, z1;
    t.getMetricMin(x0, y0, z0);
    t.getMetricMax(x1, y1, z1);
    j["bounds_map"] = {{"min", {x0, y0, z0}}, {"max", {x1, y1, z1}}};
  }
  j["metadata"] = metadata && metadata->found ? nlohmann::json::parse(mapping::formatMapMetadata(*metadata))
                                              : nlohmann::json(nullptr);
  return j;
}

}  // namespace mobmap::app
