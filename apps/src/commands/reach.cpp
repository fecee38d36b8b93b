// `mobmap reach`: which surfaces a robot can walk to from where it starts
// (mapping::computeReachability), in numbers and as a top view.
#include "commands/commands.hpp"
#include "io/files.hpp"
#include "io/io_error.hpp"
#include "mobmap/mapping/levels.hpp"
#include "io/map_files.hpp"
#include "commands/picture_options.hpp"
#include "commands/reach_options.hpp"
#include "pictures/top_view.hpp"

#include "mobmap/mapping/reachability.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <memory>

namespace mobmap::app {
namespace {

/// Standable places the robot cannot get to, in the pictures: a dark grey on viridis
/// (whose low end is purple), the purple of the red-green scale on that one.
Rgb unreachableColour(ColourScale scale) { return scale == ColourScale::kViridis ? Rgb{70, 70, 70} : Rgb{150, 70, 210}; }

/// A surface that cannot be stood on: its colour washed out, so what is reachable stands out.
Rgb pale(const Rgb& c) {
  Rgb out;
  for (std::size_t i = 0; i < 3; ++i) out[i] = static_cast<std::uint8_t>((c[i] * 2 + 255 * 3) / 5);
  return out;
}

}  // namespace

Command addReachCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "reach", "Which walkable surfaces a robot can get to from where it starts, by steps and gaps it can manage");
  struct Options {
    std::string map, png, pcd, octovis, frame = "map";
    ReachOptions reach;
    int max_pixels = 1400;
    double max_z = std::numeric_limits<double>::infinity();
    bool json = false;
    ColourScale colours = ColourScale::kViridis;
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("MAP", o->map, "A .ot map written by `mobmap build`")->required();
  addReachOptions(*cmd, o->reach, "--input-frame");
  cmd->add_option("--input-frame", o->frame, "Frame of --from: map (gravity aligned) or world (the data's own)")
      ->check(CLI::IsMember({"map", "world"}))
      ->capture_default_str();
  cmd->add_option("--png", o->png,
                  "Top view of the highest surface per column (.png, .svg or .pdf): reachable in mobility colours, dark grey "
                  "(purple with --colours red-green) where it can be stood on but not reached, pale where it cannot be stood on")
      ->check(pictureFile());
  cmd->add_option("--pcd", o->pcd,
                  "Every surface (the top voxel of each run of occupied voxels in a column) at its top face, with fields "
                  "mobility (nan if unknown), standable and reachable (0 or 1: under a standable or reachable sole); map "
                  "frame, ASCII");
  cmd->add_option("--octovis", o->octovis,
                  "A ColorOcTree .ot for stock octovis, in the picture's colours: each place reachable in mobility colours, "
                  "dark grey (or purple) where it can be stood on but not reached, every other occupied voxel (walls, the voxels under a "
                  "place, places that cannot be stood on) pale");
  cmd->add_option("--max-pixels", o->max_pixels, "Longest side of the picture's map area (as export)")
      ->check(CLI::Range(64, 16384))
      ->capture_default_str();
  auto* max_z = cmd->add_option("--max-z", o->max_z,
                                "Top view: the highest surface at or below this height (map frame, metres), as export: "
                                "the floor under a table");
  addColoursOption(*cmd, o->colours);
  cmd->add_flag("--json", o->json, "One JSON object instead of the text");
  return [o, max_z]() {
    if (max_z->count() > 0 && o->png.empty()) throw UsageError("--max-z cuts the top view: it needs --png");
    if (!std::isfinite(o->max_z) && max_z->count() > 0) throw UsageError("--max-z must be a finite height in metres");
    resolveReachOptions(o->reach);
    refuseToOverwriteInputs({{"--png", o->png}, {"--pcd", o->pcd}, {"--octovis", o->octovis}}, mapFilesAsInputs(o->map));
    const OpenedMap opened = openMapFiles(o->map);
    const mapping::MapMetadata& metadata = opened.metadata;
    const mapping::MobilityMap& map = opened.map;
    const CameraPath camera = cameraPath(metadata);
    std::vector<Eigen::Vector2d> path = camera.xy();
    const ReachRun run = runReach(o->reach, map, o->map, o->frame == "world", camera);
    const mapping::Reachability& r = run.result;
    const Eigen::Vector3d& start = run.from;
    const std::string& rule = o->reach.rule;
    const mapping::FootPlace& s = r.footPlaces()[*r.start()];
    const double res = r.resolution(), cell_m2 = res * res;
    // Where the standable places that cannot be reached gather.
    std::map<long, std::size_t> bins;
    for (const mapping::Place& p : r.places()) {
      if (p.standable && !p.reachable) ++bins[std::lround(p.top_z / res)];
    }
    const std::size_t unreachable = r.standableCount() - r.reachableCount();
    const std::vector<mapping::Level> levels = mapping::gatherLevels(std::move(bins), res);
    const auto& q = o->reach.params;
    const std::string sparse = sparseStartNote(r, o->reach);
    if (o->json) {
      nlohmann::json j{{"start", {{"from", {start.x(), start.y(), start.z()}}, {"rule", rule}, {"place", {s.x, s.y, s.z}}, {"soles", r.startFeet().size()}}},
                       {"frame", "map"},
                       {"params",
                        {{"max_step_m", q.robot.max_step_m},
                         {"min_mobility", q.robot.min_mobility},
                         {"clearance_m", q.robot.clearance_m},
                         {"max_gap_m", q.robot.max_gap_m},
                         {"sole_length_m", q.robot.sole_length_m},
                         {"sole_width_m", q.robot.sole_width_m},
                         {"min_support_fraction", q.robot.min_support_fraction},
                         {"max_tilt_deg", q.robot.max_tilt_deg},
                         {"max_unevenness_m", q.robot.max_unevenness_m},
                         {"max_stride_m", q.robot.max_stride_m},
                         {"swing_clearance_m", q.robot.swing_clearance_m},
                         {"lattice_m", q.robot.lattice_m},
                         {"start_radius_m", q.start_radius_m}}},
                       {"standable", {{"places", r.standableCount()}, {"area_m2", r.standableCount() * cell_m2}}},
                       {"reachable", {{"places", r.reachableCount()}, {"area_m2", r.reachableCount() * cell_m2}}},
                       {"unreachable", {{"places", unreachable}, {"area_m2", unreachable * cell_m2}}}};
      if (const auto& level = r.startLevel()) {
        j["start"]["level"] = {{"z_m", level->z_m},
                               {"walkable_share", level->share},
                               {"walkable_near", level->walkable_near},
                               {"standable_near", level->standable_near}};
      }
      j["start"]["note"] = sparse.empty() ? nlohmann::json(nullptr) : nlohmann::json(sparse);
      j["unreachable_levels"] = nlohmann::json::array();
      for (const mapping::Level& l : levels) j["unreachable_levels"].push_back({{"z_m", l.z_m}, {"places", l.count}, {"share", l.share}});
      std::cout << j.dump() << "\n";
    } else {
      std::printf("start: the surface at (%.2f, %.2f, %.2f) m, map frame (%zu soles: %s within %.2f m of %s)\n", s.x, s.y,
                  s.z, r.startFeet().size(),
                  rule == "nearest" ? "the nearest place for a sole" : "every standable sole on the map's largest level",
                  q.start_radius_m, o->reach.from.empty() ? "the first camera position" : "--from");
      if (!sparse.empty()) std::fprintf(stderr, "note: %s\n", sparse.c_str());
      const auto& b = q.robot;
      const auto g = [](double v) { return mapping::formatLimit(v); };  // as given
      std::printf("robot: %s x %s m soles on mobility >= %s (%s %% of the sole on known surface, tilt up to %s deg, "
                  "unevenness up to %s m); steps up to %s m, strides up to %s m, swing %s m high, gaps up to %s m",
                  g(b.sole_length_m).c_str(), g(b.sole_width_m).c_str(), g(b.min_mobility).c_str(),
                  g(100 * b.min_support_fraction).c_str(), g(b.max_tilt_deg).c_str(), g(b.max_unevenness_m).c_str(),
                  g(b.max_step_m).c_str(), g(b.max_stride_m).c_str(), g(b.swing_clearance_m).c_str(), g(b.max_gap_m).c_str());
      if (b.clearance_m > 0) {
        std::printf(", needs %s m of clearance\n", g(b.clearance_m).c_str());
      } else {
        std::printf("\n");
      }
      const double standable = static_cast<double>(r.standableCount());
      std::printf("places to stand: %zu (%.2f m2)\n", r.standableCount(), standable * cell_m2);
      std::printf("reachable:       %zu (%.2f m2, %.1f %%)\n", r.reachableCount(), r.reachableCount() * cell_m2,
                  standable > 0 ? 100.0 * r.reachableCount() / standable : 0.0);
      std::printf("not reachable:   %zu (%.2f m2)", unreachable, unreachable * cell_m2);
      if (!levels.empty()) {
        std::printf(", gathered at");
        for (std::size_t i = 0; i < levels.size(); ++i) {
          std::printf("%s z = %.2f m (%.2f m2)", i ? "," : "", levels[i].z_m, levels[i].count * cell_m2);
        }
      }
      std::printf("\n");
    }
    if (!o->pcd.empty()) {
      std::string text = "# .PCD v0.7 - mobmap reach: places (top faces of runs of occupied voxels), map frame\n"
                         "VERSION 0.7\nFIELDS x y z mobility standable reachable\nSIZE 4 4 4 4 1 1\nTYPE F F F F U U\n"
                         "COUNT 1 1 1 1 1 1\nWIDTH " + std::to_string(r.places().size()) +
                         "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + std::to_string(r.places().size()) + "\nDATA ascii\n";
      char line[128];
      for (const mapping::Place& p : r.places()) {
        std::snprintf(line, sizeof line, "%.4f %.4f %.4f %.5f %d %d\n", p.x, p.y, p.top_z, p.has_mobility ? p.mobility : std::nan(""),
                      p.standable ? 1 : 0, p.reachable ? 1 : 0);
        text += line;
      }
      writeTextFileAtomically(o->pcd, text);
      if (!o->json) std::printf("wrote %s (%zu places)\n", o->pcd.c_str(), r.places().size());
    }
    if (!o->octovis.empty()) {
      mapping::saveOctovisColorTree(map.tree(), o->octovis,
                                    [&](const octomap::OcTreeKey& key, const mapping::MobilityOcTreeNode& node) -> mapping::VoxelRgb {
                                      const mapping::Place* p = r.placeAt(key);
                                      if (p && p->reachable) return mobilityColour(p->mobility, o->colours);
                                      if (p && p->standable) return unreachableColour(o->colours);
                                      return pale(mapping::mobilityRgb(node, o->colours));
                                    });
      if (!o->json) std::printf("wrote %s (open with octovis)\n", o->octovis.c_str());
    }
    if (o->png.empty()) return 0;
    TopView view;
    try {
      view = computeTopView(map.tree(), path, o->max_pixels, o->max_z, o->colours);
    } catch (const std::invalid_argument& e) {
      throw IoError(o->map, std::string("cannot draw a top view: ") + e.what());
    }
    requireSurfaceBelowCut(view, map.tree(), o->max_z);
    for (std::size_t i = 0; i < view.top.size(); ++i) {
      if (std::isinf(view.top[i])) continue;
      const mapping::Place* p = r.placeAt(view.top_key[i]);
      if (!p || !p->standable) {
        view.colour[i] = pale(view.colour[i]);
      } else if (!p->reachable) {
        view.colour[i] = unreachableColour(o->colours);
      }
    }
    TopViewPicture picture;
    char title[200];
    std::snprintf(title, sizeof title, "Reachable from the start: %.2f x %.2f m soles, steps up to %.2f m, mobility >= %.2f%s",
                  q.robot.sole_length_m, q.robot.sole_width_m, q.robot.max_step_m, q.robot.min_mobility,
                  q.robot.clearance_m > 0 ? ", with clearance" : "");
    picture.title = title;
    if (max_z->count() > 0) {
      std::snprintf(title, sizeof title, " (highest surface at or below z = %.2f m)", o->max_z);
      picture.title += title;
    }
    picture.path = std::move(path);
    picture.run_starts = camera.run_starts;
    picture.colours = o->colours;
    picture.swatches = {{unreachableColour(o->colours), "not reachable"},
                        {pale(mobilityColour(0.0, o->colours)), "cannot stand (pale)"}};
    picture.mark = Eigen::Vector2d(s.x, s.y);
    picture.mark_label = "start";
    const Picture c = drawTopView(view, picture, o->max_pixels);
    c.save(o->png);
    if (!o->json) {
      std::printf("wrote %s (%s; the highest surface per column: reachable in mobility colours, %s where it can be "
                  "stood on but not reached, pale where it cannot be stood on)\n",
                  o->png.c_str(), describeTopView(view, c, o->max_pixels).c_str(),
                  o->colours == ColourScale::kViridis ? "dark grey" : "purple");
    }
    return 0;
  };
}

}  // namespace mobmap::app
