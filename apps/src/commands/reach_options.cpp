#include "commands/reach_options.hpp"

#include "io/cli_text.hpp"
#include "io/io_error.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace mobmap::app {

std::vector<CLI::Option*> addRobotOptions(CLI::App& cmd, mapping::RobotParams& robot) {
  const auto number = [&cmd](const std::string& name, double& field, const std::string& help) {
    return cmd.add_option(name, field, help)->capture_default_str();
  };
  auto* sole = cmd.add_option_function<std::vector<double>>(
                      "--sole",
                      [&robot](const std::vector<double>& v) {
                        robot.sole_length_m = v[0];
                        robot.sole_width_m = v[1];
                      },
                      "LENGTH WIDTH of the robot's sole, metres (default 0.25 0.12: a small humanoid)")
                   ->expected(2);
  return {
      sole,
      number("--max-step", robot.max_step_m,
             "Highest step up or down between the supports of successive footsteps, metres (support heights are known "
             "to a voxel, so a step passes when its measured height plus one voxel is within this; at least two voxels)"),
      number("--min-mobility", robot.min_mobility,
             "Lowest mobility the robot stands on: the surface under a sole must have at least this, but for --max-poor "
             "of it"),
      number("--max-poor", robot.max_poor_fraction,
             "Share of the known surface under a sole that may have mobility under --min-mobility (stray voxels scored "
             "apart at edges)"),
      number("--min-support", robot.min_support_fraction,
             "Share of a sole that must rest on known surface (the rest may hang over an edge or unseen ground)"),
      number("--max-tilt", robot.max_tilt_deg, "Steepest support plane a sole stands on, degrees"),
      number("--max-unevenness", robot.max_unevenness_m,
             "Largest distance of a voxel top under a sole from its support plane, metres"),
      number("--clearance", robot.clearance_m,
             "Free height needed above a sole (the robot's height), metres; 0 checks only --swing-clearance. Unseen "
             "space counts as free"),
      number("--max-stride", robot.max_stride_m, "Longest distance between the centres of successive footsteps, metres"),
      number("--swing-clearance", robot.swing_clearance_m,
             "How high the swing foot lifts above the higher support, metres: anything between the soles that stands "
             "higher blocks the step"),
      number("--max-gap", robot.max_gap_m,
             "Longest stretch without surface near the walking height that a swing passes over, metres"),
      number("--stance-width", robot.stance_width_m, "Sideways distance between the feet's centres when standing, metres"),
      number("--lattice", robot.lattice_m,
             "Spacing of the sole centres tried, metres (rounded to whole voxels); headings every 22.5 degrees"),
  };
}

void addReachOptions(CLI::App& cmd, ReachOptions& o, const std::string& from_frame_option) {
  auto& params = o.params;
  o.options = addRobotOptions(cmd, params.robot);
  o.options.push_back(cmd.add_option("--from", o.from,
                                     "X Y Z: where the robot is (metres, frame as " + from_frame_option +
                                         "); it starts on the soles nearest below it. Default: the first camera position "
                                         "of the map's MAP.json")
                          ->expected(3));
  o.radius = cmd.add_option("--start-radius", params.start_radius_m,
                            "How far around the start point to look for a place to stand, metres (default 0.5 with "
                            "--from, 5 from the camera: a level camera 1.5 m up first sees the floor ~4 m ahead)");
  o.options.push_back(o.radius);
  o.options.push_back(cmd.add_option("--start", o.rule,
                                     "Where to start: the sole nearest the start point (then the highest), or every "
                                     "standable sole within --start-radius on the height with the most places for a sole "
                                     "in the map (for a camera position: the floor, not a chair seat or table nearer the "
                                     "camera). Default: nearest with --from, largest-level from the camera")
                          ->check(CLI::IsMember({"nearest", "largest-level"})));
}

void resolveReachOptions(ReachOptions& o) {
  if (o.radius->count() == 0) o.params.start_radius_m = o.from.empty() ? 5.0 : 0.5;
  if (o.rule.empty()) o.rule = o.from.empty() ? "largest-level" : "nearest";
  o.params.start_rule =
      o.rule == "nearest" ? mapping::ReachParams::Start::kNearest : mapping::ReachParams::Start::kLargestLevel;
  try {
    mapping::validate(o.params);
  } catch (const std::invalid_argument& e) {
    throw UsageError(cliText(e));
  }
  if (!o.from.empty() && !Eigen::Map<const Eigen::Vector3d>(o.from.data()).allFinite()) {
    throw UsageError("--from: values must be finite");
  }
}

namespace {

// Below this share of its walkable places near the start under a whole sole, a start
// level is sparse: on a floor seen whole, only the rim (half a sole wide) and the edges
// of holes and obstacles carry none.
constexpr double kMinCarriedShare = 0.5;

// Why few of the start level's walkable voxels carry a whole sole, and what helps.
std::string sparseLevelReason(const mapping::Reachability& r) {
  char msg[400];
  std::snprintf(msg, sizeof msg,
                "its walkable voxels are scattered, as the sensor's depth steps stripe a floor seen from far away or in few "
                "frames; building with a coarser --resolution (%.2f m, twice this map's), from more frames, or from "
                "frames nearer the floor fills it in",
                2 * r.resolution());
  return msg;
}

}  // namespace

std::string sparseStartNote(const mapping::Reachability& r, const ReachOptions& o) {
  const auto& level = r.startLevel();
  if (o.params.start_rule != mapping::ReachParams::Start::kLargestLevel || !level || level->walkable_near == 0 ||
      level->carriedShare() >= kMinCarriedShare) {
    return {};
  }
  const auto& robot = o.params.robot;
  char msg[400];
  std::snprintf(msg, sizeof msg,
                "the start level (z = %.2f m, %.0f %% of the map's walkable surface) carries whole %.2f x %.2f m soles on "
                "only %.0f %% of its %zu walkable voxels within %.2f m of the start: ",
                level->z_m, 100 * level->share, robot.sole_length_m, robot.sole_width_m, 100 * level->carriedShare(),
                level->walkable_near, o.params.start_radius_m);
  return msg + sparseLevelReason(r);
}

std::optional<Eigen::Vector3d> reachFrom(const ReachOptions& o, const mapping::MobilityMap& map, bool from_in_world,
                                         const CameraPath& camera) {
  if (!o.from.empty()) {
    const Eigen::Vector3d from(o.from[0], o.from[1], o.from[2]);
    return from_in_world ? map.worldToMap(from) : from;
  }
  if (!camera.positions.empty()) return camera.positions.front();
  return std::nullopt;
}

ReachRun runReach(const ReachOptions& o, const mapping::MobilityMap& map, const std::string& map_path, bool from_in_world,
                  const CameraPath& camera) {
  ReachRun run;
  const std::optional<Eigen::Vector3d> from = reachFrom(o, map, from_in_world, camera);
  if (!from) {
    throw UsageError(map_path + ": no camera path in " + mapping::mapFileStem(map_path) +
                     ".json to start from; give --from X Y Z");
  }
  run.from = *from;
  try {
    run.result = mapping::computeReachability(map.tree(), run.from, o.params);
  } catch (const std::invalid_argument& e) {  // a step under two voxels of this map
    throw UsageError(cliText(e));
  }
  if (!run.result.start()) {
    const auto& robot = o.params.robot;
    char msg[400];
    std::snprintf(msg, sizeof msg,
                  "no place for a %.2f x %.2f m sole to stand (mobility >= %.2f) within %.2f m of (%.2f, %.2f)", robot.sole_length_m,
                  robot.sole_width_m, robot.min_mobility, o.params.start_radius_m, run.from.x(), run.from.y());
    std::string text = msg;
    if (o.rule == "nearest") {
      std::snprintf(msg, sizeof msg, " with its support at or below z = %.2f m", run.from.z() + 0.1);
      text += msg;
    } else if (const auto& level = run.result.startLevel()) {
      std::snprintf(msg, sizeof msg, " on the map's largest level (z = %.2f m, %.0f %% of its walkable surface; ", level->z_m,
                    100 * level->share);
      text += msg;
      if (level->walkable_near == 0) {
        text += "none of it lies there)";
      } else {
        std::snprintf(msg, sizeof msg, "none of its %zu walkable voxels there carries a whole sole: ", level->walkable_near);
        text += msg + sparseLevelReason(run.result) + ")";
      }
    } else {
      text += " on the map's largest level";
    }
    throw std::runtime_error(map_path + ": " + text +
                             " (map frame); give --from nearer a walkable surface, or a larger --start-radius");
  }
  return run;
}

}  // namespace mobmap::app
