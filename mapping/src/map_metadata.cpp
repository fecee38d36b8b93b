// MAP.json: the one reader and writer. Every record's keys are listed once, in a
// fields() function that both the reader and the writer walk, so the two cannot drift.
#include "mobmap/mapping/map_metadata.hpp"

#include "mobmap/mapping/gravity.hpp"
#include "mobmap/util/json_limits.hpp"
#include "mobmap/mapping/mobility_map.hpp"

#include "atomic_write.hpp"

#include <nlohmann/json.hpp>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

namespace mobmap::mapping {
namespace {

using Json = nlohmann::json;

[[noreturn]] void fail(const std::string& path, const std::string& reason) { throw MapIoError(path + ": " + reason); }

// Far beyond any map OctoMap addresses at a useful resolution (its keys span 65536
// voxels per axis: 1.3 km at 2 cm).
constexpr double kFarthest = 1e6;

template <typename V>
void fields(KeyframeRecord& r, V& v) {
  v("min_translation_m", r.min_translation_m);
  v("min_rotation_deg", r.min_rotation_deg);
  v("frames_considered", r.frames_considered);
}

template <typename V>
void fields(DepthCameraRecord& r, V& v) {
  v("fx", r.fx);
  v("fy", r.fy);
  v("cx", r.cx);
  v("cy", r.cy);
  v("width", r.width);
  v("height", r.height);
}

template <typename V>
void fields(PerceptionRecord& r, V& v) {
  v("max_range_m", r.max_range_m);
  v("voxel_size_m", r.voxel_size_m);
  v("normal_k", r.normal_k);
  v("outlier_k", r.outlier_k);
  v("colour_threshold", r.colour_threshold);
  v("min_segment_points", r.min_segment_points);
  v("ground_min_points", r.ground_min_points);
  v("neighbour_distance_m", r.neighbour_distance_m);
  v("max_triangle_edge_m", r.max_triangle_edge_m);
  v("rough_fragment_max_points", r.rough_fragment_max_points);
  v("rough_min_points", r.rough_min_points);
  v("rough_smoothing_k", r.rough_smoothing_k);
}

template <typename V>
void fields(MappingRecord& r, V& v) {
  v("resolution_m", r.resolution_m);
  v("max_range_m", r.max_range_m);
  v("free_space_ray_stride_px", r.free_space_ray_stride_px);
  v("max_weight", r.max_weight);
  v("clear_seen_through", r.clear_seen_through);
}

template <typename V>
void fields(ModelRecord& r, V& v) {
  v("kind", r.kind);
  v("table", r.table);
  v("signal_std", r.signal_std);
  v("length_scale", r.length_scale);
  v("noise_std", r.noise_std);
}

template <typename V>
void fields(MapRun& r, V& v) {
  v("format", r.format);
  v("tool", r.tool);
  v("tree_type", r.tree_type);
  v("input", r.input);
  v("frames_in_run", r.frames_in_run);
  v("frames_selected", r.frames_selected);
  v("keyframes", r.keyframes);
  v("skipped", r.skipped);
  v("recovered", r.recovered);
  v("depth_intrinsics", r.depth_intrinsics);
  v("poses", r.poses);
  v("max_pose_gap_s", r.max_pose_gap_s);
  v("depth_topic", r.depth_topic);
  v("camera_info_topic", r.camera_info_topic);
  v("world_frame", r.world_frame);
  v("extrinsics", r.extrinsics);
  v("frames_without_pose", r.frames_without_pose);
  v("unreadable", r.unreadable);
  v("frame_numbers", r.frame_numbers);
  v("interrupted", r.interrupted);
  v("checkpoint", r.checkpoint);
  v("resolution_m", r.resolution_m);
  v("gravity_down_world", r.gravity_down_world);
  v("gravity_source", r.gravity_source);
  v("gravity_given_world", r.gravity_given_world);
  v("gravity_floor_angle_deg", r.gravity_floor_angle_deg);
  v("R_map_world", r.R_map_world);
  v("origin_world", r.origin_world);
  v("origin_source", r.origin_source);
  v("points_outside_map", r.points_outside_map);
  v("frames_outside_map", r.frames_outside_map);
  v("depth_units_per_m", r.depth_units_per_m);
  v("depth_format", r.depth_format);
  v("points_in_view", r.points_in_view);
  v("points_beyond_range", r.points_beyond_range);
  v("seconds", r.seconds);
  v("frames_per_second", r.frames_per_second);
  v("perception", r.perception);
  v("mapping", r.mapping);
  v("model", r.model);
  v("config", r.config);
}

// The map-wide entries, kept at the top level beside the latest run's: not run entries.
const std::set<std::string> kMapWideKeys = {"frames", "trajectory_map", "earlier_runs"};

std::optional<std::array<double, 3>> finite3(const Json& j) {
  if (!j.is_array() || j.size() != 3) return std::nullopt;
  std::array<double, 3> v{};
  for (std::size_t i = 0; i < 3; ++i) {
    if (!j[i].is_number() || !std::isfinite(j[i].get<double>())) return std::nullopt;
    v[i] = j[i].get<double>();
  }
  return v;
}

// Reads the entries fields() lists from one JSON object, each checked by type; an entry
// of the wrong type is an error naming it ("earlier_runs entry 0: \"seconds\" ...").
class Reader {
 public:
  Reader(const Json& obj, std::string where, const std::string& path) : obj_(obj), where_(std::move(where)), path_(path) {}

  template <typename T>
  void operator()(const char* key, T& field) {
    known_.insert(key);
    if (obj_.contains(key)) parse(obj_[key], key, field);
  }
  template <typename T>
  void operator()(const char* key, std::optional<T>& field) {
    known_.insert(key);
    if (!obj_.contains(key)) return;
    T value{};
    parse(obj_[key], key, value);
    field = std::move(value);
  }

  // The entries fields() did not name, as a JSON object's text (empty if none).
  std::string others(const std::set<std::string>& also_known = {}) const {
    Json rest = Json::object();
    for (auto it = obj_.begin(); it != obj_.end(); ++it) {
      if (!known_.count(it.key()) && !also_known.count(it.key())) rest[it.key()] = it.value();
    }
    return rest.empty() ? std::string() : rest.dump();
  }

  [[noreturn]] void bad(const char* key, const std::string& expected, const Json& got) const {
    fail(path_, where_ + "\"" + key + "\" must be " + expected + ", got " + got.dump());
  }

 private:
  void parse(const Json& j, const char* key, std::string& out) const {
    if (!j.is_string()) bad(key, "a string", j);
    out = j.get<std::string>();
  }
  void parse(const Json& j, const char* key, bool& out) const {
    if (!j.is_boolean()) bad(key, "true or false", j);
    out = j.get<bool>();
  }
  void parse(const Json& j, const char* key, double& out) const {
    if (!j.is_number() || !std::isfinite(j.get<double>())) bad(key, "a finite number", j);
    out = j.get<double>();
  }
  void parse(const Json& j, const char* key, long long& out) const {
    if (!j.is_number_integer() || (j.is_number_unsigned() && j.get<unsigned long long>() > std::numeric_limits<long long>::max()) ||
        j.get<long long>() < 0) {
      bad(key, "a non-negative whole number", j);
    }
    out = j.get<long long>();
  }
  void parse(const Json& j, const char* key, int& out) const {
    long long v = 0;
    parse(j, key, v);
    if (v > std::numeric_limits<int>::max()) bad(key, "a non-negative whole number", j);
    out = static_cast<int>(v);
  }
  void parse(const Json& j, const char* key, Eigen::Vector3d& out) const {
    const auto v = finite3(j);
    if (!v) bad(key, "[x, y, z], finite", j);
    out = Eigen::Vector3d((*v)[0], (*v)[1], (*v)[2]);
  }
  void parse(const Json& j, const char* key, Eigen::Matrix3d& out) const {
    Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
    bool ok = j.is_array() && j.size() == 3;
    for (std::size_t i = 0; ok && i < 3; ++i) {
      const auto row = finite3(j[i]);
      ok = row.has_value();
      for (std::size_t k = 0; ok && k < 3; ++k) t(static_cast<int>(i), static_cast<int>(k)) = (*row)[k];
    }
    if (!ok) bad(key, "3 rows of 3 finite numbers", j);
    if (auto problem = checkRigid(t)) fail(path_, where_ + "\"" + key + "\" is not a rotation: " + *problem);
    out = t.topLeftCorner<3, 3>();
  }
  void parse(const Json& j, const char* key, std::array<long long, 2>& out) const {
    if (!j.is_array() || j.size() != 2) bad(key, "[first, last] frame numbers", j);
    for (std::size_t i = 0; i < 2; ++i) parse(j[i], key, out[i]);
  }
  void parse(const Json& j, const char* key, std::vector<std::string>& out) const {
    if (!j.is_array()) bad(key, "a list of strings", j);
    out.clear();
    for (const auto& s : j) {
      if (!s.is_string()) bad(key, "a list of strings", j);
      out.push_back(s.get<std::string>());
    }
  }
  template <typename Record>
  void parse(const Json& j, const char* key, Record& out) const {
    if (!j.is_object()) bad(key, "an object", j);
    Reader inner(j, where_ + "\"" + key + "\": ", path_);
    fields(out, inner);
  }

  const Json& obj_;
  std::string where_;
  const std::string& path_;
  std::set<std::string> known_;
};

// Writes the entries fields() lists that are set; keys come out in alphabetical order.
class Writer {
 public:
  explicit Writer(Json& obj) : obj_(obj) {}

  template <typename T>
  void operator()(const char* key, const T& field) {
    if (auto j = value(field)) obj_[key] = std::move(*j);
  }
  template <typename T>
  void operator()(const char* key, const std::optional<T>& field) {
    if (!field) return;
    if (auto j = value(*field)) obj_[key] = std::move(*j);
  }

 private:
  template <typename T>
  static std::optional<Json> value(const T& v) {
    if constexpr (std::is_same_v<T, Eigen::Vector3d>) {
      return Json{v.x(), v.y(), v.z()};
    } else if constexpr (std::is_same_v<T, Eigen::Matrix3d>) {
      return Json{{v(0, 0), v(0, 1), v(0, 2)}, {v(1, 0), v(1, 1), v(1, 2)}, {v(2, 0), v(2, 1), v(2, 2)}};
    } else if constexpr (std::is_same_v<T, std::vector<std::string>>) {
      if (v.empty()) return std::nullopt;
      return Json(v);
    } else if constexpr (std::is_same_v<T, std::string> || std::is_arithmetic_v<T> ||
                         std::is_same_v<T, std::array<long long, 2>>) {
      return Json(v);
    } else {
      Json inner = Json::object();
      Writer w(inner);
      fields(const_cast<T&>(v), w);
      return inner;
    }
  }

  Json& obj_;
};

MapRun readRun(const Json& obj, const std::string& where, const std::string& path, const std::set<std::string>& also_known) {
  MapRun run;
  Reader r(obj, where, path);
  fields(run, r);
  std::optional<long long> unreadable_count;  // checked only: written as the length of "unreadable"
  r("frames_unreadable", unreadable_count);
  if (run.gravity_down_world && run.gravity_down_world->norm() < 1e-9) {
    r.bad("gravity_down_world", "[x, y, z], finite and not zero", obj["gravity_down_world"]);
  }
  run.other_entries = r.others(also_known);
  return run;
}

Json runJson(const MapRun& run) {
  Json obj = Json::object();
  if (!run.other_entries.empty()) {
    const Json other = Json::parse(run.other_entries, nullptr, false);
    if (other.is_object()) obj = other;
  }
  Writer w(obj);
  fields(const_cast<MapRun&>(run), w);
  if (!run.unreadable.empty()) obj["frames_unreadable"] = run.unreadable.size();
  return obj;
}

}  // namespace

std::string mapFileStem(const std::string& ot_path) {
  const std::filesystem::path p(ot_path);
  return p.extension() == ".ot" ? (p.parent_path() / p.stem()).string() : ot_path;
}

Eigen::Matrix3d MapMetadata::R_map_world() const {
  // Printed to 17 digits, but a hand-edited file may round: keep it a rotation.
  return latest.R_map_world ? nearestRotation(*latest.R_map_world) : Eigen::Matrix3d::Identity();
}

Eigen::Vector3d MapMetadata::originWorld() const { return latest.origin_world.value_or(Eigen::Vector3d::Zero()); }

std::vector<const MapRun*> MapMetadata::runs() const {
  std::vector<const MapRun*> out;
  for (const MapRun& r : earlier_runs) out.push_back(&r);
  out.push_back(&latest);
  return out;
}

std::vector<std::size_t> MapMetadata::runStarts() const {
  std::vector<std::size_t> starts{0};
  for (const MapRun& r : earlier_runs) {
    if (r.frames_in_run) starts.push_back(starts.back() + static_cast<std::size_t>(*r.frames_in_run));
  }
  return starts;
}

void MapMetadata::addRun(MapRun run, const std::vector<Eigen::Vector3d>& run_trajectory) {
  // A map from before frames_in_run was recorded has no earlier runs: its frames are its one run's.
  if (!latest.frames_in_run) latest.frames_in_run = frames;
  earlier_runs.push_back(std::move(latest));
  frames += run.frames_in_run.value_or(0);
  latest = std::move(run);
  trajectory_map.insert(trajectory_map.end(), run_trajectory.begin(), run_trajectory.end());
}

MapMetadata parseMapMetadata(const std::string& text, const std::string& path) {
  MapMetadata m;
  m.path = path;
  Json meta;
  // Nesting is bounded before parsing: copying or printing a value nested 100,000 deep
  // recurses past the stack.
  if (const util::JsonLimitProblem problem = util::checkJsonLimits(text)) fail(path, "not a map metadata file: " + problem.message);
  try {
    meta = Json::parse(text);
  } catch (const Json::exception& e) {
    fail(path, std::string("not valid JSON: ") + e.what());
  }
  if (!meta.is_object()) fail(path, "not a map metadata file (expected a JSON object)");
  {
    Reader r(meta, "", path);
    r("frames", m.frames);
  }
  if (meta.contains("trajectory_map")) {
    const auto& traj = meta["trajectory_map"];
    if (!traj.is_array()) fail(path, "\"trajectory_map\" must be a list of [x, y, z] positions");
    m.trajectory_map.reserve(traj.size());
    for (std::size_t i = 0; i < traj.size(); ++i) {
      const auto p = finite3(traj[i]);
      if (!p || std::abs((*p)[0]) > kFarthest || std::abs((*p)[1]) > kFarthest || std::abs((*p)[2]) > kFarthest) {
        fail(path, "\"trajectory_map\" entry " + std::to_string(i) + " must be [x, y, z] in metres (finite, within 1e6), got " +
                       traj[i].dump());
      }
      m.trajectory_map.emplace_back((*p)[0], (*p)[1], (*p)[2]);
    }
  }
  if (meta.contains("earlier_runs")) {  // runs before the latest (`mobmap build --extend`)
    const auto& runs = meta["earlier_runs"];
    if (!runs.is_array()) fail(path, "\"earlier_runs\" must be a list of run records");
    for (std::size_t i = 0; i < runs.size(); ++i) {
      const std::string where = "\"earlier_runs\" entry " + std::to_string(i) + ": ";
      if (!runs[i].is_object()) fail(path, where + "must be a run record (a JSON object)");
      m.earlier_runs.push_back(readRun(runs[i], where, path, {}));
    }
  }
  m.latest = readRun(meta, "", path, kMapWideKeys);
  m.found = true;
  return m;
}

MapMetadata readMapMetadata(const std::string& ot_path) {
  const std::string path = mapFileStem(ot_path) + ".json";
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    MapMetadata m;
    m.path = path;
    return m;
  }
  if (std::filesystem::is_directory(path, ec)) fail(path, "is a directory, expected a file");
  // A camera path of a million frames takes ~50 MB.
  constexpr std::uintmax_t kMaxBytes = 256u << 20;
  const auto size = std::filesystem::file_size(path, ec);
  if (!ec && size > kMaxBytes) fail(path, "file is " + std::to_string(size) + " bytes, more than the 256 MB expected");
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, std::string("cannot open: ") + std::strerror(errno));
  std::ostringstream s;
  s << in.rdbuf();
  return parseMapMetadata(s.str(), path);
}

std::string formatMapMetadata(const MapMetadata& metadata) {
  Json meta = runJson(metadata.latest);
  meta["frames"] = metadata.frames;
  if (!metadata.earlier_runs.empty()) {
    Json runs = Json::array();
    for (const MapRun& r : metadata.earlier_runs) runs.push_back(runJson(r));
    meta["earlier_runs"] = std::move(runs);
  }
  // One camera position per line: a run of 100,000 frames writes 5 MB rather than 15.
  std::string text = meta.dump(1);  // "{\n \"a\": ...\n}"
  text.pop_back();                  // the closing brace
  std::string rows;
  for (std::size_t i = 0; i < metadata.trajectory_map.size(); ++i) {
    const Eigen::Vector3d& p = metadata.trajectory_map[i];
    rows += "  " + Json{p.x(), p.y(), p.z()}.dump() + (i + 1 < metadata.trajectory_map.size() ? ",\n" : "\n");
  }
  const std::string entry = " \"trajectory_map\": [" + (rows.empty() ? std::string("]") : "\n" + rows + " ]") + "\n}\n";
  text.back() = ',';  // the newline after the last entry becomes its separator ("frames" is always there)
  return text + "\n" + entry;
}

void saveMapMetadata(const MapMetadata& metadata, const std::string& json_path) {
  const std::string text = formatMapMetadata(metadata);
  writeAtomically(json_path, [&](std::ostream& s) { return static_cast<bool>(s << text); });
}

MobilityMap openMap(std::unique_ptr<MobilityOcTree> tree, const MapMetadata& metadata, MapParams params) {
  // MAP.json must describe this tree: a MAP.json left beside another map would put its
  // origin and rotation on the wrong voxels.
  if (metadata.found) {
    const MapRun& run = metadata.latest;
    if (run.tree_type && *run.tree_type != tree->getTreeType()) {
      fail(metadata.path, "records a " + *run.tree_type + " map, but the map beside it is a " + tree->getTreeType() +
                              ": the two files belong to different maps");
    }
    const double res = tree->getResolution();
    if (run.resolution_m && std::abs(*run.resolution_m - res) > 1e-6 * res) {
      std::ostringstream msg;
      msg << "records " << *run.resolution_m << " m voxels, but the map beside it has " << res
          << " m voxels: the two files belong to different maps";
      fail(metadata.path, msg.str());
    }
  }
  params.resolution_m = tree->getResolution();
  MobilityMap map(std::move(tree), params, metadata.R_map_world(), metadata.originWorld());
  map.setFramesIntegrated(metadata.frames);
  return map;
}

MobilityMap openMap(const std::string& ot_path, MapParams params) {
  auto tree = loadMobilityMap(ot_path);  // the tree's errors before the metadata's
  return openMap(std::move(tree), readMapMetadata(ot_path), params);
}

}  // namespace mobmap::mapping
