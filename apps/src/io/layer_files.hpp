#pragma once
// The files of `export --layers`: a GeoTIFF per level (GDAL), a nav2 map_server image
// and its YAML, and layers.json describing the set.

#include "mobmap/mapping/layers.hpp"

#include <string>

namespace mobmap::app {

/// The pixel values of the nav2 image (trinary mode, negate 0, thresholds 0.65 / 0.25:
/// occupancy = (255 - value) / 255).
inline constexpr int kNav2Free = 254, kNav2Occupied = 0, kNav2Unknown = 128;
inline constexpr double kNav2OccupiedThresh = 0.65, kNav2FreeThresh = 0.25;

/// Writes `layers` as a float32 GeoTIFF at `path`: one band per layer (mapping::layerNames(),
/// its name as the band's description), NaN as no data, the geotransform in the map frame
/// (origin at the top-left corner, negative y pixel size) in a local metre frame.
/// IoError naming `name` (default: `path`) with GDAL's message if it cannot.
void writeLayersGeoTiff(const std::string& path, const mapping::LevelLayers& layers, const std::string& name = "");

/// The nav2 map_server image of the traversable layer (free 254, occupied 0, unknown 128),
/// north up, as RGB with equal channels. `layers.traversable` must be filled.
void writeNav2Image(const std::string& path, const mapping::LevelLayers& layers);

/// The nav2 map_server YAML for the image named `image` (relative to the YAML's folder).
[[nodiscard]] std::string nav2Yaml(const std::string& image, const mapping::LevelLayers& layers);

}  // namespace mobmap::app
