#include "io/map_files.hpp"

#include <string>

namespace mobmap::app {

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

std::vector<Eigen::Vector2d> CameraPath::xy() const {
  std::vector<Eigen::Vector2d> out;
  out.reserve(positions.size());
  for (const Eigen::Vector3d& p : positions) out.push_back(p.head<2>());
  return out;
}

CameraPath cameraPath(const mapping::MapMetadata& meta) {
  CameraPath c;
  c.positions = meta.trajectory_map;
  c.run_starts = meta.runStarts();
  return c;
}

}  // namespace mobmap::app
