#include "io/layer_files.hpp"

#include "io/geotiff_adapter.hpp"
#include "io/io_error.hpp"
#include "io/png_io.hpp"

#include "mobmap/util/plugin.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <mutex>

namespace mobmap::app {
namespace {

const char* unitOf(const std::string& layer) {
  if (layer == "elevation" || layer == "step") return "m";
  if (layer == "elevation_variance") return "m2";
  if (layer == "slope_deg") return "deg";
  return "";
}

// GDAL, opened when the first GeoTIFF is written.
const GeoTiffAdapter& geoTiff(const std::string& path) {
  static const GeoTiffAdapter* const loaded = [&] {
    try {
      return &util::pluginTable<GeoTiffAdapter>("geotiff", "mobmap_geotiff_adapter", kGeoTiffAdapterVersion);
    } catch (const std::runtime_error& e) {
      throw IoError(path, std::string("cannot be written: ") + e.what());
    }
  }();
  return *loaded;
}

}  // namespace

void writeLayersGeoTiff(const std::string& to, const mapping::LevelLayers& layers, const std::string& name) {
  GeoTiffRaster raster;
  raster.cols = layers.cols;
  raster.rows = layers.rows;
  raster.x_min = layers.x_min;
  raster.y_max = layers.y_min + layers.rows * layers.cell_m;
  raster.cell_m = layers.cell_m;
  raster.frame = "mobmap map frame (x right, y up, z up; gravity aligned)";
  char level[64];
  std::snprintf(level, sizeof level, "%.4f", layers.level.z_m);
  raster.metadata.emplace_back("MOBMAP_LEVEL_Z_M", level);
  for (const std::string& band : mapping::layerNames()) {
    raster.bands.push_back({band, unitOf(band), mapping::layerByName(layers, band).data()});
  }
  geoTiff(name.empty() ? to : name).write(to, raster, name);
}

void writeNav2Image(const std::string& path, const mapping::LevelLayers& layers) {
  ImageRgb image;
  image.width = layers.cols;
  image.height = layers.rows;
  image.pixels.resize(layers.traversable.size());
  for (std::size_t i = 0; i < layers.traversable.size(); ++i) {
    int v = kNav2Unknown;
    if (layers.traversable[i] == mapping::Traversable::kFree) v = kNav2Free;
    if (layers.traversable[i] == mapping::Traversable::kOccupied) v = kNav2Occupied;
    const auto g = static_cast<std::uint8_t>(v);
    image.pixels[i] = {g, g, g};
  }
  writePngRgb(path, image);
}

std::string nav2Yaml(const std::string& image, const mapping::LevelLayers& layers) {
  char text[512];
  std::snprintf(text, sizeof text,
                "image: %s\nmode: trinary\nresolution: %.6g\norigin: [%.6f, %.6f, 0.0]\nnegate: 0\n"
                "occupied_thresh: %.2f\nfree_thresh: %.2f\n",
                image.c_str(), layers.cell_m, layers.x_min, layers.y_min, kNav2OccupiedThresh, kNav2FreeThresh);
  return text;
}

}  // namespace mobmap::app
