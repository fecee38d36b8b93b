#pragma once
// The robot and start options of `mobmap reach`, shared with `query --reach`, and the
// run they describe.

#include "io/map_files.hpp"

#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/mapping/reachability.hpp"

#include <CLI/CLI.hpp>

#include <Eigen/Core>

#include <optional>
#include <string>
#include <vector>

namespace mobmap::app {

struct ReachOptions {
  std::vector<double> from;  ///< X Y Z, or empty: the map's first camera position
  std::string rule;          ///< "nearest", "largest-level", or empty: by whether --from is given
  mapping::ReachParams params;
  CLI::Option* radius = nullptr;      ///< --start-radius, to tell a given value from the default
  std::vector<CLI::Option*> options;  ///< every option added, for needs()
};

/// Adds the robot's options (--sole, --max-step, --min-mobility, --min-support, --max-tilt,
/// --max-unevenness, --clearance, --max-stride, --swing-clearance, --max-gap,
/// --stance-width, --lattice) to `cmd`, writing into `robot`; returns them (for needs()).
std::vector<CLI::Option*> addRobotOptions(CLI::App& cmd, mapping::RobotParams& robot);

/// Adds --from, the robot's options (addRobotOptions), --start-radius and --start to
/// `cmd`, writing into `o` (which must outlive the parse). `from_frame_option` names the
/// option that sets the frame --from is given in.
void addReachOptions(CLI::App& cmd, ReachOptions& o, const std::string& from_frame_option);

/// Resolves the defaults (start rule and radius by whether --from was given) and checks
/// the parameters and --from: UsageError. Commands call it before loading the map, so a
/// usage error is reported as one, and before runReach.
void resolveReachOptions(ReachOptions& o);

/// A reachability run: the point it started from (map frame) and its result.
struct ReachRun {
  Eigen::Vector3d from = Eigen::Vector3d::Zero();
  mapping::Reachability result;
};

/// For options resolveReachOptions() has resolved: finds the start point (--from, in the
/// world frame when `from_in_world`, else the first position of `camera`; UsageError if
/// neither) and runs computeReachability. No place to start on: std::runtime_error naming
/// `map_path`, the radius and the rule.
/// Under the largest-level rule, when under half of the start level's walkable places
/// near the start lie under a whole standable sole: what that means and what helps (a
/// sentence without a "note:" prefix). Empty otherwise.
std::string sparseStartNote(const mapping::Reachability& r, const ReachOptions& o);

/// Where a walk starts (map frame): --from (in the world frame when `from_in_world`), else
/// the first position of `camera`; nullopt when there is neither.
std::optional<Eigen::Vector3d> reachFrom(const ReachOptions& o, const mapping::MobilityMap& map, bool from_in_world,
                                         const CameraPath& camera);

ReachRun runReach(const ReachOptions& o, const mapping::MobilityMap& map, const std::string& map_path, bool from_in_world,
                  const CameraPath& camera);

}  // namespace mobmap::app
