#include "commands/commands.hpp"
#include "io/ground_truth.hpp"
#include "io/map_files.hpp"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>
#include <memory>

namespace mobmap::app {

Command addEvaluateCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("evaluate", "Compare a map with the simulator's ground truth, surface by surface");
  struct Options {
    std::string map, truth;
    int min_count = 3;
    double tolerance = 0.04;
    bool json = false;
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("MAP", o->map, "A .ot map")->required();
  cmd->add_option("--truth", o->truth, "ground_truth.json written by `mobmap simulate`")->required();
  cmd->add_option("--min-count", o->min_count, "Only voxels observed at least this often")->capture_default_str();
  cmd->add_option("--tolerance", o->tolerance, "Max distance (m) from a voxel centre to its ground-truth surface")->capture_default_str();
  cmd->add_flag("--json", o->json, "One JSON object");
  return [o]() {
    const mapping::MobilityMap map = mapping::openMap(o->map);
    const GroundTruth truth = loadGroundTruth(o->truth);
    const Evaluation ev = evaluateMap(map, truth, o->min_count, o->tolerance);
    const int total = ev.true_traversable + ev.false_traversable + ev.true_untraversable + ev.false_untraversable;
    if (o->json) {
      nlohmann::json j;
      for (const auto& s : ev.surfaces) {
        j["surfaces"].push_back({{"id", s.surface->id}, {"name", s.surface->name}, {"expected_mobility", s.surface->expected_mobility},
                                 {"in_view", s.surface->seen},
                                 {"voxels", s.voxels}, {"mean_abs_error", s.mean_abs_error}, {"worst_abs_error", s.worst_abs_error},
                                 {"right_side_of_0_5", s.right_side}, {"area_observed_m2", s.area_observed_m2}});
      }
      j["unassigned_voxels"] = ev.unassigned;
      j["edge_voxels"] = {{"voxels", ev.edge_voxels}, {"mean_abs_error_nearest", ev.edge_mean_abs_error},
                          {"mean_abs_error_best", ev.edge_mean_abs_error_any}};
      j["confusion_at_0_5"] = {{"true_traversable", ev.true_traversable}, {"false_traversable", ev.false_traversable},
                               {"true_untraversable", ev.true_untraversable}, {"false_untraversable", ev.false_untraversable}};
      std::cout << j.dump() << "\n";
      return 0;
    }
    std::printf("%-4s %-24s %8s %7s %10s %10s %10s %9s\n", "id", "surface", "expected", "voxels", "mean |err|", "worst", "right side",
                "area m2");
    for (const auto& s : ev.surfaces) {
      if (s.voxels == 0) {
        std::printf("%-4d %-24s %8.2f %7s\n", s.surface->id, s.surface->name.c_str(), s.surface->expected_mobility,
                    s.surface->seen ? "unseen" : "never in view");
        continue;
      }
      std::printf("%-4d %-24s %8.2f %7d %10.3f %10.3f %9.1f%% %9.2f\n", s.surface->id, s.surface->name.c_str(),
                  s.surface->expected_mobility, s.voxels, s.mean_abs_error, s.worst_abs_error, 100 * s.right_side,
                  s.area_observed_m2);
    }
    if (ev.edge_voxels > 0) {
      std::printf("\n%d edge voxels (their cell also touches a surface with another answer; not in the rows above): "
                  "mean |err| %.3f against the nearest surface, %.3f against the best of those it touches\n",
                  ev.edge_voxels, ev.edge_mean_abs_error, ev.edge_mean_abs_error_any);
    }
    std::printf("\nconfusion at 0.5 over %d voxels: traversable %d correct / %d wrongly untraversable; "
                "untraversable %d correct / %d wrongly traversable; %d voxels off every surface\n",
                total, ev.true_traversable, ev.false_untraversable, ev.true_untraversable, ev.false_traversable, ev.unassigned);
    if (total) std::printf("right side of 0.5: %.1f %%\n", 100.0 * (ev.true_traversable + ev.true_untraversable) / total);
    return 0;
  };
}

}  // namespace mobmap::app
