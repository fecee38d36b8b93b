#pragma once
// The files of a built map: MAP.ot (+ .bt, .octovis.ot, .json metadata).

#include "io/files.hpp"

#include "mobmap/builder/map_builder.hpp"
#include "mobmap/mapping/mobility_map.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace mobmap::app {

/// A built map opened for reading, with its MAP.json (its metadata, for the camera path
/// and what else a command reports). Errors name the file: the .ot's are reported
/// first, as mapping::openMap(path) reports them.
struct OpenedMap {
  mapping::MapMetadata metadata;
  mapping::MobilityMap map;
};
OpenedMap openMapFiles(const std::string& ot_path);

/// The map's own files as inputs, for refuseToOverwriteInputs(): MAP.ot, MAP.bt,
/// MAP.octovis.ot and MAP.json.
std::vector<NamedPath> mapFilesAsInputs(const std::string& ot_path);

/// The rule of `build --keyframes` in words (the builder's).
using builder::describeKeyframeRule;

/// The camera path MAP.json records (map frame), and where each run of a map extended
/// with `build --extend` begins in it (0 first).
struct CameraPath {
  std::vector<Eigen::Vector3d> positions;
  std::vector<std::size_t> run_starts{0};
  /// The positions seen from above (x, y): what a top view draws and covers.
  [[nodiscard]] std::vector<Eigen::Vector2d> xy() const;
};
CameraPath cameraPath(const mapping::MapMetadata& meta);

}  // namespace mobmap::app
