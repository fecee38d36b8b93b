#pragma once
// `mobmap export --layers DIR`: 2.5D layers per level (mapping/layers.hpp) as a GeoTIFF,
// a nav2 map_server pair and layers.json.

#include "commands/reach_options.hpp"
#include "io/map_files.hpp"
#include "pictures/picture.hpp"

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace mobmap::app {

struct LayersOptions {
  std::string dir;
  double cell_m = 0;  ///< 0: the map's resolution
  std::string level = "floor";
  double clearance_m = 1.0;
  bool pictures = false;  ///< also level_K_view.png
  std::string picture_format = "png";  ///< png, svg or pdf
  ColourScale colours = ColourScale::kViridis;  ///< of the pictures
  int max_pixels = 1400;
  ReachOptions reach;
  std::vector<CLI::Option*> options;  ///< every option but --layers, which needs it
  CLI::Option* cell_option = nullptr;
};

/// Adds --layers, --cell, --level, --level-clearance and the robot's options of `reach`.
void addLayersOptions(CLI::App& cmd, LayersOptions& o);

/// Checks the options before the map is read: UsageError naming the problem.
void resolveLayersOptions(LayersOptions& o);

/// Writes the layers of the chosen levels into o.dir, all files or none, and prints
/// what it wrote. IoError / UsageError / std::runtime_error naming the problem.
void exportLayers(const LayersOptions& o, const OpenedMap& opened, const std::string& map_path);

}  // namespace mobmap::app
