#include "map_files.hpp"

#include "files.hpp"
#include "io_error.hpp"

#include <filesystem>

namespace mobmap::app {

std::string mapStem(const std::string& ot_path) {
  const std::filesystem::path p(ot_path);
  return p.extension() == ".ot" ? (p.parent_path() / p.stem()).string() : ot_path;
}

nlohmann::json readMapMetadata(const std::string& ot_path) {
  const std::string path = mapStem(ot_path) + ".json";
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return nlohmann::json::object();
  try {
    return nlohmann::json::parse(readTextFile(path, 16 << 20));
  } catch (const nlohmann::json::exception& e) {
    throw IoError(path, std::string("not valid JSON: ") + e.what());
  }
}

Eigen::Matrix3d rotationFromMetadata(const nlohmann::json& meta) {
  Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
  if (!meta.contains("R_map_world")) return r;
  const auto& m = meta["R_map_world"];
  if (!m.is_array() || m.size() != 3) return r;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r(i, j) = m[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)].get<double>();
  }
  return r;
}

mapping::MobilityMap loadMap(const std::string& ot_path) {
  auto tree = mapping::loadMobilityMap(ot_path);
  const auto meta = readMapMetadata(ot_path);
  mapping::MapParams p;
  p.resolution_m = tree->getResolution();
  mapping::MobilityMap map(std::move(tree), p, rotationFromMetadata(meta));
  if (meta.contains("frames")) map.setFramesIntegrated(meta["frames"].get<int>());
  return map;
}

}  // namespace mobmap::app
