#include "io/layer_files.hpp"

#include "io/io_error.hpp"
#include "io/png_io.hpp"

#include <cpl_error.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <mutex>

namespace mobmap::app {
namespace {

// GDAL's errors are read back and reported with the file's name, never printed.
void quietGdal() {
  static std::once_flag once;
  std::call_once(once, [] {
    GDALAllRegister();
    CPLSetErrorHandler(CPLQuietErrorHandler);
  });
}

std::string gdalProblem(const std::string& what) {
  const std::string message = CPLGetLastErrorMsg();
  return what + (message.empty() ? std::string() : ": " + message);
}

const char* unitOf(const std::string& layer) {
  if (layer == "elevation" || layer == "step") return "m";
  if (layer == "elevation_variance") return "m2";
  if (layer == "slope_deg") return "deg";
  return "";
}

}  // namespace

void writeLayersGeoTiff(const std::string& to, const mapping::LevelLayers& layers, const std::string& name) {
  const std::string& path = name.empty() ? to : name;
  quietGdal();
  CPLErrorReset();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
  if (driver == nullptr) throw IoError(path, "GDAL has no GeoTIFF driver");
  const auto& names = mapping::layerNames();
  char** options = CSLSetNameValue(nullptr, "COMPRESS", "DEFLATE");
  GDALDataset* raw = driver->Create(to.c_str(), layers.cols, layers.rows, static_cast<int>(names.size()), GDT_Float32, options);
  CSLDestroy(options);
  if (raw == nullptr) throw IoError(path, gdalProblem("cannot create the GeoTIFF"));
  std::unique_ptr<GDALDataset, void (*)(GDALDataset*)> ds(raw, [](GDALDataset* d) { GDALClose(d); });
  double transform[6] = {layers.x_min, layers.cell_m, 0.0, layers.y_min + layers.rows * layers.cell_m, 0.0, -layers.cell_m};
  OGRSpatialReference frame;
  frame.SetLocalCS("mobmap map frame (x right, y up, z up; gravity aligned)");
  frame.SetLinearUnits(SRS_UL_METER, 1.0);
  char* wkt = nullptr;
  frame.exportToWkt(&wkt);
  const bool placed = ds->SetGeoTransform(transform) == CE_None && ds->SetProjection(wkt) == CE_None;
  CPLFree(wkt);
  if (!placed) throw IoError(path, gdalProblem("cannot georeference the GeoTIFF"));
  char level[64];
  std::snprintf(level, sizeof level, "%.4f", layers.level.z_m);
  ds->SetMetadataItem("MOBMAP_LEVEL_Z_M", level);
  for (std::size_t b = 0; b < names.size(); ++b) {
    GDALRasterBand* band = ds->GetRasterBand(static_cast<int>(b) + 1);
    band->SetDescription(names[b].c_str());
    band->SetNoDataValue(std::numeric_limits<double>::quiet_NaN());
    band->SetUnitType(unitOf(names[b]));
    auto& values = const_cast<std::vector<float>&>(mapping::layerByName(layers, names[b]));
    if (band->RasterIO(GF_Write, 0, 0, layers.cols, layers.rows, values.data(), layers.cols, layers.rows, GDT_Float32, 0, 0) !=
        CE_None) {
      throw IoError(path, gdalProblem("cannot write band " + names[b]));
    }
  }
  GDALClose(ds.release());
  if (CPLGetLastErrorType() >= CE_Failure) {
    throw IoError(path, gdalProblem("cannot finish the GeoTIFF (disk full?)"));
  }
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
