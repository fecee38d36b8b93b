// MAP.json, the metadata `mobmap build` writes beside a map: read and checked here so a
// planner linking the library gets the map's frame the way the command-line tools do.
#include "mobmap/mapping/gravity.hpp"
#include "mobmap/mapping/mobility_map.hpp"

#include <nlohmann/json.hpp>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

namespace mobmap::mapping {
namespace {

[[noreturn]] void fail(const std::string& path, const std::string& reason) { throw MapIoError(path + ": " + reason); }

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

// A whole number of frames, if the entry is there.
void checkCount(const nlohmann::json& obj, const char* key, const std::string& where, const std::string& path) {
  if (!obj.contains(key)) return;
  const auto& f = obj[key];
  if (!f.is_number_integer() || f.get<long long>() < 0 || f.get<long long>() > std::numeric_limits<int>::max()) {
    fail(path, where + "\"" + key + "\" must be a non-negative whole number, got " + f.dump());
  }
}

// Checks every entry the tools read back, so a hand-edited or damaged file is reported
// by name and key, not by a JSON type error later.
void check(const nlohmann::json& meta, const std::string& path) {
  if (!meta.is_object()) fail(path, "not a map metadata file (expected a JSON object)");
  checkCount(meta, "frames", "", path);
  checkCount(meta, "frames_in_run", "", path);
  if (meta.contains("R_map_world")) {
    const auto& m = meta["R_map_world"];
    Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
    bool ok = m.is_array() && m.size() == 3;
    for (std::size_t i = 0; ok && i < 3; ++i) {
      const auto row = finiteNumbers(m[i], 3);
      ok = row.has_value();
      for (std::size_t k = 0; ok && k < 3; ++k) t(static_cast<int>(i), static_cast<int>(k)) = (*row)[k];
    }
    if (!ok) fail(path, "\"R_map_world\" must be 3 rows of 3 finite numbers");
    if (auto problem = checkRigid(t)) fail(path, "\"R_map_world\" is not a rotation: " + *problem);
  }
  if (meta.contains("origin_world")) {
    const auto o = finiteNumbers(meta["origin_world"], 3);
    if (!o) fail(path, "\"origin_world\" must be [x, y, z], finite, got " + meta["origin_world"].dump());
  }
  if (meta.contains("gravity_down_world")) {
    const auto g = finiteNumbers(meta["gravity_down_world"], 3);
    if (!g || Eigen::Vector3d((*g)[0], (*g)[1], (*g)[2]).norm() < 1e-9) {
      fail(path, "\"gravity_down_world\" must be [x, y, z], finite and not zero, got " + meta["gravity_down_world"].dump());
    }
  }
  if (meta.contains("trajectory_map")) {
    const auto& traj = meta["trajectory_map"];
    if (!traj.is_array()) fail(path, "\"trajectory_map\" must be a list of [x, y, z] positions");
    // Far beyond any map OctoMap addresses at a useful resolution (its keys span 65536
    // voxels per axis: 1.3 km at 2 cm).
    constexpr double kFarthest = 1e6;
    for (std::size_t i = 0; i < traj.size(); ++i) {
      const auto p = finiteNumbers(traj[i], 3);
      if (!p || std::abs((*p)[0]) > kFarthest || std::abs((*p)[1]) > kFarthest || std::abs((*p)[2]) > kFarthest) {
        fail(path, "\"trajectory_map\" entry " + std::to_string(i) + " must be [x, y, z] in metres (finite, within 1e6), got " +
                       traj[i].dump());
      }
    }
  }
  if (meta.contains("earlier_runs")) {  // runs before the latest (`mobmap build --extend`)
    const auto& runs = meta["earlier_runs"];
    if (!runs.is_array()) fail(path, "\"earlier_runs\" must be a list of run records");
    for (std::size_t i = 0; i < runs.size(); ++i) {
      const std::string where = "\"earlier_runs\" entry " + std::to_string(i) + ": ";
      if (!runs[i].is_object()) fail(path, where + "must be a run record (a JSON object)");
      checkCount(runs[i], "frames_in_run", where, path);
    }
  }
}

}  // namespace

std::string mapFileStem(const std::string& ot_path) {
  const std::filesystem::path p(ot_path);
  return p.extension() == ".ot" ? (p.parent_path() / p.stem()).string() : ot_path;
}

MapMetadata readMapMetadata(const std::string& ot_path) {
  MapMetadata m;
  m.path = mapFileStem(ot_path) + ".json";
  std::error_code ec;
  if (!std::filesystem::exists(m.path, ec)) return m;
  if (std::filesystem::is_directory(m.path, ec)) fail(m.path, "is a directory, expected a file");
  // A camera path of a million frames takes ~50 MB.
  constexpr std::uintmax_t kMaxBytes = 256u << 20;
  const auto size = std::filesystem::file_size(m.path, ec);
  if (!ec && size > kMaxBytes) fail(m.path, "file is " + std::to_string(size) + " bytes, more than the 256 MB expected");
  std::ifstream in(m.path, std::ios::binary);
  if (!in) fail(m.path, std::string("cannot open: ") + std::strerror(errno));
  std::ostringstream s;
  s << in.rdbuf();
  m.text = s.str();
  nlohmann::json meta;
  try {
    meta = nlohmann::json::parse(m.text);
  } catch (const nlohmann::json::exception& e) {
    fail(m.path, std::string("not valid JSON: ") + e.what());
  }
  check(meta, m.path);
  m.found = true;
  if (meta.contains("frames")) m.frames = meta["frames"].get<int>();
  if (meta.contains("R_map_world")) {
    const auto& rows = meta["R_map_world"];
    Eigen::Matrix3d r;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) r(i, j) = rows[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)].get<double>();
    }
    m.has_frame = true;
    // Printed to 17 digits, but a hand-edited file may round: keep it a rotation.
    m.R_map_world = nearestRotation(r);
  }
  if (meta.contains("origin_world")) {
    const auto& o = meta["origin_world"];
    m.origin_world = Eigen::Vector3d(o[0].get<double>(), o[1].get<double>(), o[2].get<double>());
  }
  if (meta.contains("gravity_down_world")) {
    const auto& g = meta["gravity_down_world"];
    m.gravity_down_world = Eigen::Vector3d(g[0].get<double>(), g[1].get<double>(), g[2].get<double>());
  }
  return m;
}

MobilityMap openMap(std::unique_ptr<MobilityOcTree> tree, const MapMetadata& metadata, MapParams params) {
  params.resolution_m = tree->getResolution();
  MobilityMap map(std::move(tree), params, metadata.R_map_world, metadata.origin_world);
  map.setFramesIntegrated(metadata.frames);
  return map;
}

MobilityMap openMap(const std::string& ot_path, MapParams params) {
  auto tree = loadMobilityMap(ot_path);  // the tree's errors before the metadata's
  return openMap(std::move(tree), readMapMetadata(ot_path), params);
}

}  // namespace mobmap::mapping
