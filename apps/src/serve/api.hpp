#pragma once
// The HTTP API of `mobmap serve` as plain functions: a request (method, path, query
// parameters, body) in, a response (status, content type, body) out. The server
// (http_server.hpp) only carries them over sockets, so tests and fuzzers can call them
// directly.

#include "mobmap/mapping/budget.hpp"
#include "mobmap/mapping/map_metadata.hpp"
#include "mobmap/mapping/mobility_map.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace mobmap::app::serve {

/// The map a request is answered from, as one consistent whole.
struct ServedMap {
  std::shared_ptr<const mapping::MobilityMap> map;  ///< never null
  /// Its MAP.json, when it has one (a saved map; a live map once it is saved).
  std::shared_ptr<const mapping::MapMetadata> metadata;
  int frames = 0;                          ///< frames fused into the map so far
  std::vector<Eigen::Vector3d> camera_path;  ///< camera positions, map frame, one per frame
  bool building = false;                   ///< frames are still being fused (serve --live)
};

/// Where the served map comes from: a saved map, or a live one that changes as frames are
/// fused. Thread-safe: requests read it from the server's threads.
class MapSource {
 public:
  explicit MapSource(ServedMap initial);
  [[nodiscard]] std::shared_ptr<const ServedMap> current() const;
  void publish(ServedMap next);

 private:
  mutable std::mutex mutex_;
  std::shared_ptr<const ServedMap> current_;
};

struct Limits {
  std::size_t max_body_bytes = 16u << 20;  ///< request bodies larger than this: 413
  std::size_t max_batch = 100000;          ///< points or soles per request: 413
  std::size_t max_voxels = 2000000;        ///< voxels per /api/voxels page: 413
  double max_plan_time_s = 60.0;           ///< time_limit_s a plan request may ask for
  // The connections (http_server.cpp), docs/RELIABILITY.md:
  std::size_t max_connections = 64;             ///< served at once, in all; more: 503 at once
  double request_read_s = 10;                   ///< a request must arrive whole this soon after it begins
  double keep_alive_idle_s = 5;                 ///< an idle connection is closed after this
  double answer_write_s = 60;                   ///< an answer must be taken by the client this soon
  std::size_t large_body_bytes = 1u << 20;      ///< a body larger than this is large
  std::size_t max_large_bodies = 4;             ///< large bodies read and answered at once; more: 503
  std::size_t max_json_depth = 16;         ///< arrays and objects nested deeper in a body: 400
  // The work of one request (docs/RELIABILITY.md), counted in voxel look-ups: a point is
  // one, plus one per voxel of its snap distance; a sole one per sample (voxel) under it
  // times the voxels of its search height; twice that with "reach".
  double max_work = 2e8;             ///< a request asking for more: 413 before any is done (~10 s)
  double heavy_work = 2e6;           ///< a request asking for more, a plan, or a new reachability is heavy
  std::size_t max_heavy_requests = 2;  ///< heavy requests answered at once; more: 503
  double max_request_s = 60;         ///< a request still working after this: 503
  std::size_t max_reach_cache_entries = 4;       ///< reachabilities kept per map
  /// and their memory, at most; the soles judged for them and for plans (shared across
  /// starts, mapping::ReachCache) are kept within as much again
  std::size_t max_reach_cache_bytes = 512u << 20;
  /// Connections one client address may hold: a quarter of max_connections (16); more: 503 at once.
  [[nodiscard]] std::size_t max_connections_per_client() const { return std::max<std::size_t>(1, max_connections / 4); }
  /// Values (numbers, strings, arrays, objects) one body may hold: enough for max_batch
  /// soles of 6 numbers each and the other fields; more: 413 before the body is parsed.
  [[nodiscard]] std::size_t max_json_values() const { return 8 * max_batch + 1000; }
};

struct Response {
  int status = 200;
  std::string content_type = "application/json";
  std::string body;
};

/// Answers one request. Never throws: bad requests are 400 (malformed JSON, wrong
/// shapes, NaN or infinite numbers, unknown fields), 404 (unknown paths), 405 (a known
/// path with the wrong method) and 413 (batches over the limits), each with a JSON body
/// {"error": "..."}. `map_label` is the "map" field of /api/info.
class Api {
 public:
  /// `colours`: the scale GET /api/colours gives the viewer.
  Api(std::string map_label, const MapSource& source, Limits limits = {},
      mapping::ColourScale colours = mapping::ColourScale::kViridis);
  [[nodiscard]] Response handle(const std::string& method, const std::string& path,
                                const std::multimap<std::string, std::string>& params, const std::string& body) const;
  [[nodiscard]] const Limits& limits() const { return limits_; }
  /// Ends the work of every request being answered (503) and of every later one: for a
  /// server that is stopping. Any thread.
  void stopWork() const { state_->stop.store(true); }
  /// The reachabilities kept for "reach" and their memory (Limits::max_reach_cache_*).
  struct ReachCacheFigures {
    std::size_t entries = 0, bytes = 0;
  };
  [[nodiscard]] ReachCacheFigures reachCache() const;

 private:
  struct Cache;
  struct Exchange;  // one request being answered (api.cpp)
  struct State {
    std::atomic<bool> stop{false};
    std::atomic<std::size_t> heavy{0};  // heavy requests being answered
  };
  std::string label_;
  const MapSource& source_;
  Limits limits_;
  mapping::ColourScale colours_;
  std::shared_ptr<Cache> cache_;
  std::shared_ptr<State> state_;
};

/// Surface voxels on a grid of cells `level` times coarser than the map (cell side
/// resolution * 2^level): each cell that holds an occupied voxel, with the lowest known
/// mobility in it (as the tree's inner nodes keep it) or NaN. Cells in key order (z, y, x).
struct Cell {
  Eigen::Vector3d centre;
  float mobility;
};
std::vector<Cell> surfaceCells(const mapping::MobilityOcTree& tree, int level);
/// surfaceCells() that stops early: nullopt as soon as there are more than `most`
/// cells; BudgetExceeded when `budget` runs out first.
std::optional<std::vector<Cell>> surfaceCellsWithin(const mapping::MobilityOcTree& tree, int level, std::size_t most,
                                                    const mapping::Budget& budget);

/// The error body the API answers with.
std::string errorBody(const std::string& message);

}  // namespace mobmap::app::serve
