// A downstream project, as a footstep planner would use mobmap: links mobmap::mapping
// (and through it gp and perception), opens a map `mobmap build` wrote and asks it
// about a foot placement.
#include <mobmap/gp/mobility_model.hpp>
#include <mobmap/mapping/gravity.hpp>
#include <mobmap/mapping/mobility_map.hpp>
#include <mobmap/mapping/footstep_planner.hpp>
#include <mobmap/mapping/reachability.hpp>

#include <cmath>
#include <cstdio>
#include <exception>

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
    return map.framesIntegrated() == 2 && foot.known_fraction > 0.9 && foot.min_mobility > 0.9 && reachable && plan.found ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
}
