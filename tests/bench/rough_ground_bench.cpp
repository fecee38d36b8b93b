// Rough ground from the fused fine surface (MapParams::fine_surface) against the frames'
// score alone, on a sequence `mobmap simulate` wrote: `mobmap build`'s library run with
// the fine surface off and on, alternating, and `mobmap evaluate`'s scores of each map;
// for each surface, the voxels scored as rough ground with their mean A/A' and mobility;
// fusion per frame and the map's memory (tree, occupied index, moments) of each.
//
//   rough_ground_bench SIM_DIR [FRAMES] [REPEATS] [MAPPING]
// FRAMES as build's --frames (0:239:2); MAPPING: more lines of the configuration's
// `mapping:` section for both runs, e.g. "fine_min_weight: 4".
#include "io/ground_truth.hpp"

#include "mobmap/builder/map_builder.hpp"
#include "mobmap/mapping/mobility_map.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <vector>

using namespace mobmap;

namespace {

struct Run {
  std::shared_ptr<const mapping::MobilityMap> map;
  builder::BuildReport report;
};

Run build(const std::string& input, const std::string& frames, bool fine, const std::filesystem::path& dir,
          const std::string& extra) {
  const std::filesystem::path config = dir / (fine ? "fine.yaml" : "frames.yaml");
  std::ofstream(config) << "mapping:\n  fine_surface: " << (fine ? "true" : "false") << "\n"
                        << (extra.empty() ? "" : "  " + extra + "\n");
  builder::BuildOptions o;
  o.input = input;
  o.frames = frames;
  o.out = (dir / (fine ? "fine.ot" : "frames.ot")).string();
  o.force = true;
  o.config = config.string();
  Run run;
  builder::BuildHooks hooks;
  hooks.saved = [&](std::shared_ptr<const mapping::MobilityMap> map, const mapping::MapMetadata&) { run.map = std::move(map); };
  run.report = builder::buildMap(o, hooks);
  return run;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: rough_ground_bench SIM_DIR [FRAMES] [REPEATS]\n");
    return 2;
  }
  const std::string input = argv[1];
  const std::string frames = argc > 2 ? argv[2] : "0:239:2";
  const int repeats = argc > 3 ? std::max(1, std::atoi(argv[3])) : 1;
  const std::string extra = argc > 4 ? argv[4] : "";
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("rough_ground_bench_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  // A simulated sequence has its ground truth; real data does not (then: how the maps differ).
  const std::filesystem::path truth_path = std::filesystem::path(input) / "ground_truth.json";
  const bool simulated = std::filesystem::exists(truth_path);
  const app::GroundTruth truth = simulated ? app::loadGroundTruth(truth_path.string()) : app::GroundTruth{};

  std::vector<double> fusion[2], frame_ms[2];
  Run last[2];
  for (int r = 0; r < repeats; ++r) {
    for (const bool fine : {false, true}) {
      Run run = build(input, frames, fine, dir, extra);
      fusion[fine].push_back(run.report.fusion_ms);
      double total = run.report.read_ms + run.report.fusion_ms;
      for (const auto& [stage, ms] : run.report.stage_ms) total += ms;
      frame_ms[fine].push_back(total);
      last[fine] = std::move(run);
    }
  }
  std::filesystem::remove_all(dir);

  std::printf("rough ground bench: %s, frames %s, %d repeat(s); per surface mean |mobility error| (evaluate: min count 3, "
              "tolerance 4 cm)\n\n",
              input.c_str(), frames.c_str(), repeats);
  if (!simulated) {
    // Surface voxels with a mobility, traversable (>= 0.5) or not, in each map; and of the
    // voxels scored as rough ground, those the frames had called traversable.
    for (int f = 0; f < 2; ++f) {
      const auto& tree = last[f].map->tree();
      std::size_t known = 0, below = 0;
      for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
        if (!tree.isNodeOccupied(*it) || !it->hasMobility()) continue;
        const std::size_t n = std::size_t{1} << (3 * (tree.getTreeDepth() - it.getDepth()));
        known += n;
        if (it->mobility() < 0.5) below += n;
      }
      std::printf("%s: %zu surface voxels with a mobility, %.2f %% below 0.5\n", f ? "fine  " : "frames", known,
                  known ? 100.0 * static_cast<double>(below) / static_cast<double>(known) : 0.0);
    }
    std::size_t turned = 0, level = 0;
    for (const mapping::RoughVoxel& v : last[1].map->roughVoxels()) {
      if (v.frames_mobility >= 0.5 && v.mobility < 0.5) {
        ++turned;
        if (std::getenv("ROUGH_DUMP")) std::printf("turned %.2f %.2f %.2f r %.2f s %.1f\n", v.centre.x(), v.centre.y(), v.centre.z(), v.roughness, v.slope_deg);
      }
      if (v.slope_deg < 10 && v.mobility < 0.5) ++level;
    }
    std::printf("rough ground: %zu voxels scored, %zu of them traversable by the frames and not now, %zu level (< 10 deg) "
                "and below 0.5\n",
                last[1].map->roughVoxels().size(), turned, level);
  }
  const app::Evaluation ev[2] = {app::evaluateMap(*last[0].map, truth, 3, 0.04), app::evaluateMap(*last[1].map, truth, 3, 0.04)};
  // The rough voxels by their nearest surface.
  struct Rough {
    int n = 0;
    double ratio = 0, mobility = 0, slope = 0;
  };
  std::map<int, Rough> rough;
  for (const mapping::RoughVoxel& v : last[1].map->roughVoxels()) {
    const Eigen::Vector3d p = last[1].map->mapToWorld(v.centre);
    const app::TruthSurface* best = nullptr;
    double best_d = 0.04;
    for (const auto& s : truth.surfaces) {
      const double d = s.distance(p);
      if (d <= best_d) best = &s, best_d = d;
    }
    if (!best) continue;
    if (std::getenv("ROUGH_DUMP") && best->name == std::getenv("ROUGH_DUMP") && v.mobility < 0.5)
      std::printf("dump %.3f %.3f %.3f r %.2f s %.1f m %.2f frames %.2f\n", p.x(), p.y(), p.z(), v.roughness, v.slope_deg, v.mobility, v.frames_mobility);
    Rough& r = rough[best->id];
    ++r.n, r.ratio += v.roughness, r.mobility += v.mobility, r.slope += v.slope_deg;
  }
  std::printf("%-26s %8s %9s %9s %7s | %7s %9s %9s %9s\n", "surface", "expected", "frames", "fine", "voxels", "rough",
              "A/A'", "slope", "mobility");
  for (std::size_t i = 0; i < ev[0].surfaces.size(); ++i) {
    const auto& a = ev[0].surfaces[i];
    const auto& b = ev[1].surfaces[i];
    if (a.voxels == 0 && b.voxels == 0) continue;
    const auto it = rough.find(a.surface->id);
    const Rough r = it == rough.end() ? Rough{} : it->second;
    std::printf("%-26s %8.2f %9.3f %9.3f %7d | %7d %9.3f %9.1f %9.3f\n", a.surface->name.c_str(), a.surface->expected_mobility,
                a.mean_abs_error, b.mean_abs_error, b.voxels, r.n, r.n ? r.ratio / r.n : 0.0, r.n ? r.slope / r.n : 0.0,
                r.n ? r.mobility / r.n : 0.0);
  }
  for (int f = 0; f < 2; ++f) {
    const int total = ev[f].true_traversable + ev[f].false_traversable + ev[f].true_untraversable + ev[f].false_untraversable;
    std::printf("%s: right side of 0.5 %.1f %% of %d voxels; edge voxels %d, mean |err| %.3f\n", f ? "fine  " : "frames",
                total ? 100.0 * (ev[f].true_traversable + ev[f].true_untraversable) / total : 0.0, total, ev[f].edge_voxels,
                ev[f].edge_mean_abs_error);
  }
  const mapping::RoughGroundReport& rep = last[1].map->roughGroundReport();
  std::printf("\nfine surface: %zu planes; of the surface voxels %zu on flat rectangles, %zu scored as rough ground, %zu too "
              "sparse and %zu too noisy to tell\n",
              rep.planes, rep.supported, rep.scored, rep.too_sparse, rep.too_noisy);
  std::printf("per frame (medians of %d): fusion %.2f / %.2f ms (%.2fx), read + perception + fusion %.1f / %.1f ms (%.3fx)\n", repeats,
              median(fusion[0]), median(fusion[1]), median(fusion[1]) / median(fusion[0]), median(frame_ms[0]),
              median(frame_ms[1]), median(frame_ms[1]) / median(frame_ms[0]));
  // finalize() again on copies of each map: what scoring rough ground adds to it.
  {
    std::vector<double> took[2];
    for (int r = 0; r < 3; ++r) {
      for (int f = 0; f < 2; ++f) {
        mapping::MobilityMap copy(*last[f].map);
        const auto start = std::chrono::steady_clock::now();
        copy.finalize();
        took[f].push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
      }
    }
    std::printf("finalize() (medians of 3): %.1f ms off, %.1f ms on\n", median(took[0]), median(took[1]));
  }
  // The fine run's map holds its moments; the saved map of either run has the same tree.
  const auto bytes = [](const mapping::MobilityMap& m) { return static_cast<double>(m.tree().memoryUsage()); };
  const double tree = bytes(*last[0].map), moments = static_cast<double>(last[1].map->fineSurfaceBytes());
  std::printf("memory: tree %.2f MB, moments %.2f MB (%zu voxels): %.2fx the tree\n", tree / 1e6, moments / 1e6,
              last[1].map->fineSurface().size(), (tree + moments) / tree);
  return 0;
}
