// A downstream project, as a footstep planner would use mobmap: links mobmap::mapping
// (and through it gp and perception), mobmap::sources and mobmap::builder, opens a map
// `mobmap build` wrote and asks it about a foot placement, then reads the frames it was
// built from and maps them itself, and builds the map again through the builder.
#include <mobmap/gp/mobility_model.hpp>
#include <mobmap/mapping/gravity.hpp>
#include <mobmap/mapping/mobility_map.hpp>
#include <mobmap/mapping/footstep_planner.hpp>
#include <mobmap/mapping/live_mapper.hpp>
#include <mobmap/mapping/reachability.hpp>
#include <mobmap/sources/sequence.hpp>
#include <mobmap/builder/map_builder.hpp>

#include <cmath>
#include <cstdio>
#include <exception>
#include <fstream>
#include <iterator>
#include <string>

int main(int argc, char** argv) {
  // 7-Scenes redkitchen gravity: the map's z axis must come out pointing up.
  const Eigen::Vector3d g(-0.0089, 0.9044, 0.4265);
  const Eigen::Matrix3d r = mobmap::mapping::gravityAlignment(g);
  const Eigen::Vector3d down = r * g.normalized();
  const double score = mobmap::gp::MobilityModel().predict(5.0, 1.1).mobility;
  std::printf("down in map frame: %.6f %.6f %.6f, flat-ground score %.3f\n", down.x(), down.y(), down.z(), score);
  if (!(std::abs(down.z() + 1.0) < 1e-9 && score > 0.9)) return 1;
  if (argc < 2) return 0;
  // A map of the simulated corridor (2 frames): a 25 x 12 cm sole on the floor 2 m ahead
  // of the first camera, given in the world frame of the poses.
  try {
    const mobmap::mapping::MobilityMap map = mobmap::mapping::openMap(argv[1]);
    const Eigen::Vector3d at = map.worldToMap({2.0, 0.0, 0.0});
    const mobmap::mapping::Foot sole{at.x(), at.y(), at.z(), 0.0, 0.25, 0.12};
    const auto foot = map.footprint(sole);
    // Can a robot standing 0.5 m further along the floor walk there?
    const auto reach = mobmap::mapping::computeReachability(map.tree(), map.worldToMap({2.5, 0.0, 0.5}));
    const bool reachable = reach.sole(sole).reachable;
    // And footsteps from there back to the sole.
    const auto plan = mobmap::mapping::planFootsteps(map.tree(), map.worldToMap({2.5, 0.0, 0.0}), at);
    std::printf("%d frames; sole at 2 m: min mobility %.3f over %.0f %% known, %s; plan: %s, %zu footsteps\n",
                map.framesIntegrated(), foot.min_mobility, 100 * foot.known_fraction, reachable ? "reachable" : "NOT reachable",
                plan.found ? "found" : plan.reason.c_str(), plan.footsteps.size());
    if (!(map.framesIntegrated() == 2 && foot.known_fraction > 0.9 && foot.min_mobility > 0.9 && reachable && plan.found)) {
      return 1;
    }
    if (argc < 3) return 0;
    // The frames the map was built from, read by the library's readers and mapped here.
    const auto seq = mobmap::sources::openSequence(argv[2]);
    mobmap::mapping::LiveMapper::Config config;
    config.gravity_down_world = seq->gravityDown().value_or(Eigen::Vector3d(0, 0, -1));
    mobmap::mapping::LiveMapper mapper(config);
    for (const int n : seq->frames()) {
      mobmap::sources::Frame f = seq->load(n);
      mapper.push({std::move(*f.depth), seq->intrinsics(), *f.T_world_camera, n / 30.0});
    }
    mapper.finish();
    const auto live = mapper.snapshot();
    const Eigen::Vector3d c = live->worldToMap({2.0, 0.0, 0.0});
    const auto live_foot = live->footprint({c.x(), c.y(), c.z(), 0.0, 0.25, 0.12});
    std::printf("%s (%s): %zu frames mapped here; sole at 2 m: min mobility %.3f over %.0f %% known\n",
                argv[2], seq->format().c_str(), seq->frames().size(), live_foot.min_mobility, 100 * live_foot.known_fraction);
    if (!(seq->frames().size() == 2 && live->framesIntegrated() == 2 && live_foot.known_fraction > 0.9 &&
          live_foot.min_mobility > 0.9)) {
      return 1;
    }
    // The same frames through the builder: the map `mobmap build` wrote, byte for byte.
    mobmap::builder::BuildOptions options;
    options.input = argv[2];
    options.out = std::string(argv[1]) + ".library.ot";
    options.force = true;
    const mobmap::builder::BuildReport report = mobmap::builder::buildMap(options);
    const auto bytes = [](const std::string& path) {
      std::ifstream in(path, std::ios::binary);
      return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    };
    const bool same = bytes(options.out) == bytes(argv[1]);
    std::printf("buildMap: %d frames fused, %s the CLI's map\n", report.frames_fused, same ? "the same bytes as" : "NOT");
    return report.frames_fused == 2 && same ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
}
