#pragma once
// The files of a built map: MAP.ot (+ .bt, .octovis.ot, .json metadata).

#include "mobmap/mapping/mobility_map.hpp"

#include <nlohmann/json.hpp>

#include <string>

namespace mobmap::app {

/// "maps/x.ot" -> "maps/x" (the stem the other files share).
std::string mapStem(const std::string& ot_path);

/// Metadata written beside a map as STEM.json: an empty object if there is none. IoError
/// naming the file if it is not JSON or if an entry the tools read (frames,
/// R_map_world, trajectory_map) has the wrong shape, is not finite, or R_map_world is not
/// a rotation.
nlohmann::json readMapMetadata(const std::string& ot_path);

/// MAP.json's text: indented like nlohmann's dump(1), except that each trajectory_map
/// position takes one line ("[x,y,z]") instead of five (a run of 100,000 frames writes
/// 5 MB rather than 15). Parses back to `meta`.
std::string formatMapMetadata(const nlohmann::json& meta);

/// R_map_world recorded in metadata that readMapMetadata() checked (identity if absent).
Eigen::Matrix3d rotationFromMetadata(const nlohmann::json& meta);

/// Loads MAP.ot and its metadata into a MobilityMap.
mapping::MobilityMap loadMap(const std::string& ot_path);

}  // namespace mobmap::app
