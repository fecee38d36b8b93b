#include "commands/export_layers.hpp"

#include "io/cli_text.hpp"
#include "io/files.hpp"
#include "io/io_error.hpp"
#include "io/layer_files.hpp"
#include "pictures/top_view.hpp"

#include "mobmap/mapping/layers.hpp"
#include "mobmap/mapping/reachability.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>

namespace mobmap::app {
namespace {

// The levels --level names: floor (the one reach starts on), all, or the one nearest a
// height within 0.25 m.
std::vector<std::size_t> chosenLevels(const std::string& choice, const std::vector<mapping::LayerLevel>& levels,
                                      const mapping::Reachability& reach, const std::string& map_path) {
  std::string listed;
  for (const auto& l : levels) {
    char z[32];
    std::snprintf(z, sizeof z, "%s%.2f", listed.empty() ? "" : ", ", l.z_m);
    listed += z;
  }
  if (levels.empty()) throw std::runtime_error(map_path + ": the map has no walkable level (no surface of mobility >= 0.75)");
  if (choice == "all") {
    std::vector<std::size_t> all(levels.size());
    for (std::size_t k = 0; k < all.size(); ++k) all[k] = k;
    return all;
  }
  double z = 0;
  double within = 0.25;
  if (choice == "floor") {
    const std::optional<double> start = mapping::startHeight(reach);
    if (!start) {
      throw std::runtime_error(map_path + ": no level for the robot to start on (give --level all or a height; levels at z = " +
                               listed + " m)");
    }
    z = *start;
    within = std::numeric_limits<double>::infinity();
  } else {
    char* end = nullptr;
    z = std::strtod(choice.c_str(), &end);
    if (end == choice.c_str() || *end != '\0' || !std::isfinite(z)) {
      throw UsageError("--level must be floor, all or a height in metres, got '" + choice + "'");
    }
  }
  const std::size_t best = mapping::nearestLevel(levels, z);
  if (std::abs(levels[best].z_m - z) > within) {
    char msg[160];
    std::snprintf(msg, sizeof msg, ": no level at z = %.2f m (within 0.25 m); the levels are at z = ", z);
    throw UsageError(map_path + msg + listed + " m");
  }
  return {best};
}

nlohmann::json settingsJson(const LayersOptions& o, double cell_m) {
  nlohmann::json robot;
  const auto& r = o.reach.params.robot;
  robot["sole_length_m"] = r.sole_length_m;
  robot["sole_width_m"] = r.sole_width_m;
  robot["min_mobility"] = r.min_mobility;
  robot["max_step_m"] = r.max_step_m;
  robot["max_tilt_deg"] = r.max_tilt_deg;
  robot["max_unevenness_m"] = r.max_unevenness_m;
  robot["min_support_fraction"] = r.min_support_fraction;
  robot["max_poor_fraction"] = r.max_poor_fraction;
  robot["clearance_m"] = r.clearance_m;
  return {{"cell_m", cell_m}, {"level_clearance_m", o.clearance_m}, {"level", o.level}, {"robot", robot}};
}

// A level seen from above: the mobility colour of each cell shaded by the elevation's
// relief (light from the upper left, 45 degrees up), with contours and height labels.
Picture levelPicture(const mapping::LevelLayers& l, std::size_t index, int max_pixels, ColourScale scale) {
  TopView view;
  view.resolution = l.cell_m;
  view.columns = l.cols;
  view.rows = l.rows;
  view.x0 = l.x_min + l.cell_m / 2;
  view.y0 = l.y_min + l.cell_m / 2;
  const std::size_t n = static_cast<std::size_t>(l.cols) * static_cast<std::size_t>(l.rows);
  view.top.assign(n, -std::numeric_limits<double>::infinity());
  view.colour.assign(n, Rgb{255, 255, 255});
  view.top_key.assign(n, octomap::OcTreeKey(0, 0, 0));
  const auto elevationAt = [&](int col, int row_up, float fallback) {
    if (col < 0 || row_up < 0 || col >= l.cols || row_up >= l.rows) return fallback;
    const float e = l.elevation[l.index(l.rows - 1 - row_up, col)];
    return std::isnan(e) ? fallback : e;
  };
  const Eigen::Vector3d light = Eigen::Vector3d(-1, 1, std::sqrt(2.0)).normalized();
  for (int row_up = 0; row_up < l.rows; ++row_up) {
    for (int col = 0; col < l.cols; ++col) {
      const std::size_t at = l.index(l.rows - 1 - row_up, col);
      const float e = l.elevation[at];
      if (std::isnan(e)) continue;
      const std::size_t cell = view.cell(col, row_up);
      view.top[cell] = e;
      const double gx = (elevationAt(col + 1, row_up, e) - elevationAt(col - 1, row_up, e)) / (2 * l.cell_m);
      const double gy = (elevationAt(col, row_up + 1, e) - elevationAt(col, row_up - 1, e)) / (2 * l.cell_m);
      const double shade = std::max(0.0, Eigen::Vector3d(-gx, -gy, 1).normalized().dot(light));
      const Rgb base = mobilityColour(l.mobility[at], scale);
      const double k = 0.35 + 0.65 * shade / light.z();  // flat ground keeps its colour
      for (std::size_t c = 0; c < 3; ++c) {
        view.colour[cell][c] = static_cast<std::uint8_t>(std::clamp(base[c] * k, 0.0, 255.0));
      }
    }
  }
  TopViewPicture picture;
  char title[160];
  std::snprintf(title, sizeof title, "Level %zu at z = %.2f m: mobility, shaded by the elevation's relief", index, l.level.z_m);
  picture.title = title;
  picture.colours = scale;
  return drawTopView(view, picture, max_pixels);
}

}  // namespace

void addLayersOptions(CLI::App& cmd, LayersOptions& o) {
  cmd.add_option("--layers", o.dir,
                 "Write 2.5D layers per level into DIR: level_K.tif (GeoTIFF, float32 bands elevation, elevation_variance, "
                 "mobility, mobility_variance, step, slope_deg, known), level_K.yaml + level_K.png (nav2 map_server: free "
                 "where a sole stands and no neighbour is more than --max-step away), layers.json (docs/MAPPING.md)");
  o.cell_option = cmd.add_option("--cell", o.cell_m, "Layers: cell size in metres (default: the map's resolution)");
  o.options.push_back(o.cell_option);
  o.options.push_back(cmd.add_option("--level", o.level,
                                     "Layers: floor (the level reach starts on), all, or a level's height in metres")
                          ->capture_default_str());
  o.options.push_back(cmd.add_option("--level-clearance", o.clearance_m,
                                     "Layers: the robot's height; a surface it cannot stand under is elevation on the level "
                                     "below, one it fits under is a level of its own")
                          ->capture_default_str());
  o.options.push_back(cmd.add_flag("--layer-pictures", o.pictures,
                                   "Layers: also level_K_view.png, each level from above: mobility colours shaded by the "
                                   "elevation's relief, with height contours"));
  o.options.push_back(cmd.add_option("--layer-picture-format", o.picture_format,
                                     "Layers: the format of the level pictures, png, svg or pdf (level_K_view.svg ...)")
                          ->check(CLI::IsMember({"png", "svg", "pdf"}))
                          ->capture_default_str());
  addReachOptions(cmd, o.reach, "the map frame");
  for (CLI::Option* opt : o.reach.options) o.options.push_back(opt);
}

void resolveLayersOptions(LayersOptions& o) {
  if (o.dir.empty()) {
    for (const CLI::Option* opt : o.options) {
      if (opt->count() > 0) throw UsageError(opt->get_name() + " is a setting of the layers: it needs --layers DIR");
    }
    return;
  }
  if (!std::isfinite(o.clearance_m) || !(o.clearance_m > 0) || o.clearance_m > 100) {
    throw UsageError("--level-clearance must be a height in (0, 100] m");
  }
  if (o.cell_option->count() > 0 && (!std::isfinite(o.cell_m) || !(o.cell_m > 0) || o.cell_m > mapping::kMaxLayerCellM)) {
    char msg[128];
    std::snprintf(msg, sizeof msg, "--cell must be from the map's resolution to %g m", mapping::kMaxLayerCellM);
    throw UsageError(msg);
  }
  resolveReachOptions(o.reach);
}

void exportLayers(const LayersOptions& o, const OpenedMap& opened, const std::string& map_path) {
  const mapping::MobilityMap& map = opened.map;
  const auto columns = map.surfaceColumns();
  const double res = columns->resolution();
  const double cell = o.cell_m == 0 ? res : o.cell_m;
  try {
    mapping::checkLayerCell(cell, res);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--cell: ") + e.what());
  }
  // Where a sole stands (the nav2 image) and the level the robot starts on.
  // Without a start (no --from, no camera path) the standable soles are still found; only
  // --level floor needs one.
  const std::optional<Eigen::Vector3d> from = reachFrom(o.reach, map, false, cameraPath(opened.metadata));
  if (!from && o.level == "floor") {
    throw UsageError(map_path + ": no camera path in " + mapping::mapFileStem(map_path) +
                     ".json to find the floor from; give --from X Y Z, --level all or a height");
  }
  mapping::Reachability reach;
  try {
    reach = mapping::computeReachability(columns, from.value_or(Eigen::Vector3d::Zero()), o.reach.params);
  } catch (const std::invalid_argument& e) {
    throw UsageError(cliText(e));
  }
  const std::vector<mapping::LayerLevel> levels = mapping::layerLevels(*columns, o.clearance_m);
  const std::vector<std::size_t> chosen = chosenLevels(o.level, levels, reach, map_path);

  std::vector<mapping::LevelLayers> made;
  for (std::size_t k : chosen) {
    try {
      made.push_back(mapping::levelLayers(*columns, levels[k], cell, &reach));
    } catch (const std::length_error& e) {
      throw UsageError(std::string("--cell: ") + e.what());
    }
  }
  const std::filesystem::path dir(o.dir);
  nlohmann::json index = settingsJson(o, cell);
  index["format"] = "mobmap-layers";
  index["map"] = map_path;
  index["frame"] = "map";
  index["levels"] = nlohmann::json::array();
  std::vector<PendingFile> files;
  for (std::size_t i = 0; i < made.size(); ++i) {
    const mapping::LevelLayers& l = made[i];
    const std::string stem = "level_" + std::to_string(chosen[i]);
    nlohmann::json entry{{"index", chosen[i]},
                         {"z_m", l.level.z_m},
                         {"share", l.level.share},
                         {"band", {{"min_top_m", std::isfinite(l.level.min_top_m) ? nlohmann::json(l.level.min_top_m) : nullptr},
                                   {"max_bottom_m", l.level.max_bottom_m}}},
                         {"extent", {{"x_min", l.x_min}, {"y_min", l.y_min}, {"x_max", l.x_min + l.cols * l.cell_m},
                                     {"y_max", l.y_min + l.rows * l.cell_m}, {"cols", l.cols}, {"rows", l.rows}}},
                         {"files", {{"geotiff", stem + ".tif"}, {"nav2_yaml", stem + ".yaml"}, {"nav2_image", stem + ".png"}}}};
    index["levels"].push_back(entry);
    const std::string tif = (dir / (stem + ".tif")).string(), png = (dir / (stem + ".png")).string(),
                      yaml = (dir / (stem + ".yaml")).string();
    if (l.cols == 0) continue;
    files.push_back({tif, [&l, tif](const std::string& tmp) { writeLayersGeoTiff(tmp, l, tif); }});
    files.push_back({png, [&l](const std::string& tmp) { writeNav2Image(tmp, l); }});
    files.push_back({yaml, [&l, stem](const std::string& tmp) { writeTextFileAtomically(tmp, nav2Yaml(stem + ".png", l)); }});
    if (o.pictures) {
      const std::size_t k = chosen[i];
      const std::string picture = stem + "_view." + o.picture_format;
      entry["files"]["picture"] = picture;
      index["levels"].back() = entry;
      const std::string path = (dir / picture).string();
      files.push_back({path, [&l, k, &o, path](const std::string& tmp) {
                         levelPicture(l, k, o.max_pixels, o.colours).save(tmp, pictureFormat(path), path);
                       }});
    }
  }
  files.push_back({(dir / "layers.json").string(), [&index](const std::string& tmp) { writeTextFileAtomically(tmp, index.dump(2) + "\n"); }});
  writeFilesTogether(files);
  for (const mapping::LevelLayers& l : made) {
    std::printf("level at z = %.2f m: %d x %d cells of %.3g m from (%.2f, %.2f)\n", l.level.z_m, l.cols, l.rows, l.cell_m,
                l.x_min, l.y_min);
  }
  std::printf("wrote %zu files into %s (layers.json lists them)\n", files.size(), o.dir.c_str());
}

}  // namespace mobmap::app
