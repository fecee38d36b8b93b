#include "serve/api.hpp"

#include "answers/answers.hpp"
#include "serve/viewer_assets.hpp"

#include "mobmap/mapping/footstep_planner.hpp"
#include "mobmap/util/json_limits.hpp"
#include "mobmap/mapping/layers.hpp"
#include "mobmap/mapping/reachability.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <charconv>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <optional>
#include <stdexcept>
#include <unordered_map>
#include <utility>

namespace mobmap::app::serve {

MapSource::MapSource(ServedMap initial) : current_(std::make_shared<const ServedMap>(std::move(initial))) {}

std::shared_ptr<const ServedMap> MapSource::current() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return current_;
}

void MapSource::publish(ServedMap next) {
  auto p = std::make_shared<const ServedMap>(std::move(next));
  const std::lock_guard<std::mutex> lock(mutex_);
  current_ = std::move(p);
}

namespace {
// JSON text of `j`; bytes that are not UTF-8 (a request's own, echoed in an error; a file
// name) become U+FFFD instead of an exception.
std::string text(const nlohmann::json& j) { return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace); }
}  // namespace

std::string errorBody(const std::string& message) { return text(nlohmann::json{{"error", message}}); }

std::vector<Cell> surfaceCells(const mapping::MobilityOcTree& tree, int level) {
  return *surfaceCellsWithin(tree, level, std::numeric_limits<std::size_t>::max(), mapping::Budget{});
}

std::optional<std::vector<Cell>> surfaceCellsWithin(const mapping::MobilityOcTree& tree, int level, std::size_t most,
                                                    const mapping::Budget& budget) {
  const double res = tree.getResolution();
  const double cell = res * std::ldexp(1.0, level);
  // Cell index along an axis from a finest-level key: the octree's nodes at depth
  // 16 - level are exactly these cells.
  budget.check("the map's surface cells");
  std::unordered_map<std::uint64_t, float> cells;
  std::uint64_t added = 0;
  const auto add = [&](const octomap::OcTreeKey& k, float mobility) {
    const std::uint64_t key = (static_cast<std::uint64_t>(k[2] >> level) << 32) |
                              (static_cast<std::uint64_t>(k[1] >> level) << 16) | static_cast<std::uint64_t>(k[0] >> level);
    const auto [it, inserted] = cells.emplace(key, mobility);
    if (!inserted && mobility == mobility && !(it->second <= mobility)) it->second = mobility;  // lowest known
    // A pruned block can cover billions of cells: the count and the time are checked as
    // they grow.
    if (++added % 65536 == 0) budget.check("the map's surface cells");
    return cells.size() <= most;
  };
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) {
    if (!tree.isNodeOccupied(*it)) continue;
    const float m = it->hasMobility() ? it->mobility() : std::numeric_limits<float>::quiet_NaN();
    const double size = it.getSize();
    const octomap::point3d c = it.getCoordinate();
    if (size <= cell) {
      if (!add(tree.coordToKey(c), m)) return std::nullopt;
      continue;
    }
    // A pruned block larger than a cell: every cell it covers.
    const int n = static_cast<int>(std::lround(size / cell));
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j)
        for (int k = 0; k < n; ++k) {
          const octomap::point3d p(static_cast<float>(c.x() - size / 2 + cell * (i + 0.5)),
                                   static_cast<float>(c.y() - size / 2 + cell * (j + 0.5)),
                                   static_cast<float>(c.z() - size / 2 + cell * (k + 0.5)));
          if (!add(tree.coordToKey(p), m)) return std::nullopt;
        }
  }
  std::vector<std::pair<std::uint64_t, float>> sorted(cells.begin(), cells.end());
  std::sort(sorted.begin(), sorted.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<Cell> out;
  out.reserve(sorted.size());
  const double half_keys = 32768.0;
  const auto centre = [&](std::uint64_t index) { return (static_cast<double>(index) + 0.5) * cell - half_keys * res; };
  for (const auto& [key, m] : sorted) {
    out.push_back({Eigen::Vector3d(centre(key & 0xffff), centre((key >> 16) & 0xffff), centre(key >> 32)), m});
  }
  return out;
}

namespace {

// A request that cannot be answered: its status and message.
struct Refusal : std::runtime_error {
  int status;
  Refusal(int s, const std::string& message) : std::runtime_error(message), status(s) {}
};

Response json(const nlohmann::json& j, int status = 200) { return {status, "application/json", text(j)}; }

// Bounded before parsing (util/json_limits.hpp): nesting, which the error messages
// and copies below would recurse through, and the number of values, which sets the
// parsed document's memory (a few tens of bytes each).
nlohmann::json parseBody(const std::string& body, const Limits& limits) {
  util::JsonLimits bounds;
  bounds.max_depth = limits.max_json_depth;
  bounds.max_values = limits.max_json_values();
  if (const util::JsonLimitProblem problem = util::checkJsonLimits(body, bounds)) {
    if (problem.kind == util::JsonLimitProblem::Kind::kTooManyValues) {
      throw Refusal(413, "the request body holds " + problem.message + "; " + std::to_string(limits.max_batch) +
                             " points or soles (--max-batch) need fewer");
    }
    throw Refusal(400, "the request body is refused: " + problem.message);
  }
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(body);
  } catch (const nlohmann::json::exception& e) {
    throw Refusal(400, std::string("the request body is not JSON: ") + e.what());
  }
  if (!j.is_object()) throw Refusal(400, "the request body must be a JSON object");
  return j;
}

// `prefix` names the object the fields are in ("reach." for the fields of "reach").
void onlyKnownFields(const nlohmann::json& body, const std::vector<std::string>& known, const std::string& prefix = "") {
  for (const auto& [key, value] : body.items()) {
    if (std::find(known.begin(), known.end(), key) == known.end()) {
      std::string list;
      for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
      throw Refusal(400, "unknown field \"" + prefix + key.substr(0, 100) + "\" (known: " + list + ")");
    }
  }
}

double finiteNumber(const nlohmann::json& v, const std::string& what) {
  if (!v.is_number()) throw Refusal(400, what + " must be a number, got " + text(v).substr(0, 100));
  const double d = v.get<double>();
  if (!std::isfinite(d)) throw Refusal(400, what + " must be finite");
  return d;
}

InputFrame frameOf(const nlohmann::json& body) {
  if (!body.contains("frame") || body["frame"].is_null()) return InputFrame::kMap;
  const nlohmann::json& f = body["frame"];
  if (f == "map") return InputFrame::kMap;
  if (f == "world") return InputFrame::kWorld;
  throw Refusal(400, "\"frame\" must be \"map\" or \"world\", got " + text(f).substr(0, 100));
}

// The snap distance: absent or null is none (-1).
double snapOf(const nlohmann::json& body) {
  if (!body.contains("snap") || body["snap"].is_null()) return -1;
  const double s = finiteNumber(body["snap"], "\"snap\"");
  if (s < 0) throw Refusal(400, "\"snap\" must be >= 0 metres");
  return s;
}

// `field` of `body`: an array of arrays of `n` finite numbers, at most `max` of them.
std::vector<std::vector<double>> rows(const nlohmann::json& body, const std::string& field, std::size_t n, std::size_t max) {
  if (!body.contains(field)) throw Refusal(400, "\"" + field + "\" is missing");
  const nlohmann::json& a = body[field];
  if (!a.is_array()) throw Refusal(400, "\"" + field + "\" must be an array");
  if (a.size() > max) {
    throw Refusal(413, "\"" + field + "\" holds " + std::to_string(a.size()) + " entries; at most " + std::to_string(max) +
                           " per request");
  }
  std::vector<std::vector<double>> out;
  out.reserve(a.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    const std::string what = field + "[" + std::to_string(i) + "]";
    if (!a[i].is_array() || a[i].size() != n) throw Refusal(400, what + " must be an array of " + std::to_string(n) + " numbers");
    std::vector<double> row(n);
    for (std::size_t k = 0; k < n; ++k) row[k] = finiteNumber(a[i][k], what + "[" + std::to_string(k) + "]");
    out.push_back(std::move(row));
  }
  return out;
}

Eigen::Vector3d point(const nlohmann::json& body, const std::string& field) {
  if (!body.contains(field)) throw Refusal(400, "\"" + field + "\" is missing");
  const nlohmann::json& a = body[field];
  if (!a.is_array() || a.size() != 3) throw Refusal(400, "\"" + field + "\" must be an array of 3 numbers");
  return {finiteNumber(a[0], field + "[0]"), finiteNumber(a[1], field + "[1]"), finiteNumber(a[2], field + "[2]")};
}

// `rows` x `cols` floats from values[first], row by row, as nested arrays, null where NaN,
// each number the shortest text that reads back as the same float.
void appendGrid(std::string& out, const std::vector<float>& values, std::size_t first, int rows, int cols) {
  char digits[32];
  std::size_t at = first;
  out += '[';
  for (int j = 0; j < rows; ++j) {
    out += j == 0 ? "[" : ",[";
    for (int i = 0; i < cols; ++i, ++at) {
      if (i > 0) out += ',';
      const float v = values[at];
      if (std::isnan(v)) {
        out += "null";
        continue;
      }
      const auto r = std::to_chars(digits, digits + sizeof digits, v);
      out.append(digits, r.ptr);
    }
    out += ']';
  }
  out += ']';
}

// A height scan's values as nested arrays (poses, ny, nx).
void appendScanValues(std::string& out, const std::vector<float>& values, const mapping::HeightScan& scan) {
  const std::size_t per_pose = static_cast<std::size_t>(scan.ny) * static_cast<std::size_t>(scan.nx);
  out += '[';
  for (std::size_t p = 0; p < scan.poses; ++p) {
    if (p > 0) out += ',';
    appendGrid(out, values, p * per_pose, scan.ny, scan.nx);
  }
  out += ']';
}

// A non-negative whole number from the query string.
std::optional<std::size_t> count(const std::multimap<std::string, std::string>& params, const std::string& name,
                                 std::size_t max) {
  const auto it = params.find(name);
  if (it == params.end()) return std::nullopt;
  const std::string& text = it->second;
  if (text.empty() || text.size() > 12 || text.find_first_not_of("0123456789") != std::string::npos) {
    throw Refusal(400, "query parameter " + name + " must be a whole number >= 0, got '" + text.substr(0, 40) + "'");
  }
  const unsigned long long v = std::strtoull(text.c_str(), nullptr, 10);
  if (v > max) throw Refusal(413, "query parameter " + name + " is " + text + "; at most " + std::to_string(max));
  return static_cast<std::size_t>(v);
}

// A request's "reach": true (start from the map's first camera position) or an object
// with "from" (in the request's frame), "start", "start_radius_m" and the robot's
// parameters, as `mobmap query --reach` takes them as options.
struct ReachRequest {
  mapping::ReachParams params;
  Eigen::Vector3d from_map = Eigen::Vector3d::Zero();
  std::string key;  // what the reachability depends on, for the cache
};

std::optional<ReachRequest> reachOf(const nlohmann::json& body, InputFrame frame, const mapping::MobilityMap& map,
                                    const std::vector<Eigen::Vector3d>& camera_path) {
  if (!body.contains("reach") || body["reach"].is_null() || body["reach"] == false) return std::nullopt;
  const nlohmann::json& r = body["reach"];
  if (!(r == true || r.is_object())) throw Refusal(400, "\"reach\" must be true or an object (from, start, start_radius_m, the robot's parameters)");
  ReachRequest q;
  std::optional<Eigen::Vector3d> from;
  std::string rule;
  std::optional<double> radius;
  if (r.is_object()) {
    std::vector<std::string> known{"from", "start", "start_radius_m"};
    const std::vector<std::string>& names = mapping::robotParameterNames();
    known.insert(known.end(), names.begin(), names.end());
    onlyKnownFields(r, known, "reach.");
    if (r.contains("from")) from = point(r, "from");
    if (r.contains("start")) {
      if (r["start"] != "nearest" && r["start"] != "largest-level") {
        throw Refusal(400, "\"reach.start\" must be \"nearest\" or \"largest-level\"");
      }
      rule = r["start"].get<std::string>();
    }
    if (r.contains("start_radius_m")) radius = finiteNumber(r["start_radius_m"], "\"reach.start_radius_m\"");
    for (const std::string& name : names) {
      if (r.contains(name)) mapping::setRobotParameter(q.params.robot, name, finiteNumber(r[name], "\"reach." + name + "\""));
    }
  }
  // The defaults of `mobmap query --reach`: from a given point, the nearest sole within
  // 0.5 m; from the camera, the largest level within 5 m.
  if (rule.empty()) rule = from ? "nearest" : "largest-level";
  q.params.start_rule = rule == "nearest" ? mapping::ReachParams::Start::kNearest : mapping::ReachParams::Start::kLargestLevel;
  q.params.start_radius_m = radius.value_or(from ? 0.5 : 5.0);
  try {
    mapping::validate(q.params);
  } catch (const std::invalid_argument& e) {
    throw Refusal(400, e.what());
  }
  if (from) {
    q.from_map = frame == InputFrame::kWorld ? map.worldToMap(*from) : *from;
  } else if (!camera_path.empty()) {
    q.from_map = camera_path.front();
  } else {
    throw Refusal(400, "\"reach\": the map has no camera path to start from; give reach.from");
  }
  nlohmann::json key{{"from", {q.from_map.x(), q.from_map.y(), q.from_map.z()}},
                     {"start", rule},
                     {"start_radius_m", q.params.start_radius_m}};
  const mapping::RobotParams& rp = q.params.robot;
  key["robot"] = {rp.sole_length_m, rp.sole_width_m, rp.min_mobility, rp.max_poor_fraction, rp.min_support_fraction,
                  rp.max_tilt_deg, rp.max_unevenness_m, rp.clearance_m, rp.max_step_m, rp.max_stride_m,
                  rp.swing_clearance_m, rp.max_gap_m, rp.stance_width_m, rp.lattice_m};
  q.key = key.dump();
  return q;
}

// Voxels a search of `metres` down a column visits (a column has 2^16).
double voxelsDown(double metres, double res) { return std::min(std::ceil(metres / res), 65536.0); }

// /api/layer's answers kept per map.
constexpr std::size_t kLayerCacheEntries = 4;
constexpr std::size_t kLayerCacheBytes = 64u << 20;
// The cells of one /api/voxels level asked for outright: at most this many pages.
constexpr std::size_t kMaxLevelCellsPerPage = 2;

// One of Limits::max_heavy_requests places, held until the request is answered.
class HeavySlot {
 public:
  HeavySlot() = default;
  HeavySlot(const HeavySlot&) = delete;
  HeavySlot& operator=(const HeavySlot&) = delete;
  ~HeavySlot() {
    if (count_) count_->fetch_sub(1);
  }
  bool take(std::atomic<std::size_t>& count, std::size_t most) {
    std::size_t n = count.load();
    while (n < most) {
      if (count.compare_exchange_weak(n, n + 1)) {
        count_ = &count;
        return true;
      }
    }
    return false;
  }
  [[nodiscard]] bool held() const { return count_ != nullptr; }

 private:
  std::atomic<std::size_t>* count_ = nullptr;
};

}  // namespace

// Answers kept by key, oldest first, within a count and a byte bound: each `keep` drops
// the oldest until the new one fits; one larger than the byte bound alone is not kept.
template <typename T>
struct Kept {
  std::vector<std::pair<std::string, std::shared_ptr<const T>>> entries;
  std::size_t bytes = 0;

  [[nodiscard]] std::shared_ptr<const T> find(const std::string& key) const {
    for (const auto& [k, v] : entries) {
      if (k == key) return v;
    }
    return nullptr;
  }
  void keep(const std::string& key, std::shared_ptr<const T> value, std::size_t value_bytes, std::size_t max_entries,
            std::size_t max_bytes, const std::function<std::size_t(const T&)>& size_of) {
    if (value_bytes > max_bytes || max_entries == 0 || find(key)) return;
    while (!entries.empty() && (entries.size() >= max_entries || bytes + value_bytes > max_bytes)) {
      bytes -= size_of(*entries.front().second);
      entries.erase(entries.begin());
    }
    entries.emplace_back(key, std::move(value));
    bytes += value_bytes;
  }
  void clear() {
    entries.clear();
    bytes = 0;
  }
};

struct Api::Cache {
  std::mutex mutex;
  // What the entries below were computed from. Not held: a live map's snapshot kept
  // here would make its mapper copy the map to fuse the next frame.
  std::weak_ptr<const ServedMap> served;
  std::optional<nlohmann::json> info;
  std::map<int, std::shared_ptr<const std::vector<Cell>>> cells;  // by level
  std::map<int, std::size_t> cells_over;  // level -> a count its cells are known to pass
  Kept<std::string> layers;                // /api/layer's answers by their query
  Kept<mapping::Reachability> reach;       // by ReachRequest::key
  // The soles judged per robot and the walks per start, shared by "reach" and plans.
  mapping::ReachCache soles;

  explicit Cache(std::size_t soles_bytes) : soles(soles_bytes) {}

  // Drops what belongs to an older map.
  void follow(const std::shared_ptr<const ServedMap>& s) {
    if (served.lock() == s) return;
    served = s;
    info.reset();
    cells.clear();
    cells_over.clear();
    layers.clear();
    reach.clear();
    soles.clear();
  }
  void keepReach(const std::string& key, std::shared_ptr<const mapping::Reachability> r, const Limits& limits) {
    const std::size_t bytes = r->memoryBytes();
    reach.keep(key, std::move(r), bytes, limits.max_reach_cache_entries, limits.max_reach_cache_bytes,
               [](const mapping::Reachability& x) { return x.memoryBytes(); });
  }
  void keepLayer(const std::string& key, std::shared_ptr<const std::string> answer) {
    const std::size_t bytes = answer->size();
    layers.keep(key, std::move(answer), bytes, kLayerCacheEntries, kLayerCacheBytes, [](const std::string& x) { return x.size(); });
  }
};

Api::Api(std::string map_label, const MapSource& source, Limits limits, mapping::ColourScale colours)
    : label_(std::move(map_label)),
      source_(source),
      limits_(limits),
      colours_(colours),
      cache_(std::make_shared<Cache>(limits.max_reach_cache_bytes)),
      state_(std::make_shared<State>()) {}

Api::ReachCacheFigures Api::reachCache() const {
  const std::lock_guard<std::mutex> lock(cache_->mutex);
  return {cache_->reach.entries.size(), cache_->reach.bytes};
}

// One request being answered: what it asks, the map it is answered on, and what answering
// it may use (its budget, a heavy slot, the caches). Each endpoint is one of its functions
// (the route table in Api::handle).
struct Api::Exchange {
  Exchange(const Api& api_, const std::string& path_, const std::multimap<std::string, std::string>& params_,
           const std::string& body_)
      : api(api_),
        path(path_),
        params(params_),
        body(body_),
        served(api_.source_.current()),
        map(*served->map),
        // Every request's work ends at this deadline, or when the server stops.
        budget(mapping::Budget::within(api_.limits_.max_request_s, &api_.state_->stop)) {}

  const Api& api;
  const std::string& path;
  const std::multimap<std::string, std::string>& params;
  const std::string& body;
  const std::shared_ptr<const ServedMap> served;
  const mapping::MobilityMap& map;
  const mapping::Budget budget;
  HeavySlot heavy;

  // One of the places for heavy requests (plans, reachability, large batches), or 503.
  void takeHeavySlot() {
    if (heavy.held()) return;
    if (!heavy.take(api.state_->heavy, api.limits_.max_heavy_requests)) {
      throw Refusal(503, "the server is answering " + std::to_string(api.limits_.max_heavy_requests) +
                             " heavy requests (plans, reachability, large batches), its most at once; try again shortly");
    }
  }

  // Where the robot can get to, worked out once per map and request of "reach" (the
  // cache keeps the last few), outside the cache's lock.
  std::shared_ptr<const mapping::Reachability> reachability(const std::optional<ReachRequest>& q) {
    if (!q) return nullptr;
    {
      const std::lock_guard<std::mutex> lock(api.cache_->mutex);
      api.cache_->follow(served);
      if (auto r = api.cache_->reach.find(q->key)) return r;
    }
    takeHeavySlot();
    std::shared_ptr<const mapping::Reachability> r;
    try {
      r = api.cache_->soles.reachability(map.surfaceColumns(), q->from_map, q->params, budget);
    } catch (const std::invalid_argument& e) {  // a step under two voxels of this map
      throw Refusal(400, std::string("\"reach\": ") + e.what());
    }
    if (!r->start()) {
      char text[300];
      std::snprintf(text, sizeof text,
                    "\"reach\": no place for a %.2f x %.2f m sole to stand (mobility >= %.2f) within %.2f m of (%.2f, "
                    "%.2f, %.2f) (map frame); give reach.from nearer a walkable surface, or a larger reach.start_radius_m",
                    q->params.robot.sole_length_m, q->params.robot.sole_width_m, q->params.robot.min_mobility,
                    q->params.start_radius_m, q->from_map.x(), q->from_map.y(), q->from_map.z());
      throw Refusal(400, text);
    }
    const std::lock_guard<std::mutex> lock(api.cache_->mutex);
    api.cache_->follow(served);
    api.cache_->keepReach(q->key, r, api.limits_);
    return r;
  }

  // The endpoints.
  Response info();
  Response batch();  // /api/query (points) and /api/foot (soles)
  Response heightScan();
  Response plan();
  Response layer();
  Response colours();
  Response voxels();
  Response cameraPath();
};

// GET /api/info: the map, its metadata, and the frames fused so far.
Response Api::Exchange::info() {
  std::optional<nlohmann::json> cached;
  {
    const std::lock_guard<std::mutex> lock(api.cache_->mutex);
    api.cache_->follow(served);
    cached = api.cache_->info;
  }
  nlohmann::json j = cached ? std::move(*cached) : infoJson(api.label_, map, served->metadata.get());
  if (!cached) {
    const std::lock_guard<std::mutex> lock(api.cache_->mutex);
    api.cache_->follow(served);
    api.cache_->info = j;
  }
  j["frames"] = served->frames;
  j["building"] = served->building;
  return json(j);
}

// POST /api/query and /api/foot.
Response Api::Exchange::batch() {
  // A batch of points (x y z) or soles (x y z yaw length width) in one frame, with
  // an optional snap distance and reachability.
  const bool soles = path == "/api/foot";
  const std::string field = soles ? "soles" : "points";
  const nlohmann::json b = parseBody(body, api.limits_);
  onlyKnownFields(b, {field, "frame", "snap", "reach"});
  const InputFrame frame = frameOf(b);
  const double snap = snapOf(b);
  const auto batch = rows(b, field, soles ? 6 : 3, api.limits_.max_batch);
  const std::optional<ReachRequest> reach_request = reachOf(b, frame, map, served->camera_path);
  // The work asked for, bounded before any is done (Limits::max_work).
  const double res = map.tree().getResolution();
  double work = 0;
  for (std::size_t i = 0; i < batch.size(); ++i) {
    if (soles) {
      const double length = batch[i][4], width = batch[i][5];
      try {
        checkSoleSize(length, width);
      } catch (const std::invalid_argument& e) {
        throw Refusal(400, "soles[" + std::to_string(i) + "]: " + e.what());
      }
      const double samples = std::ceil(length / res) * std::ceil(width / res);
      work += samples * (1 + voxelsDown(0.1 + (snap >= 0 ? snap : 0.1), res));
    } else {
      work += 1 + (snap >= 0 ? voxelsDown(snap, res) : 0);
    }
  }
  if (reach_request) work *= 2;
  if (work > api.limits_.max_work) {
    char message[400];
    std::snprintf(message, sizeof message,
                  "this request asks for about %.3g voxel look-ups (%zu entries of \"%s\"%s at %g m voxels), more than the %.3g one "
                  "request may: ask in smaller batches, with smaller soles or a smaller snap",
                  work, batch.size(), field.c_str(), snap >= 0 ? " with snap" : "", res, api.limits_.max_work);
    throw Refusal(413, message);
  }
  if (work > api.limits_.heavy_work) takeHeavySlot();
  const auto reach = reachability(reach_request);
  nlohmann::json answers = nlohmann::json::array();
  for (std::size_t i = 0; i < batch.size(); ++i) {
    if ((soles || (i & 1023u) == 0) && budget.exceeded()) budget.check(path.c_str());
    const auto& q = batch[i];
    if (!soles) {
      answers.push_back(toJson(answerPoint(map, {q[0], q[1], q[2]}, frame, snap, reach.get())));
      continue;
    }
    try {
      answers.push_back(toJson(answerFoot(map, {q[0], q[1], q[2], q[3], q[4], q[5]}, frame, snap, reach.get())));
    } catch (const std::invalid_argument& e) {
      throw Refusal(400, "soles[" + std::to_string(i) + "]: " + e.what());
    }
  }
  return json({{"answers", std::move(answers)}, {"frames", served->frames}});
}

// POST /api/height_scan.
Response Api::Exchange::heightScan() {
  // Heights and mobilities around many robot bases at once (mapping/height_scan.hpp).
  const nlohmann::json b = parseBody(body, api.limits_);
  onlyKnownFields(b, {"poses", "size", "resolution", "clearance", "frame"});
  const InputFrame frame = frameOf(b);
  const auto batch = rows(b, "poses", 4, api.limits_.max_batch);
  mapping::HeightScanGrid grid;
  if (b.contains("size") && !b["size"].is_null()) {
    const nlohmann::json& size = b["size"];
    if (!size.is_array() || size.size() != 2) throw Refusal(400, "\"size\" must be an array of 2 numbers (length, width)");
    grid.length_m = finiteNumber(size[0], "size[0]");
    grid.width_m = finiteNumber(size[1], "size[1]");
  }
  if (b.contains("resolution") && !b["resolution"].is_null()) grid.resolution_m = finiteNumber(b["resolution"], "\"resolution\"");
  if (b.contains("clearance") && !b["clearance"].is_null()) grid.clearance_m = finiteNumber(b["clearance"], "\"clearance\"");
  try {
    mapping::checkHeightScanGrid(grid, batch.size());
  } catch (const std::invalid_argument& e) {
    throw Refusal(400, e.what());
  }
  // The answer's size: about 20 bytes of JSON a point.
  const double points = static_cast<double>(batch.size()) * grid.nx() * grid.ny();
  const double max_points = 10.0 * static_cast<double>(api.limits_.max_batch);
  if (points > max_points) {
    char message[300];
    std::snprintf(message, sizeof message,
                  "this request asks for %.0f points (%zu poses x %d x %d); at most %.0f per request: ask in smaller "
                  "batches or a coarser grid",
                  points, batch.size(), grid.nx(), grid.ny(), max_points);
    throw Refusal(413, message);
  }
  if (points > api.limits_.heavy_work) takeHeavySlot();
  std::vector<mapping::HeightScanPose> poses;
  poses.reserve(batch.size());
  for (const auto& q : batch) {
    const Eigen::Vector3d c = frame == InputFrame::kWorld ? map.worldToMap({q[0], q[1], q[2]}) : Eigen::Vector3d(q[0], q[1], q[2]);
    poses.push_back({c.x(), c.y(), c.z(), frame == InputFrame::kWorld ? map.worldYawToMap(q[3]) : q[3]});
  }
  const mapping::HeightScan scan = map.heightScan(poses, grid);
  std::string out = "{\"nx\":" + std::to_string(scan.nx) + ",\"ny\":" + std::to_string(scan.ny) + ",\"height\":";
  out.reserve(out.size() + 24 * scan.height.size());
  appendScanValues(out, scan.height, scan);
  out += ",\"mobility\":";
  appendScanValues(out, scan.mobility, scan);
  out += ",\"frames\":" + std::to_string(served->frames) + "}";
  return {200, "application/json", std::move(out)};
}

// POST /api/plan.
Response Api::Exchange::plan() {
  const nlohmann::json b = parseBody(body, api.limits_);
  // The robot and the search by the names of mobmap.plan's keyword arguments in Python.
  mapping::PlanParams plan_params;
  std::vector<std::string> known{"from", "to", "frame"};
  const std::vector<std::string>& names = mapping::planParameterNames();
  known.insert(known.end(), names.begin(), names.end());
  onlyKnownFields(b, known);
  for (const std::string& name : names) {
    if (!b.contains(name)) continue;
    try {
      mapping::setPlanParameter(plan_params, name, finiteNumber(b[name], "\"" + name + "\""));
    } catch (const std::invalid_argument& e) {
      throw Refusal(400, e.what());
    }
  }
  if (plan_params.time_limit_s > api.limits_.max_plan_time_s) {
    char message[120];
    std::snprintf(message, sizeof message, "\"time_limit_s\" may be at most %g s on this server", api.limits_.max_plan_time_s);
    throw Refusal(400, message);
  }
  try {
    mapping::validate(plan_params);
  } catch (const std::invalid_argument& e) {
    throw Refusal(400, e.what());
  }
  const InputFrame frame = frameOf(b);
  const Eigen::Vector3d from_in = point(b, "from"), to_in = point(b, "to");
  const bool world = frame == InputFrame::kWorld;
  const Eigen::Vector3d from = world ? map.worldToMap(from_in) : from_in;
  const Eigen::Vector3d to = world ? map.worldToMap(to_in) : to_in;
  mapping::Plan plan;
  takeHeavySlot();
  try {
    // The plan's own time limit (at most max_plan_time_s) bounds it; the budget stops it
    // when the server stops.
    mapping::Budget stop;
    stop.stop = &api.state_->stop;
    {
      const std::lock_guard<std::mutex> lock(api.cache_->mutex);
      api.cache_->follow(served);
    }
    plan = mapping::planFootsteps(map.surfaceColumns(), from, to, plan_params, stop, &api.cache_->soles);
  } catch (const mapping::PlanInputError& e) {
    throw Refusal(400, e.what());
  } catch (const std::invalid_argument& e) {
    throw Refusal(400, e.what());
  }
  return json(planJson(map, plan, plan_params, frame));
}

// GET /api/layer.
Response Api::Exchange::layer() {
  // A level's elevation and mobility on a grid (mapping/layers.hpp), for the viewer.
  const std::size_t max_cells = count(params, "max", 1000000).value_or(250000);
  if (max_cells == 0) throw Refusal(400, "query parameter max must be at least 1");
  const std::size_t k = count(params, "level", std::numeric_limits<std::uint32_t>::max()).value_or(0);
  // Answers are kept per map and query (a few, kLayerCacheBytes together): a viewer
  // asks the same level again and again.
  const std::string key = std::to_string(k) + "/" + std::to_string(max_cells);
  {
    const std::lock_guard<std::mutex> lock(api.cache_->mutex);
    api.cache_->follow(served);
    if (const auto answer = api.cache_->layers.find(key)) return {200, "application/json", *answer};
  }
  takeHeavySlot();  // up to a million cells over every column of the map
  const auto columns = map.surfaceColumns();
  const std::vector<mapping::LayerLevel> levels = mapping::layerLevels(*columns, 1.0);
  nlohmann::json listed = nlohmann::json::array();
  for (std::size_t i = 0; i < levels.size(); ++i) {
    listed.push_back({{"index", i}, {"z_m", levels[i].z_m}, {"share", levels[i].share}});
  }
  if (levels.empty()) {
    return json({{"levels", listed}, {"level", nullptr}, {"frames", served->frames}});
  }
  if (k >= levels.size()) {
    throw Refusal(400, "query parameter level must be below " + std::to_string(levels.size()) + " (the map's levels)");
  }
  budget.check("the level's layers");
  // The finest cell, a power of two voxels, that keeps the map's whole extent (and so
  // any level in it) within `max` cells, up to cells of 100 m.
  const double res = columns->resolution();
  const double extent = static_cast<double>(columns->columnsX() + 1) * static_cast<double>(columns->columnsY() + 1);
  int voxels = 1;
  while (extent / (static_cast<double>(voxels) * voxels) > static_cast<double>(max_cells) &&
         2 * voxels * res <= mapping::kMaxLayerCellM) {
    voxels *= 2;
  }
  const mapping::LevelLayers l = mapping::levelLayers(*columns, levels[k], voxels * res);
  std::string out = "{\"frames\":" + std::to_string(served->frames) + ",\"levels\":" + text(listed) +
                    ",\"level\":" + std::to_string(k);
  char head[256];
  std::snprintf(head, sizeof head, ",\"z_m\":%.6g,\"cell_m\":%.6g,\"x_min\":%.9g,\"y_min\":%.9g,\"cols\":%d,\"rows\":%d",
                l.level.z_m, l.cell_m, l.x_min, l.y_min, l.cols, l.rows);
  out += head;
  out += ",\"elevation\":";
  appendGrid(out, l.elevation, 0, l.rows, l.cols);
  out += ",\"mobility\":";
  appendGrid(out, l.mobility, 0, l.rows, l.cols);
  out += '}';
  auto answer = std::make_shared<const std::string>(std::move(out));
  {
    const std::lock_guard<std::mutex> lock(api.cache_->mutex);
    api.cache_->follow(served);
    api.cache_->keepLayer(key, answer);
  }
  return {200, "application/json", *answer};
}

// GET /api/voxels.
Response Api::Exchange::voxels() {
  const std::size_t most = api.limits_.max_voxels;
  const std::size_t max = count(params, "max", most).value_or(std::min<std::size_t>(200000, most));
  const std::optional<std::size_t> level_asked = count(params, "level", std::numeric_limits<std::uint32_t>::max());
  if (level_asked && *level_asked > 15) throw Refusal(400, "query parameter level must be 0 to 15 (the octree's depth)");
  const std::size_t offset = count(params, "offset", std::numeric_limits<std::uint32_t>::max()).value_or(0);
  const std::size_t limit = count(params, "limit", most).value_or(most);
  if (max == 0) throw Refusal(400, "query parameter max must be at least 1");
  // The finest level whose cells number at most `max`, unless one is asked for. A
  // level not worked out yet is worked out outside the cache's lock (light requests
  // never wait for it) in a heavy request's place, within the request's time, and
  // stops as soon as it has more cells than it may: `max` (a coarser level then
  // follows), or for a level asked outright kMaxLevelCellsPerPage pages of voxels.
  int level = level_asked ? static_cast<int>(*level_asked) : 0;
  const std::size_t most_cells = level_asked ? kMaxLevelCellsPerPage * most : max;
  std::shared_ptr<const std::vector<Cell>> cells;
  for (;; ++level) {
    bool over = false;
    {
      const std::lock_guard<std::mutex> lock(api.cache_->mutex);
      api.cache_->follow(served);
      const auto found = api.cache_->cells.find(level);
      if (found != api.cache_->cells.end()) cells = found->second;
      const auto passed = api.cache_->cells_over.find(level);
      over = !cells && passed != api.cache_->cells_over.end() && passed->second >= most_cells;
    }
    if (!cells && !over) {
      takeHeavySlot();
      auto computed = surfaceCellsWithin(map.tree(), level, most_cells, budget);
      const std::lock_guard<std::mutex> lock(api.cache_->mutex);
      api.cache_->follow(served);
      if (computed) {
        auto& entry = api.cache_->cells[level];
        if (!entry) entry = std::make_shared<const std::vector<Cell>>(std::move(*computed));
        cells = entry;
      } else {
        auto& passed = api.cache_->cells_over[level];
        passed = std::max(passed, most_cells);
        over = true;
      }
    }
    if (over && level_asked) {
      throw Refusal(413, "level " + std::to_string(level) + " of this map has more than " + std::to_string(most_cells) +
                             " surface cells, more than one request works out; ask for a coarser level");
    }
    if (!over && (level_asked || cells->size() <= max || level >= 15)) break;
    if (level >= 15) throw Refusal(413, "the map has more than " + std::to_string(max) + " surface cells at every level");
    cells.reset();
  }
  const std::size_t first = std::min(offset, cells->size());
  const std::size_t n = std::min(limit, cells->size() - first);
  // Written by hand: a million voxels go out as fast as they are counted.
  std::string v;
  v.reserve(n * 40 + 2);
  v += '[';
  char number[128];
  for (std::size_t i = first; i < first + n; ++i) {
    const Cell& c = (*cells)[i];
    int len = 0;
    if (c.mobility == c.mobility) {
      len = std::snprintf(number, sizeof number, "%s%.4f,%.4f,%.4f,%.3f", i == first ? "" : ",", c.centre.x(), c.centre.y(),
                          c.centre.z(), static_cast<double>(c.mobility));
    } else {
      len = std::snprintf(number, sizeof number, "%s%.4f,%.4f,%.4f,null", i == first ? "" : ",", c.centre.x(), c.centre.y(),
                          c.centre.z());
    }
    v.append(number, static_cast<std::size_t>(len));
  }
  v += ']';
  nlohmann::json head{{"frame", "map"},
                      {"frames", served->frames},
                      {"building", served->building},
                      {"level", level},
                      {"cell_size_m", map.tree().getResolution() * std::ldexp(1.0, level)},
                      {"total", cells->size()},
                      {"offset", first},
                      {"count", n}};
  head["next"] = first + n < cells->size() ? nlohmann::json(first + n) : nlohmann::json(nullptr);
  std::string out = text(head);
  out.pop_back();  // the closing brace: the voxels follow
  out += ",\"voxels\":";
  out += v;
  out += '}';
  return {200, "application/json", std::move(out)};
}

// GET /api/colours: the mobility colour scale the viewer draws with, as the pictures do.
Response Api::Exchange::colours() {
  nlohmann::json stops = nlohmann::json::array();
  for (const mapping::VoxelRgb& c : mapping::colourStops(api.colours_)) stops.push_back({c[0], c[1], c[2]});
  const mapping::VoxelRgb unknown = mapping::unknownRgb(api.colours_);
  return json({{"scale", mapping::toString(api.colours_)}, {"stops", std::move(stops)}, {"unknown", {unknown[0], unknown[1], unknown[2]}}});
}

// GET /api/camera_path: the camera positions, map frame.
Response Api::Exchange::cameraPath() {
  nlohmann::json positions = nlohmann::json::array();
  for (const Eigen::Vector3d& p : served->camera_path) positions.push_back({p.x(), p.y(), p.z()});
  return json({{"frame", "map"}, {"frames", served->frames}, {"positions", std::move(positions)}});
}

Response Api::handle(const std::string& method, const std::string& path,
                     const std::multimap<std::string, std::string>& params, const std::string& body) const {
  struct Route {
    const char* path;
    const char* method;
    Response (Exchange::*answer)();
  };
  static constexpr Route kRoutes[] = {
      {"/api/info", "GET", &Exchange::info},
      {"/api/voxels", "GET", &Exchange::voxels},
      {"/api/camera_path", "GET", &Exchange::cameraPath},
      {"/api/layer", "GET", &Exchange::layer},
      {"/api/colours", "GET", &Exchange::colours},
      {"/api/query", "POST", &Exchange::batch},
      {"/api/foot", "POST", &Exchange::batch},
      {"/api/plan", "POST", &Exchange::plan},
      {"/api/height_scan", "POST", &Exchange::heightScan},
  };
  try {
    const auto expect = [&](const char* m) {
      if (method != m) throw Refusal(405, path + " takes " + m + " requests, not " + method);
    };
    for (const Route& route : kRoutes) {
      if (path != route.path) continue;
      expect(route.method);
      Exchange exchange(*this, path, params, body);
      return (exchange.*route.answer)();
    }
    if (const ViewerAsset* asset = findViewerAsset(path)) {
      expect("GET");
      return {200, asset->content_type, std::string(asset->bytes, asset->size)};
    }
    std::string api_list;
    for (const char* m : {"GET", "POST"}) {
      api_list += std::string(api_list.empty() ? "" : "; ") + m;
      const char* sep = " ";
      for (const Route& route : kRoutes) {
        if (std::string(route.method) != m) continue;
        api_list += sep + std::string(route.path);
        sep = ", ";
      }
    }
    throw Refusal(404, "no such path: " + path.substr(0, 200) + " (the API: " + api_list + "; the viewer: GET /)");
  } catch (const Refusal& r) {
    return {r.status, "application/json", errorBody(r.what())};
  } catch (const mapping::BudgetExceeded& e) {
    const std::string why = state_->stop.load() ? "the server is stopping"
                                                : "the request ran past the " + std::to_string(static_cast<int>(limits_.max_request_s)) +
                                                      " s one request may take";
    return {503, "application/json", errorBody(why + " (" + e.what() + ")")};
  } catch (const std::bad_alloc&) {
    return {503, "application/json", errorBody("out of memory answering this request")};
  } catch (const std::exception& e) {
    return {500, "application/json", errorBody(std::string("internal error: ") + e.what())};
  }
}

}  // namespace mobmap::app::serve
