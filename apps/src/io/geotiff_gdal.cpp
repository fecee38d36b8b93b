// mobmap's GeoTIFF adapter (libmobmap_geotiff.so, opened on demand: geotiff_adapter.hpp):
// GDAL writes the layers' bands, georeferenced in the map's local frame.
#include "io/geotiff_adapter.hpp"

#include "mobmap/sources/io_error.hpp"

#include <cpl_error.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <limits>
#include <memory>
#include <mutex>

namespace mobmap::app {
namespace {

using sources::IoError;

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

void write(const std::string& to, const GeoTiffRaster& raster, const std::string& name) {
  const std::string& path = name.empty() ? to : name;
  quietGdal();
  CPLErrorReset();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
  if (driver == nullptr) throw IoError(path, "GDAL has no GeoTIFF driver");
  char** options = CSLSetNameValue(nullptr, "COMPRESS", "DEFLATE");
  GDALDataset* raw = driver->Create(to.c_str(), raster.cols, raster.rows, static_cast<int>(raster.bands.size()), GDT_Float32, options);
  CSLDestroy(options);
  if (raw == nullptr) throw IoError(path, gdalProblem("cannot create the GeoTIFF"));
  std::unique_ptr<GDALDataset, void (*)(GDALDataset*)> ds(raw, [](GDALDataset* d) { GDALClose(d); });
  double transform[6] = {raster.x_min, raster.cell_m, 0.0, raster.y_max, 0.0, -raster.cell_m};
  OGRSpatialReference frame;
  frame.SetLocalCS(raster.frame.c_str());
  frame.SetLinearUnits(SRS_UL_METER, 1.0);
  char* wkt = nullptr;
  frame.exportToWkt(&wkt);
  const bool placed = ds->SetGeoTransform(transform) == CE_None && ds->SetProjection(wkt) == CE_None;
  CPLFree(wkt);
  if (!placed) throw IoError(path, gdalProblem("cannot georeference the GeoTIFF"));
  for (const auto& [key, value] : raster.metadata) ds->SetMetadataItem(key.c_str(), value.c_str());
  for (std::size_t b = 0; b < raster.bands.size(); ++b) {
    const GeoTiffRaster::Band& source = raster.bands[b];
    GDALRasterBand* band = ds->GetRasterBand(static_cast<int>(b) + 1);
    band->SetDescription(source.name.c_str());
    band->SetNoDataValue(std::numeric_limits<double>::quiet_NaN());
    band->SetUnitType(source.unit.c_str());
    if (band->RasterIO(GF_Write, 0, 0, raster.cols, raster.rows, const_cast<float*>(source.values), raster.cols, raster.rows,
                       GDT_Float32, 0, 0) != CE_None) {
      throw IoError(path, gdalProblem("cannot write band " + source.name));
    }
  }
  GDALClose(ds.release());
  if (CPLGetLastErrorType() >= CE_Failure) {
    throw IoError(path, gdalProblem("cannot finish the GeoTIFF (disk full?)"));
  }
}

const GeoTiffAdapter kAdapter{kGeoTiffAdapterVersion, &write};

}  // namespace
}  // namespace mobmap::app

extern "C" const mobmap::app::GeoTiffAdapter* mobmap_geotiff_adapter() { return &mobmap::app::kAdapter; }
