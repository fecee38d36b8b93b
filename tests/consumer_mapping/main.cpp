// A footstep planner that only reads maps, linking mobmap::mapping alone: opens a map of
// the simulated corridor and asks about a sole on its floor and a plan to it.
#include <mobmap/mapping/footstep_planner.hpp>
#include <mobmap/mapping/mobility_map.hpp>
#include <mobmap/util/field_error.hpp>

#include <cstdio>
#include <exception>

int main(int argc, char** argv) {
  if (argc < 2) return 2;
  try {
    const mobmap::mapping::MobilityMap map = mobmap::mapping::openMap(argv[1]);
    const Eigen::Vector3d at = map.worldToMap({2.0, 0.0, 0.0});
    const auto foot = map.footprint({at.x(), at.y(), at.z(), 0.0, 0.25, 0.12});
    const auto plan = mobmap::mapping::planFootsteps(map.tree(), map.worldToMap({2.5, 0.0, 0.0}), at);
    // A limit out of its range names the field.
    bool named = false;
    try {
      mobmap::mapping::PlanParams bad;
      bad.robot.max_step_m = -1;
      mobmap::mapping::validate(bad);
    } catch (const mobmap::util::FieldError& e) {
      named = e.field() == "max_step_m";
    }
    std::printf("sole at 2 m: min mobility %.3f over %.0f %% known; plan %s; bad limit named: %s\n", foot.min_mobility,
                100 * foot.known_fraction, plan.found ? "found" : plan.reason.c_str(), named ? "yes" : "no");
    return foot.known_fraction > 0.9 && foot.min_mobility > 0.9 && plan.found && named ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
}
