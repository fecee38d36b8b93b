#include "reach_options.hpp"

#include "io_error.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace mobmap::app {

void addReachOptions(CLI::App& cmd, ReachOptions& o, const std::string& from_frame_option) {
  auto& params = o.params;
  o.options = {
      cmd.add_option("--from", o.from,
                     "X Y Z: where the robot is (metres, frame as " + from_frame_option +
                         "); it starts on the walkable surface nearest below it. Default: the first camera position of "
                         "the map's MAP.json")
          ->expected(3),
      cmd.add_option("--max-step", params.max_step_m,
                     "Highest step up or down between neighbouring places, metres (tops are known to a voxel, so tops n "
                     "voxels apart need n + 1 voxels within it; at least two voxels)")
          ->capture_default_str(),
      cmd.add_option("--min-mobility", params.min_mobility, "Lowest mobility the robot stands on")->capture_default_str(),
      cmd.add_option("--clearance", params.clearance_m,
                     "Free height needed above a place (the robot's height), metres; 0 does not check. Unseen space "
                     "counts as free")
          ->capture_default_str(),
      cmd.add_option("--max-gap", params.max_gap_m,
                     "Widest run of unobserved columns stepped over, metres (never across anything occupied near the "
                     "walking height)")
          ->capture_default_str(),
      o.radius = cmd.add_option("--start-radius", params.start_radius_m,
                                "How far around the start point to look for a place to stand, metres (default 0.5 with "
                                "--from, 5 from the camera: a level camera 1.5 m up first sees the floor ~4 m ahead)"),
      cmd.add_option("--start", o.rule,
                     "Which place near the start point to start on: the nearest (then the highest), or one on the "
                     "height with the most standable area in the map, in the largest region there (for a camera "
                     "position: the floor, not a chair seat or table nearer the camera). Default: nearest with --from, "
                     "largest-level from the camera")
          ->check(CLI::IsMember({"nearest", "largest-level"})),
  };
}

void resolveReachOptions(ReachOptions& o) {
  if (o.radius->count() == 0) o.params.start_radius_m = o.from.empty() ? 5.0 : 0.5;
  if (o.rule.empty()) o.rule = o.from.empty() ? "largest-level" : "nearest";
  o.params.start_rule =
      o.rule == "nearest" ? mapping::ReachParams::Start::kNearest : mapping::ReachParams::Start::kLargestLevel;
  try {
    mapping::validate(o.params);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  if (!o.from.empty() && !Eigen::Map<const Eigen::Vector3d>(o.from.data()).allFinite()) {
    throw UsageError("--from: values must be finite");
  }
}

ReachRun runReach(const ReachOptions& o, const mapping::MobilityMap& map, const std::string& map_path, bool from_in_world,
                  const CameraPath& camera) {
  ReachRun run;
  if (!o.from.empty()) {
    run.from = Eigen::Vector3d(o.from[0], o.from[1], o.from[2]);
    if (from_in_world) run.from = map.worldToMap(run.from);
  } else if (!camera.positions.empty()) {
    run.from = camera.positions.front();
  } else {
    throw UsageError(map_path + ": no camera path in " + mapping::mapFileStem(map_path) +
                     ".json to start from; give --from X Y Z");
  }
  try {
    run.result = mapping::computeReachability(map.tree(), run.from, o.params);
  } catch (const std::invalid_argument& e) {  // a step under two voxels of this map
    throw UsageError(e.what());
  }
  if (!run.result.start()) {
    char msg[320];
    std::snprintf(msg, sizeof msg,
                  "no place to stand (mobility >= %.2f%s) within %.2f m of (%.2f, %.2f) with its top at or below z = "
                  "%.2f m (map frame); give --from nearer a walkable surface, or a larger --start-radius",
                  o.params.min_mobility, o.rule == "nearest" ? "" : ", on the map's largest walkable level",
                  o.params.start_radius_m, run.from.x(), run.from.y(), run.from.z() + o.params.max_step_m);
    throw std::runtime_error(map_path + ": " + msg);
  }
  return run;
}

}  // namespace mobmap::app
