// `mobmap export --layers` on the simulated corridor against its exact geometry
// (ground_truth.json): elevation within a voxel on floors, ramps, treads and the box
// top, steps at every riser and box edge and not on the floor, mobility as the map
// answers it, the nav2 image free on the floor and occupied on risers and steep ramps,
// the GeoTIFF read by GDAL (gdalinfo and the library), and bad settings refused.
#include "cli_support.hpp"

#include "mobmap/mapping/mobility_map.hpp"

#include <gdal_priv.h>

#include <optional>

namespace mobmap::cli_test {
namespace {

struct Surface {
  std::string kind;
  int id = 0;
  double slope_deg = 0;
  std::vector<std::vector<Eigen::Vector3d>> polygons;  // world frame
};

std::vector<Surface> truthSurfaces(const std::string& path) {
  std::vector<Surface> out;
  const auto j = nlohmann::json::parse(fileBytes(path));
  for (const auto& s : j["surfaces"]) {
    Surface surface{s["kind"], s["id"], s["slope_deg"], {}};
    if (s["geometry"]["type"] != "polygons") continue;
    for (const auto& poly : s["geometry"]["polygons"]) {
      std::vector<Eigen::Vector3d> p;
      for (const auto& v : poly) p.emplace_back(v[0], v[1], v[2]);
      surface.polygons.push_back(p);
    }
    out.push_back(surface);
  }
  return out;
}

// Whether (x, y) lies inside the convex polygon's outline seen from above, at least
// `margin` from its edges.
bool insideFromAbove(const std::vector<Eigen::Vector3d>& poly, double x, double y, double margin) {
  int sign = 0;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Eigen::Vector3d& a = poly[i];
    const Eigen::Vector3d& b = poly[(i + 1) % poly.size()];
    const double ex = b.x() - a.x(), ey = b.y() - a.y(), len = std::hypot(ex, ey);
    if (len < 1e-9) continue;
    const double cross = (ex * (y - a.y()) - ey * (x - a.x())) / len;  // signed distance
    if (sign == 0) sign = cross > 0 ? 1 : -1;
    if (cross * sign < margin) return false;
  }
  return true;
}

// The height of the polygon's plane at (x, y).
double heightAt(const std::vector<Eigen::Vector3d>& poly, double x, double y) {
  const Eigen::Vector3d n = (poly[1] - poly[0]).cross(poly[2] - poly[0]).normalized();
  return poly[0].z() - (n.x() * (x - poly[0].x()) + n.y() * (y - poly[0].y())) / n.z();
}

struct Raster {
  int cols = 0, rows = 0;
  double transform[6] = {};
  std::vector<std::string> names;
  std::vector<std::vector<float>> bands;
  [[nodiscard]] const std::vector<float>& band(const std::string& name) const {
    return bands[static_cast<std::size_t>(std::find(names.begin(), names.end(), name) - names.begin())];
  }
  [[nodiscard]] double x(int col) const { return transform[0] + (col + 0.5) * transform[1]; }
  [[nodiscard]] double y(int row) const { return transform[3] + (row + 0.5) * transform[5]; }
};

// Any raster GDAL reads (the GeoTIFF, the nav2 PNG), every band as floats.
Raster readRaster(const std::string& path) {
  GDALAllRegister();
  Raster r;
  std::unique_ptr<GDALDataset, void (*)(GDALDataset*)> ds(static_cast<GDALDataset*>(GDALOpen(path.c_str(), GA_ReadOnly)),
                                                          [](GDALDataset* d) { GDALClose(d); });
  EXPECT_TRUE(ds) << path;
  if (!ds) return r;
  r.cols = ds->GetRasterXSize();
  r.rows = ds->GetRasterYSize();
  ds->GetGeoTransform(r.transform);
  for (int b = 1; b <= ds->GetRasterCount(); ++b) {
    GDALRasterBand* band = ds->GetRasterBand(b);
    r.names.emplace_back(band->GetDescription());
    std::vector<float> v(static_cast<std::size_t>(r.cols) * static_cast<std::size_t>(r.rows));
    EXPECT_EQ(band->RasterIO(GF_Read, 0, 0, r.cols, r.rows, v.data(), r.cols, r.rows, GDT_Float32, 0, 0), CE_None);
    r.bands.push_back(std::move(v));
  }
  return r;
}

TEST(Layers, CorridorLayersMatchItsGeometry) {
  const std::string dir = tempDir("layers");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --noise none --quiet").code, 0);
  const std::string map_path = dir + "/c.ot";
  ASSERT_EQ(run("build " + dir + "/seq --frames 0:239:3 --out " + map_path + " --quiet").code, 0);
  const Result exported = run("export " + map_path + " --layers " + dir + "/layers --layer-pictures");
  ASSERT_EQ(exported.code, 0) << exported.out;

  // layers.json: one level (the box top and treads are elevation for a robot 1 m tall).
  const auto index = nlohmann::json::parse(fileBytes(dir + "/layers/layers.json"));
  ASSERT_EQ(index["levels"].size(), 1u) << index.dump(2);
  const auto& level = index["levels"][0];
  EXPECT_NEAR(level["z_m"].get<double>(), 0.02, 0.011);
  EXPECT_EQ(index["cell_m"], 0.02);
  const std::string tif = dir + "/layers/" + level["files"]["geotiff"].get<std::string>();
  // The picture of the level, listed with the level's files.
  ASSERT_TRUE(level["files"].contains("picture")) << level.dump(2);
  const auto [picture_w, picture_h] = pngSize(dir + "/layers/" + level["files"]["picture"].get<std::string>());
  EXPECT_GT(picture_w, 1000);
  EXPECT_GT(picture_h, 300);

  // gdalinfo reads the band names, the georeferencing and the unit. (-json also tries a
  // WGS 84 extent, which a local metric frame has not, and says so on standard error.)
  const Result plain = runShell("gdalinfo " + tif);
  ASSERT_EQ(plain.code, 0) << plain.out;
  EXPECT_EQ(plain.out.find("ERROR"), std::string::npos) << plain.out;
  EXPECT_NE(plain.out.find("Description = elevation"), std::string::npos) << plain.out;
  const Result info = runShell("{ gdalinfo -json " + tif + " 2>/dev/null; }");
  ASSERT_EQ(info.code, 0) << info.out;
  const auto gi = nlohmann::json::parse(info.out);
  const std::vector<std::string> want{"elevation", "elevation_variance", "mobility", "mobility_variance", "step", "slope_deg", "known"};
  ASSERT_EQ(gi["bands"].size(), want.size());
  for (std::size_t b = 0; b < want.size(); ++b) {
    EXPECT_EQ(gi["bands"][b]["description"], want[b]);
    EXPECT_EQ(gi["bands"][b]["type"], "Float32");
  }
  const auto& gt = gi["geoTransform"];
  EXPECT_NEAR(gt[0].get<double>(), level["extent"]["x_min"].get<double>(), 1e-9);
  EXPECT_NEAR(gt[3].get<double>(), level["extent"]["y_max"].get<double>(), 1e-9);
  EXPECT_EQ(gt[1], 0.02);
  EXPECT_EQ(gt[5], -0.02);
  EXPECT_NE(gi["coordinateSystem"]["wkt"].get<std::string>().find("metre"), std::string::npos);

  const Raster r = readRaster(tif);
  ASSERT_EQ(r.names, want);
  const auto& elevation = r.band("elevation");
  const auto& step = r.band("step");
  const auto& mobility = r.band("mobility");
  const mapping::MobilityMap map = mapping::openMap(map_path);
  const std::vector<Surface> truth = truthSurfaces(dir + "/seq/ground_truth.json");
  const auto toWorld = [&](double x, double y, double z) { return map.mapToWorld(Eigen::Vector3d(x, y, z)); };
  const double res = 0.02;

  // Elevation against the surface under each cell's centre, for cells a few voxels inside
  // a floor, ramp, tread or static box top (and clear of every other surface's outline).
  std::map<int, int> checked;
  for (int row = 0; row < r.rows; ++row) {
    for (int col = 0; col < r.cols; ++col) {
      const float e = elevation[static_cast<std::size_t>(row) * r.cols + col];
      const Eigen::Vector3d w = toWorld(r.x(col), r.y(row), 0);
      const Surface* under = nullptr;
      const std::vector<Eigen::Vector3d>* poly = nullptr;
      bool near_other = false;
      for (const Surface& s : truth) {
        for (const auto& p : s.polygons) {
          if (s.kind == "floor" || s.kind == "ramp" || s.kind == "stair_tread" || (s.kind == "box_top" && s.id == 26)) {
            if (insideFromAbove(p, w.x(), w.y(), 3 * res)) {
              under = &s, poly = &p;
              continue;
            }
          }
          if (s.kind != "floor" && insideFromAbove(p, w.x(), w.y(), -0.1)) near_other = true;
        }
      }
      // The moving box leaves its old top in the map where no later frame saw through it.
      const bool box_path = w.x() > 2.8 && w.x() < 3.6;
      if (under == nullptr || (near_other && under->kind == "floor") || box_path || std::abs(w.y()) > 1.3 || std::isnan(e)) {
        continue;
      }
      const double z = heightAt(*poly, w.x(), w.y());
      const double tilt = std::tan(under->slope_deg * M_PI / 180);
      const double e_world = toWorld(r.x(col), r.y(row), e).z();
      EXPECT_LE(std::abs(e_world - z), res + tilt * res / 2 + 0.002)
          << under->kind << " " << under->id << " at " << w.x() << ", " << w.y() << ": " << e_world << " vs " << z;
      ++checked[under->id];
    }
  }
  EXPECT_GT(checked[1], 3000);  // the floor
  for (int id : {5, 9, 13, 17, 21, 26, 32, 34, 36, 38}) EXPECT_GT(checked[id], 20) << "surface " << id;

  // Steps: at every riser and the static box's edges, the step across reaches the
  // height there less a voxel; on the floor away from everything, no step.
  const auto cellAt = [&](double x, double y) -> std::optional<std::size_t> {
    const int col = static_cast<int>(std::floor((x - r.transform[0]) / r.transform[1]));
    const int row = static_cast<int>(std::floor((y - r.transform[3]) / r.transform[5]));
    if (col < 0 || row < 0 || col >= r.cols || row >= r.rows) return std::nullopt;
    return static_cast<std::size_t>(row) * r.cols + col;
  };
  const auto largestStepNear = [&](double x, double y) {
    float largest = 0;
    for (double dx : {-res, 0.0, res}) {
      for (double dy : {-res, 0.0, res}) {
        const auto at = cellAt(x + dx, y + dy);
        if (at && !std::isnan(step[*at])) largest = std::max(largest, step[*at]);
      }
    }
    return largest;
  };
  for (const auto& [x, height] : std::vector<std::pair<double, double>>{{6.0, 0.17}, {6.3, 0.17}, {6.6, 0.17}, {6.9, 0.17}}) {
    int marked = 0, samples = 0;
    for (double y = 0.5; y <= 1.3; y += res, ++samples) marked += largestStepNear(x, y) >= height - res - 1e-4;
    EXPECT_GE(marked, samples * 9 / 10) << "riser at x = " << x;
  }
  {
    // The box's edges, where the floor beside them was seen (the far sides hide it).
    const auto known = [&](double x, double y) {
      const auto at = cellAt(x, y);
      return at && !std::isnan(elevation[*at]);
    };
    int marked = 0, samples = 0;
    const double out = 2 * res;
    for (double t = 0.05; t <= 0.35; t += res) {
      const std::array<std::array<double, 4>, 4> edges{{{4.6, 0.6 + t, -out, 0},   // -x: x, y, outward dx, dy
                                                         {5.0, 0.6 + t, out, 0},
                                                         {4.6 + t, 0.6, 0, -out},
                                                         {4.6 + t, 1.0, 0, out}}};
      for (const auto& [x, y, dx, dy] : edges) {
        if (!known(x + dx, y + dy) || !known(x - dx, y - dy)) continue;
        ++samples;
        marked += largestStepNear(x, y) >= 0.5 - res - 1e-4;
      }
    }
    EXPECT_GT(samples, 20);
    EXPECT_GE(marked, samples * 9 / 10) << "the box's edges";
  }
  int floor_cells = 0, floor_steps = 0;
  for (double x = 0.8; x <= 7.5; x += res) {
    for (double y = -0.3; y <= 0.3; y += res) {
      if (x > 2.8 && x < 3.6) continue;  // the moving box's path
      const auto at = cellAt(x, y);
      if (!at || std::isnan(step[*at])) continue;
      ++floor_cells;
      floor_steps += step[*at] > res + 1e-4;
    }
  }
  EXPECT_GT(floor_cells, 1000);
  EXPECT_LE(floor_steps, floor_cells / 100) << "steps on the open floor";

  // Mobility: the map's own answer for the surface's top voxel, where it has one.
  int compared = 0;
  for (int row = 0; row < r.rows; row += 4) {
    for (int col = 0; col < r.cols; col += 4) {
      const std::size_t at = static_cast<std::size_t>(row) * r.cols + col;
      if (std::isnan(elevation[at])) continue;
      const auto q = map.query(Eigen::Vector3d(r.x(col), r.y(row), elevation[at] - res / 2));
      if (!q.has_mobility) continue;
      EXPECT_EQ(mobility[at], static_cast<float>(q.mobility)) << r.x(col) << ", " << r.y(row);
      ++compared;
    }
  }
  EXPECT_GT(compared, 500);

  // nav2: its YAML, and the image read as map_server reads it (trinary, negate 0).
  const std::string yaml = fileBytes(dir + "/layers/" + level["files"]["nav2_yaml"].get<std::string>());
  for (const char* key : {"image: level_0.png", "mode: trinary", "resolution: 0.02", "negate: 0", "occupied_thresh: 0.65",
                          "free_thresh: 0.25"}) {
    EXPECT_NE(yaml.find(key), std::string::npos) << key << " in\n" << yaml;
  }
  char origin[96];
  std::snprintf(origin, sizeof origin, "origin: [%.6f, %.6f, 0.0]", level["extent"]["x_min"].get<double>(),
                level["extent"]["y_min"].get<double>());
  EXPECT_NE(yaml.find(origin), std::string::npos) << yaml;
  const Raster image = readRaster(dir + "/layers/level_0.png");
  ASSERT_EQ(image.cols, r.cols);
  ASSERT_EQ(image.rows, r.rows);
  const auto occupancy = [&](double x, double y) -> int {  // 1 occupied, 0 free, -1 unknown
    const auto at = cellAt(x, y);
    if (!at) return -1;
    const double p = (255.0 - image.bands[0][*at]) / 255.0;
    return p > 0.65 ? 1 : p < 0.25 ? 0 : -1;
  };
  const auto shares = [&](double x0, double x1, double y0, double y1) {
    int free = 0, occupied = 0;
    for (double x = x0; x <= x1; x += res)
      for (double y = y0; y <= y1; y += res) {
        const int o = occupancy(x, y);
        free += o == 0, occupied += o == 1;
      }
    return std::make_pair(free, occupied);
  };
  const auto [floor_free, floor_occupied] = shares(0.9, 2.6, -0.3, 0.3);
  EXPECT_GT(floor_free, 1000);
  EXPECT_LE(floor_occupied, floor_free / 50) << "the open floor is free";
  for (double x0 : {3.9, 5.1, 6.3}) {  // the 25, 35 and 45 degree ramps: too steep to stand on
    // (At its foot a sole still stands with its heel on the floor.)
    const auto [free, occupied] = shares(x0 + 0.2, x0 + 0.55, -1.2, -0.6);
    EXPECT_GT(occupied, 100) << "ramp at x = " << x0;
    EXPECT_LE(free, occupied / 10) << "ramp at x = " << x0;
  }
  for (double x : {6.0, 6.3, 6.6, 6.9}) {  // risers of 0.17 m, over the default 0.15 m step
    int marked = 0, samples = 0;
    for (double y = 0.5; y <= 1.3; y += res, ++samples) {
      marked += occupancy(x - res / 2, y) == 1 || occupancy(x + res / 2, y) == 1;
    }
    EXPECT_GE(marked, samples * 9 / 10) << "riser at x = " << x;
  }
  fs::remove_all(dir);
}

TEST(Layers, BadLayerSettingsAreRefusedNamingThem) {
  const std::string dir = tempDir("layers-bad");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 6 --noise none --quiet").code, 0);
  const std::string map = dir + "/m.ot";
  ASSERT_EQ(run("build " + dir + "/seq --out " + map + " --quiet").code, 0);
  const std::vector<std::pair<std::string, std::string>> bad{
      {"--cell 0.01", "--cell"},          // finer than the map's 2 cm voxels
      {"--cell 1e9", "--cell"},           // absurd
      {"--cell nan", "--cell"},
      {"--cell 0", "--cell"},
      {"--level 5", "no level at z = 5.00"},  // no such level: the levels are listed
      {"--level upstairs", "--level"},
      {"--level-clearance 0", "--level-clearance"},
  };
  for (const auto& [args, says] : bad) {
    const Result r = run("export " + map + " --layers " + dir + "/out " + args);
    EXPECT_NE(r.code, 0) << args;
    EXPECT_LT(r.code, 128) << args << ": " << r.out;  // an error, not a crash
    EXPECT_NE(r.out.find(says), std::string::npos) << args << ": " << r.out;
    EXPECT_FALSE(fs::exists(dir + "/out/layers.json")) << args;
  }
  const Result alone = run("export " + map + " --png " + dir + "/top.png --cell 0.05");
  EXPECT_NE(alone.code, 0);
  EXPECT_NE(alone.out.find("needs --layers"), std::string::npos) << alone.out;
  // A level given by its height.
  const Result by_height = run("export " + map + " --layers " + dir + "/out --level 0.03 --cell 0.1");
  EXPECT_EQ(by_height.code, 0) << by_height.out;
  EXPECT_EQ(nlohmann::json::parse(fileBytes(dir + "/out/layers.json"))["cell_m"], 0.1);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mobmap::cli_test
