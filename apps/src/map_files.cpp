#include "map_files.hpp"

#include "files.hpp"
#include "io_error.hpp"

#include "mobmap/mapping/gravity.hpp"

#include <cmath>
#include <filesystem>
#include <limits>
#include <optional>
#include <vector>

namespace mobmap::app {

std::string mapStem(const std::string& ot_path) {
  const std::filesystem::path p(ot_path);
  return p.extension() == ".ot" ? (p.parent_path() / p.stem()).string() : ot_path;
}

namespace {

/// A JSON array of exactly n finite numbers, or nothing.
std::optional<std::vector<double>> finiteNumbers(const nlohmann::json& j, std::size_t n) {
  if (!j.is_array() || j.size() != n) return std::nullopt;
  std::vector<double> v;
  for (const auto& x : j) {
    if (!x.is_number() || !std::isfinite(x.get<double>())) return std::nullopt;
    v.push_back(x.get<double>());
  }
  return v;
}

// Checks the entries the tools read back (frames, R_map_world, trajectory_map), so a
// hand-edited or damaged file is reported by name and key, not by a JSON type error.
void checkMetadata(const nlohmann::json& meta, const std::string& path) {
  if (!meta.is_object()) throw IoError(path, "not a map metadata file (expected a JSON object)");
  if (meta.contains("frames")) {
    const auto& f = meta["frames"];
    if (!f.is_number_integer() || f.get<long long>() < 0 || f.get<long long>() > std::numeric_limits<int>::max()) {
      throw IoError(path, "\"frames\" must be a non-negative whole number, got " + f.dump());
    }
  }
  if (meta.contains("R_map_world")) {
    const auto& m = meta["R_map_world"];
    Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
    bool ok = m.is_array() && m.size() == 3;
    for (std::size_t i = 0; ok && i < 3; ++i) {
      const auto row = finiteNumbers(m[i], 3);
      ok = row.has_value();
      for (std::size_t k = 0; ok && k < 3; ++k) t(static_cast<int>(i), static_cast<int>(k)) = (*row)[k];
    }
    if (!ok) throw IoError(path, "\"R_map_world\" must be 3 rows of 3 finite numbers");
    if (auto problem = mapping::checkRigid(t)) throw IoError(path, "\"R_map_world\" is not a rotation: " + *problem);
  }
  // Runs before the latest of a map extended with `build --extend` (printed by `info`).
  const auto count = [&](const nlohmann::json& obj, const char* key, const std::string& where) {
    if (!obj.contains(key)) return;
    const auto& f = obj[key];
    if (!f.is_number_integer() || f.get<long long>() < 0 || f.get<long long>() > std::numeric_limits<int>::max()) {
      throw IoError(path, where + "\"" + key + "\" must be a non-negative whole number, got " + f.dump());
    }
  };
  count(meta, "frames_in_run", "");
  if (meta.contains("earlier_runs")) {
    const auto& runs = meta["earlier_runs"];
    if (!runs.is_array()) throw IoError(path, "\"earlier_runs\" must be a list of run records");
    for (std::size_t i = 0; i < runs.size(); ++i) {
      const std::string where = "\"earlier_runs\" entry " + std::to_string(i) + ": ";
      if (!runs[i].is_object()) throw IoError(path, where + "must be a run record (a JSON object)");
      count(runs[i], "frames_in_run", where);
    }
  }
  if (meta.contains("trajectory_map")) {
    const auto& traj = meta["trajectory_map"];
    if (!traj.is_array()) throw IoError(path, "\"trajectory_map\" must be a list of [x, y, z] positions");
    // Far beyond any map OctoMap addresses at a useful resolution (its keys span 65536
    // voxels per axis: 1.3 km at 2 cm).
    constexpr double kFarthest = 1e6;
    for (std::size_t i = 0; i < traj.size(); ++i) {
      const auto p = finiteNumbers(traj[i], 3);
      if (!p || std::abs((*p)[0]) > kFarthest || std::abs((*p)[1]) > kFarthest || std::abs((*p)[2]) > kFarthest) {
        throw IoError(path, "\"trajectory_map\" entry " + std::to_string(i) +
                                " must be [x, y, z] in metres (finite, within 1e6), got " + traj[i].dump());
      }
    }
  }
}

}  // namespace

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

nlohmann::json readMapMetadata(const std::string& ot_path) {
  const std::string path = mapStem(ot_path) + ".json";
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return nlohmann::json::object();
  nlohmann::json meta;
  try {
    meta = nlohmann::json::parse(readTextFile(path, 256u << 20));
  } catch (const nlohmann::json::exception& e) {
    throw IoError(path, std::string("not valid JSON: ") + e.what());
  }
  checkMetadata(meta, path);
  return meta;
}

Eigen::Matrix3d rotationFromMetadata(const nlohmann::json& meta) {
  Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
  if (!meta.contains("R_map_world")) return r;
  const auto& m = meta["R_map_world"];
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r(i, j) = m[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)].get<double>();
  }
  // Printed to 16-17 digits, but a hand-edited file may round: keep it a rotation.
  return mapping::nearestRotation(r);
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
