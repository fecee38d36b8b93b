#include "io/simulation_writer.hpp"

#include "io/dataset.hpp"
#include "io/files.hpp"
#include "io/io_error.hpp"
#include "io/png_io.hpp"

#include <atomic>
#include <chrono>
#include <exception>
#include <filesystem>
#include <mutex>
#include <thread>

namespace mobmap::app {
namespace {

nlohmann::json vec(const Eigen::Vector3d& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); }

}  // namespace

void countSurfacePixels(const sim::RenderedFrame& frame, std::vector<long long>& pixels_seen) {
  for (const std::uint16_t id : frame.labels) {
    if (id == 0) continue;
    if (id >= pixels_seen.size()) pixels_seen.resize(static_cast<std::size_t>(id) + 1, 0);
    ++pixels_seen[id];
  }
}

nlohmann::json groundTruthJson(const sim::CorridorScene& scene, const std::vector<long long>* pixels_seen) {
  using nlohmann::json;
  const auto& p = scene.params();
  json j;
  j["format"] = "mobmap-ground-truth";
  j["version"] = 1;
  j["scene"] = "corridor";
  j["frames"] = p.frames;
  j["frame_rate_hz"] = p.frame_rate_hz;
  j["seed"] = p.seed;
  j["noise"] = p.noise == sim::NoiseModel::kKinect ? "kinect" : "none";
  j["world_frame"] = "metres, z up, corridor along +x";
  j["gravity_down_world"] = vec(scene.gravityDown());
  j["intrinsics"] = {{"width", p.intrinsics.width}, {"height", p.intrinsics.height},
                     {"fx", p.intrinsics.fx},       {"fy", p.intrinsics.fy},
                     {"cx", p.intrinsics.cx},       {"cy", p.intrinsics.cy}};
  j["mobility_rule"] = "Genesio et al. Table I (paper rule table) at (slope_deg, roughness)";
  j["label_images"] = "frame-NNNNNN.labels.png: 16-bit surface id per pixel, 0 = nothing hit";
  json surfaces = json::array();
  for (const auto& s : scene.surfaces()) {
    json js;
    js["id"] = s.id;
    js["name"] = s.name;
    js["kind"] = sim::toString(s.kind);
    js["slope_deg"] = s.slope_deg;
    js["roughness"] = s.roughness;
    js["expected_mobility"] = s.expected_mobility;
    js["traversable"] = s.expected_mobility >= 0.5;
    js["moving"] = s.moving;
    if (pixels_seen) {
      const auto id = static_cast<std::size_t>(s.id);
      js["pixels_seen"] = id < pixels_seen->size() ? (*pixels_seen)[id] : 0;
    }
    js["normal"] = vec(s.normal);
    json polys = json::array();
    for (const auto& poly : s.polygons) {
      json jp = json::array();
      for (const auto& v : poly) jp.push_back(vec(v));
      polys.push_back(jp);
    }
    if (s.kind == sim::SurfaceKind::kRough && scene.params().layout == sim::Layout::kRoughYard) {
      js["geometry"] = {{"type", "rough_field"}, {"footprint", polys}, {"top_m", s.top_m}, {"description", s.description},
                        {"area_ratio", "exact: the field's true area over its footprint"}};
    } else if (s.kind == sim::SurfaceKind::kRough) {
      const auto& f = scene.roughPatch();
      js["geometry"] = {{"type", "pyramid_field"},
                        {"x0", f.x0}, {"y0", f.y0}, {"nx", f.nx}, {"ny", f.ny},
                        {"pitch_m", f.pitch_m}, {"height_m", f.height_m},
                        {"footprint", polys},
                        {"description", "one square pyramid of height height_m per pitch_m cell; "
                                        "area ratio sqrt(1 + (2 height_m / pitch_m)^2)"}};
    } else {
      js["geometry"] = {{"type", "polygons"}, {"polygons", polys},
                        {"note", s.moving ? "at start_frame position; see moving_obstacle" : ""}};
    }
    surfaces.push_back(js);
  }
  j["surfaces"] = surfaces;
  const auto& m = scene.movingObstacle();
  json ids = json::array();
  for (const auto& s : scene.surfaces()) {
    if (s.moving) ids.push_back(s.id);
  }
  j["moving_obstacle"] = {{"surface_ids", ids},      {"size_m", vec(m.size)},
                          {"from", vec(m.from)},      {"to", vec(m.to)},
                          {"start_frame", m.start_frame}, {"end_frame", m.end_frame},
                          {"description", "box footprint centre moves linearly from `from` to `to` "
                                          "between start_frame and end_frame"}};
  return j;
}

void writeSimulation(const sim::CorridorScene& scene, const std::string& dir, int threads,
                     const std::function<void(int)>& progress) {
  namespace fs = std::filesystem;
  const auto& p = scene.params();
  std::error_code ec;
  fs::create_directories(dir, ec);  // the sequence's own folder
  if (ec) throw IoError(dir, "cannot create the folder: " + ec.message());
  writeIntrinsicsFile((fs::path(dir) / "camera-intrinsics.txt").string(), p.intrinsics);
  writeGravityFile((fs::path(dir) / "gravity-direction.txt").string(), scene.gravityDown());

  std::atomic<int> next{0};
  std::vector<long long> pixels_seen;
  std::atomic<int> done{0};
  std::exception_ptr failure;
  std::mutex failure_mutex;
  auto worker = [&] {
    for (;;) {
      const int f = next.fetch_add(1);
      if (f >= p.frames) return;
      {
        std::lock_guard<std::mutex> lock(failure_mutex);
        if (failure) return;
      }
      try {
        const sim::RenderedFrame r = scene.render(f);
        {
          std::lock_guard<std::mutex> lock(failure_mutex);
          countSurfacePixels(r, pixels_seen);
        }
        const std::string stem = (fs::path(dir) / frameStem(f)).string();
        writeDepthPng(stem + ".depth.png", r.depth);
        writePoseFile(stem + ".pose.txt", r.T_world_camera.matrix());
        Image16 labels{p.intrinsics.width, p.intrinsics.height, r.labels};
        writePng16(stem + ".labels.png", labels);
        ImageRgb colour{p.intrinsics.width, p.intrinsics.height, r.colour};
        writePngRgb(stem + ".color.png", colour);
        done.fetch_add(1);
      } catch (...) {
        std::lock_guard<std::mutex> lock(failure_mutex);
        if (!failure) failure = std::current_exception();
        return;
      }
    }
  };
  std::vector<std::thread> pool;
  for (int i = 0; i < std::max(1, threads); ++i) pool.emplace_back(worker);
  int reported = -1;
  while (done.load() < p.frames) {
    {
      std::lock_guard<std::mutex> lock(failure_mutex);
      if (failure) break;
    }
    const int d = done.load();
    if (d != reported) {
      progress(d);
      reported = d;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  for (auto& t : pool) t.join();
  if (failure) std::rethrow_exception(failure);
  writeTextFileAtomically((fs::path(dir) / "ground_truth.json").string(),
                          groundTruthJson(scene, &pixels_seen).dump(1) + "\n");
  progress(done.load());
}

}  // namespace mobmap::app
