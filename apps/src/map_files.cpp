#include "map_files.hpp"

#include <sstream>
#include <string>

namespace mobmap::app {

std::string formatMapMetadata(const nlohmann::json& meta) {
  if (!meta.is_object() || !meta.contains("trajectory_map") || !meta["trajectory_map"].is_array()) {
    return meta.dump(1) + "\n";
  }
  nlohmann::json rest = meta;
  rest.erase("trajectory_map");
  std::string text = rest.dump(1);  // "{\n \"a\": ...\n}"
  text.pop_back();                  // the closing brace
  std::string rows;
  const auto& traj = meta["trajectory_map"];
  for (std::size_t i = 0; i < traj.size(); ++i) {
    rows += "  " + traj[i].dump() + (i + 1 < traj.size() ? ",\n" : "\n");
  }
  const std::string entry = " \"trajectory_map\": [" + (rows.empty() ? std::string("]") : "\n" + rows + " ]") + "\n}\n";
  if (rest.empty()) return "{\n" + entry;
  text.back() = ',';  // the newline after the last entry becomes its separator
  return text + "\n" + entry;
}

OpenedMap openMapFiles(const std::string& ot_path) {
  auto tree = mapping::loadMobilityMap(ot_path);
  mapping::MapMetadata metadata = mapping::readMapMetadata(ot_path);
  mapping::MobilityMap map = mapping::openMap(std::move(tree), metadata);
  return {std::move(metadata), std::move(map)};
}

std::vector<NamedPath> mapFilesAsInputs(const std::string& ot_path) {
  const std::string stem = mapping::mapFileStem(ot_path);
  return {{"the map", ot_path},
          {"the map's occupancy export", stem + ".bt"},
          {"the map's octovis export", stem + ".octovis.ot"},
          {"the map's metadata", stem + ".json"}};
}

nlohmann::json metadataJson(const mapping::MapMetadata& meta) {
  return meta.found ? nlohmann::json::parse(meta.text) : nlohmann::json::object();
}

std::string describeKeyframeRule(double min_translation_m, double min_rotation_deg) {
  std::ostringstream out;
  if (min_translation_m > 0) out << "camera moved >= " << min_translation_m << " m";
  if (min_translation_m > 0 && min_rotation_deg > 0) out << " or ";
  if (min_rotation_deg > 0) out << (min_translation_m > 0 ? "" : "camera ") << "turned >= " << min_rotation_deg << " degrees";
  return out.str();
}

std::vector<Eigen::Vector2d> CameraPath::xy() const {
  std::vector<Eigen::Vector2d> out;
  out.reserve(positions.size());
  for (const Eigen::Vector3d& p : positions) out.push_back(p.head<2>());
  return out;
}

CameraPath cameraPath(const nlohmann::json& meta) {
  CameraPath c;
  if (meta.contains("trajectory_map")) {
    for (const auto& p : meta["trajectory_map"]) c.positions.emplace_back(p[0].get<double>(), p[1].get<double>(), p[2].get<double>());
  }
  if (meta.contains("earlier_runs")) {
    for (const auto& run : meta["earlier_runs"]) {
      if (run.contains("frames_in_run")) c.run_starts.push_back(c.run_starts.back() + run["frames_in_run"].get<std::size_t>());
    }
  }
  return c;
}

}  // namespace mobmap::app
