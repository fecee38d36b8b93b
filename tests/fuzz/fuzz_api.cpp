// libFuzzer target: `mobmap serve`'s API (serve::Api::handle) on any request. The first
// byte picks the path and method; the rest is the body, or the query string of
// /api/voxels and /api/layer (/api/height_scan and /api/layer: see kPaths). With bit 0x40 of the first byte set, the body is a valid request with the
// rest put as the value of one of its fields (the second byte picks which) inside arrays
// nested up to 76,500 deep (the third byte): nesting a recursion would overflow on.
// Every answer must be a status the API documents with a JSON body (or a viewer file):
// the server keeps serving whatever it is sent.
#include "serve/api.hpp"

#include "mobmap/mapping/mobility_map.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <cstdlib>
#include <map>
#include <memory>
#include <string>

namespace {

using namespace mobmap;

// A floor of 1 x 1 m with a step and a wall, 5 cm voxels, a few without mobility.
std::shared_ptr<const mapping::MobilityMap> smallMap() {
  auto tree = std::make_unique<mapping::MobilityOcTree>(0.05);
  for (int i = 0; i < 20; ++i) {
    for (int j = 0; j < 20; ++j) {
      const double z = i < 10 ? 0.0 : 0.15;
      auto* n = tree->updateNode(octomap::point3d(0.05f * i, 0.05f * j, static_cast<float>(z)), true);
      for (int k = 0; k < 5; ++k) n = tree->updateNode(octomap::point3d(0.05f * i, 0.05f * j, static_cast<float>(z)), true);
      if ((i * 20 + j) % 17 != 0) n->setMobility(i == 9 ? 0.1 : 0.9, 1.0, 3);
    }
  }
  for (int j = 0; j < 20; ++j)
    for (int k = 0; k < 10; ++k) {
      auto* n = tree->updateNode(octomap::point3d(1.0f, 0.05f * j, 0.05f * k), true);
      n->setMobility(0.0, 1.0, 2);
    }
  tree->updateInnerOccupancy();
  return std::make_shared<const mapping::MobilityMap>(std::move(tree), mapping::MapParams{}, Eigen::Matrix3d::Identity(),
                                                      Eigen::Vector3d(0.2, -0.1, 0.05));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const app::serve::MapSource source([] {
    app::serve::ServedMap s;
    s.map = smallMap();
    s.frames = 3;
    s.camera_path = {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0.5, 0, 1)};
    return s;
  }());
  static const app::serve::Api api("fuzz.ot", source, [] {
    app::serve::Limits l;
    l.max_batch = 2000;
    l.max_voxels = 100000;
    l.max_plan_time_s = 2;
    return l;
  }());
  if (size == 0) return 0;
  static const char* const kPaths[] = {"/api/query", "/api/foot", "/api/plan", "/api/voxels", "/api/info",
                                       "/api/camera_path", "/", "/nothing"};
  // /nothing and / with bit 0x20 set are the height scans and the layers (added after
  // the corpus was grown).
  std::string path = kPaths[data[0] % 8];
  if (data[0] & 0x20) {
    if (data[0] % 8 == 7) path = "/api/height_scan";
    if (data[0] % 8 == 6) path = "/api/layer";
  }
  const bool query_string = path == "/api/voxels" || path == "/api/layer";
  const std::string method = (data[0] & 0x80) ? "GET" : "POST";
  std::string rest(reinterpret_cast<const char*>(data + 1), size - 1);
  if ((data[0] & 0x40) && size >= 3) {
    // Where a value goes in a request each endpoint takes: @ is replaced.
    static const char* const kTemplates[] = {
        R"({"points": [[0.5, 0.5, 0.1]], "frame": @})",
        R"({"points": [[0.5, 0.5, 0.1]], "snap": @})",
        R"({"points": [[0.5, @, 0.1]]})",
        R"({"soles": [[0.5, 0.5, 0.1, 0, @, 0.12]]})",
        R"({"soles": [[0.5, 0.5, 0.1, 0, 0.25, 0.12]], "reach": {"max_step_m": @}})",
        R"({"points": [[0.5, 0.5, 0.1]], "reach": {"from": @}})",
        R"({"from": [0.2, 0.5, 0.1], "to": [0.8, 0.5, 0.1], "max_step_m": @})",
        R"({"from": @, "to": [0.8, 0.5, 0.1]})",
    };
    static const char* const kScanTemplates[] = {
        R"({"poses": [[0.5, 0.5, 0.3, @]]})",
        R"({"poses": [[0.5, 0.5, 0.3, 0]], "size": @})",
        R"({"poses": [[0.5, 0.5, 0.3, 0]], "resolution": @, "frame": "world"})",
    };
    const std::string t = path == "/api/height_scan" ? kScanTemplates[data[1] % 3] : kTemplates[data[1] % 8];
    const std::size_t depth = static_cast<std::size_t>(data[2]) * 300;
    const std::string value = std::string(depth, '[') + rest.substr(2) + std::string(depth, ']');
    rest = t.substr(0, t.find('@')) + value + t.substr(t.find('@') + 1);
  }
  std::multimap<std::string, std::string> params;
  if (query_string) {
    // "key=value&key=value"
    std::size_t at = 0;
    while (at <= rest.size()) {
      const std::size_t end = std::min(rest.find('&', at), rest.size());
      const std::string pair = rest.substr(at, end - at);
      const std::size_t eq = pair.find('=');
      if (eq != std::string::npos) params.emplace(pair.substr(0, eq), pair.substr(eq + 1));
      at = end + 1;
    }
  }
  const app::serve::Response r = api.handle(method, path, params, query_string ? std::string() : rest);
  const bool documented =
      r.status == 200 || r.status == 400 || r.status == 404 || r.status == 405 || r.status == 413 || r.status == 503;
  if (!documented) std::abort();  // 500 is an internal error: a bug
  if (r.content_type == "application/json" && nlohmann::json::parse(r.body, nullptr, false).is_discarded()) std::abort();
  return 0;
}
