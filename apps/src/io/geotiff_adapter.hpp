#pragma once
// The GeoTIFF writer, in the adapter libmobmap_geotiff.so (geotiff_gdal.cpp) that
// layer_files.cpp opens when `export --layers` first writes one (util/plugin.hpp): no
// other command loads GDAL and the ~100 libraries it brings.

#include <string>
#include <vector>

namespace mobmap::app {

/// Changes whenever GeoTiffAdapter or GeoTiffRaster does.
inline constexpr int kGeoTiffAdapterVersion = 1;

/// Float bands on a grid of square cells in a local metric frame, north up.
struct GeoTiffRaster {
  int cols = 0, rows = 0;
  double x_min = 0, y_max = 0, cell_m = 0;  ///< the top left corner and the cell side
  std::string frame;                         ///< the local frame's name
  std::vector<std::pair<std::string, std::string>> metadata;  ///< key, value
  struct Band {
    std::string name, unit;
    const float* values = nullptr;  ///< cols x rows, row 0 at y_max; NaN: no data
  };
  std::vector<Band> bands;
};

struct GeoTiffAdapter {
  int version;
  /// Writes `raster` to `to` (DEFLATE); IoError naming `name` (or `to`) on failure.
  void (*write)(const std::string& to, const GeoTiffRaster& raster, const std::string& name);
};

}  // namespace mobmap::app

extern "C" const mobmap::app::GeoTiffAdapter* mobmap_geotiff_adapter();
