// Footstep planning on the simulated corridor: time and expansions of long plans, with
// the time of one whole-map reachability run (every sole, every step) in the same run as
// the reference, that run's two parts (judging the soles, once per map and robot; the
// walk, per start), and a refusal with the start's reachability kept in a ReachCache.
// Prints medians. Release builds only.
//
//   planning_bench [REPEATS] [HEURISTIC_WEIGHT]
//   planning_bench building [REPEATS] [HEURISTIC_WEIGHT] [SIZE_M]   the building of
//       tests/mapping/building_scene.hpp (40 m): its trips of ~10, 30 and 60 m
#include "mobmap/mapping/footstep_planner.hpp"
#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/mapping/reachability.hpp"
#include "mobmap/perception/pipeline.hpp"
#include "mobmap/sim/corridor_scene.hpp"
#include "../mapping/building_scene.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <vector>

using namespace mobmap;
using Clock = std::chrono::steady_clock;

namespace {

double ms(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double, std::milli>(b - a).count(); }

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

// FNV-1a over the footsteps' bits: equal prints mean byte-identical plans, so runs of
// two builds can be compared.
std::uint64_t footstepsHash(const mapping::Plan& plan) {
  std::uint64_t h = 1469598103934665603ull;
  const auto mix = [&](const void* p, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) h = (h ^ static_cast<const unsigned char*>(p)[i]) * 1099511628211ull;
  };
  for (const mapping::Footstep& f : plan.footsteps) {
    const int side = f.side == mapping::Side::kLeft ? 0 : 1;
    mix(&side, sizeof side);
    for (const double v : {f.x, f.y, f.z, f.yaw, f.min_mobility, f.mean_mobility, f.poor_fraction, f.tilt_deg}) mix(&v, sizeof v);
  }
  mix(&plan.cost, sizeof plan.cost);
  return h;
}

}  // namespace

// The building: time to make it, whole-map reachability and its parts, and each trip.
int buildingBench(int repeats, double weight, double size_m) {
  mapping::building::Params bp;
  bp.size_m = size_m;
  auto t0 = Clock::now();
  const mapping::building::Scene scene(bp);
  const double make_ms = ms(t0, Clock::now());
  t0 = Clock::now();
  const auto columns = std::make_shared<const mapping::SurfaceColumns>(scene.tree);
  std::printf("planning benchmark: the building, %.0f x %.0f m, two floors, %zu voxels (made in %.0f ms), %zu surface runs "
              "(%.0f ms, %.1f MB), one core, %d repeats, heuristic weight %.2f\n",
              size_m, size_m, static_cast<std::size_t>(scene.tree.getNumLeafNodes()), make_ms, columns->runs().size(),
              ms(t0, Clock::now()), columns->memoryBytes() / 1e6, repeats, weight);
  t0 = Clock::now();
  const auto standing = mapping::computeStandability(columns, {});
  const auto t1 = Clock::now();
  const auto reach = mapping::computeReachability(standing, scene.trips.front().from, {});
  std::printf("whole-map reachability: judging every sole %.0f ms (%zu foot places, %.1f MB kept), the walk %.0f ms; "
              "%zu of %zu surfaces reachable\n",
              ms(t0, t1), standing->footPlaces().size(), standing->memoryBytes() / 1e6, ms(t1, Clock::now()),
              reach.reachableCount(), reach.places().size());
  std::printf("%-52s %6s %9s %7s %11s %10s %9s %16s\n", "trip", "found", "length_m", "steps", "expansions", "median_ms", "cost",
              "footsteps_hash");
  for (const auto& trip : scene.trips) {
    mapping::PlanParams pp;
    pp.heuristic_weight = weight;
    std::vector<double> t;
    mapping::Plan plan;
    for (int i = 0; i < repeats; ++i) {
      const auto a = Clock::now();
      plan = mapping::planFootsteps(columns, trip.from, trip.to, pp);
      t.push_back(ms(a, Clock::now()));
    }
    std::printf("%-52s %6s %9.2f %7zu %11zu %10.1f %9.4f %016llx\n", trip.name.c_str(), plan.found ? "yes" : "no", plan.length_m,
                plan.footsteps.size() >= 2 ? plan.footsteps.size() - 2 : 0, plan.expansions, median(t), plan.cost,
                static_cast<unsigned long long>(footstepsHash(plan)));
    if (!plan.found) std::printf("    reason: %s\n", plan.reason.c_str());
  }
  return 0;
}

int main(int argc, char** argv) {
#ifndef NDEBUG
  std::fprintf(stderr, "warning: this is not a Release build; the numbers mean little\n");
#endif
  if (argc > 1 && std::strcmp(argv[1], "building") == 0) {
    return buildingBench(argc > 2 ? std::max(1, std::atoi(argv[2])) : 1, argc > 3 ? std::atof(argv[3]) : 1.25,
                         argc > 4 ? std::atof(argv[4]) : 40.0);
  }
  const int repeats = argc > 1 ? std::max(1, std::atoi(argv[1])) : 7;
  // The corridor walked to x = 8 (320 frames, Kinect noise with rounded edges), every
  // fourth frame fused: the map reaches the end wall at x = 10.
  sim::CorridorParams p;
  p.frames = 320;
  p.noise = sim::NoiseModel::kKinect;
  const sim::CorridorScene scene(p);
  const perception::FramePipeline pipeline;
  mapping::MobilityMap map;
  for (int f = 0; f < p.frames; f += 4) {
    const auto r = scene.render(f);
    const Eigen::Vector3f g = (r.T_world_camera.linear().transpose() * scene.gravityDown()).cast<float>();
    map.integrate(pipeline.process(r.depth, p.intrinsics, g), r.T_world_camera, &r.depth, &p.intrinsics);
  }
  map.finalize();
  const auto columns = std::make_shared<const mapping::SurfaceColumns>(map.tree());
  std::printf("planning benchmark: the corridor (%d frames fused), %zu surface runs, one core, %d repeats\n", p.frames / 4,
              columns->runs().size(), repeats);

  struct Case {
    const char* name;
    Eigen::Vector3d from, to;
    double max_step;
  };
  const std::vector<Case> cases = {
      {"along the corridor, 8.4 m", {1.0, 0.0, 0.0}, {9.4, 0.0, 0.0}, 0.15},
      {"corner to corner, past the box and the ramps", {1.2, 1.1, 0.0}, {9.4, -1.2, 0.0}, 0.15},
      {"up the stairs (20 cm steps)", {1.0, 0.0, 0.0}, {7.05, 0.9, 0.68}, 0.2},
      {"stairs refused (15 cm steps)", {1.0, 0.0, 0.0}, {7.05, 0.9, 0.68}, 0.15},
      {"far end to the top tread (20 cm steps)", {9.4, -1.2, 0.0}, {7.05, 0.9, 0.68}, 0.2},
  };
  std::vector<double> reach_ms;
  for (int i = 0; i < repeats; ++i) {
    const auto t0 = Clock::now();
    const auto r = mapping::computeReachability(columns, {1.0, 0.0, 0.05}, {});
    reach_ms.push_back(ms(t0, Clock::now()));
  }
  const double reach = median(reach_ms);
  std::printf("reference: computeReachability over the whole map: median %.1f ms\n", reach);
  {
    // Whole-map reachability split: the soles judged once per map and robot, then a walk
    // per start.
    std::vector<double> judge_ms, walk_ms;
    std::size_t bytes = 0;
    for (int i = 0; i < repeats; ++i) {
      const auto t0 = Clock::now();
      const auto standing = mapping::computeStandability(columns, {});
      const auto t1 = Clock::now();
      const auto r = mapping::computeReachability(standing, {2.0 + 0.1 * i, 0.0, 0.05}, {});
      walk_ms.push_back(ms(t1, Clock::now()));
      judge_ms.push_back(ms(t0, t1));
      bytes = standing->memoryBytes();
    }
    std::printf("  of which judging every sole (once per map and robot): median %.1f ms, %.1f MB kept; a walk from a new start: median %.1f ms\n",
                median(judge_ms), bytes / 1e6, median(walk_ms));
  }
  std::printf("%-48s %6s %9s %9s %11s %10s %8s %9s %16s\n", "plan", "found", "length_m", "steps", "expansions", "median_ms", "/reach",
              "cost", "footsteps_hash");
  const double weight = argc > 2 ? std::atof(argv[2]) : 1.0;
  std::printf("heuristic weight %.2f\n", weight);
  for (const Case& c : cases) {
    mapping::PlanParams pp;
    pp.heuristic_weight = weight;
    pp.robot.max_step_m = c.max_step;
    std::vector<double> t;
    mapping::Plan plan;
    for (int i = 0; i < repeats; ++i) {
      const auto t0 = Clock::now();
      plan = mapping::planFootsteps(columns, c.from, c.to, pp);
      t.push_back(ms(t0, Clock::now()));
    }
    std::printf("%-48s %6s %9.2f %9zu %11zu %10.1f %8.2f %9.4f %016llx\n", c.name, plan.found ? "yes" : "no", plan.length_m,
                plan.footsteps.size() >= 2 ? plan.footsteps.size() - 2 : 0, plan.expansions, median(t), median(t) / reach,
                plan.cost, static_cast<unsigned long long>(footstepsHash(plan)));
    if (!plan.found) std::printf("    reason: %s\n", plan.reason.c_str());
  }
  // A caller that keeps a ReachCache (the server, Python, a planner trying several goals):
  // the start's reachability worked out once, then each refusal is immediate.
  {
    const Case& c = cases[3];
    mapping::PlanParams pp;
    pp.heuristic_weight = weight;
    pp.robot.max_step_m = c.max_step;
    mapping::ReachCache cache;
    mapping::ReachParams rp;
    rp.robot = pp.robot;
    rp.start_radius_m = pp.start_radius_m + 0.5 * pp.robot.stance_width_m;
    (void)cache.reachability(columns, c.from, rp);
    std::vector<double> t;
    mapping::Plan plan;
    for (int i = 0; i < repeats; ++i) {
      const auto t0 = Clock::now();
      plan = mapping::planFootsteps(columns, c.from, c.to, pp, {}, &cache);
      t.push_back(ms(t0, Clock::now()));
    }
    std::printf("%-48s %6s %9s %9s %11zu %10.1f %8.2f\n", "stairs refused, the start's reach kept", plan.found ? "yes" : "no", "", "",
                plan.expansions, median(t), median(t) / reach);
  }
  return 0;
}
