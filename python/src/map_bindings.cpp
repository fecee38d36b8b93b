// mobmap.open_map and mobmap.Map: point and sole queries in numpy, save, info.

#include "convert.hpp"
#include "map_handle.hpp"

#include "mobmap/mapping/foot.hpp"
#include "mobmap/mapping/layers.hpp"

#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>

namespace mobmap::python {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

Eigen::Vector3d toMap(const mapping::MobilityMap& map, const Eigen::Vector3d& p, Frame frame) {
  return frame == Frame::kWorld ? map.worldToMap(p) : p;
}

Eigen::Vector3d fromMap(const mapping::MobilityMap& map, const Eigen::Vector3d& p, Frame frame) {
  return frame == Frame::kWorld ? map.mapToWorld(p) : p;
}

// Points (N, 3) given in `from` taken to the other frame.
py::array_t<double> transformed(const MapHandle& h, const py::object& points, Frame from) {
  const auto a = rows(points, 3, "points");
  auto out = newArray(a.shape(0), 3);
  auto o = out.mutable_unchecked<2>();
  const auto in = a.unchecked<2>();
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    const Eigen::Vector3d p(in(i, 0), in(i, 1), in(i, 2));
    const Eigen::Vector3d q = from == Frame::kWorld ? h.map->worldToMap(p) : h.map->mapToWorld(p);
    for (int k = 0; k < 3; ++k) o(i, k) = q(k);
  }
  return out;
}

py::dict query(const MapHandle& h, const py::object& points, const std::string& frame_name, std::optional<double> snap) {
  const Frame frame = parseFrame(frame_name);
  const auto p = rows(points, 3, "points");
  if (snap && !(*snap >= 0.0 && std::isfinite(*snap))) throw py::value_error("snap must be a distance >= 0 in metres");
  const py::ssize_t n = p.shape(0);
  py::array_t<std::uint8_t> state(n);
  py::array_t<double> mobility(n), variance(n);
  py::array_t<std::int32_t> count(n);
  py::array_t<double> centre({n, py::ssize_t{3}});
  {
    auto s = state.mutable_unchecked<1>();
    auto mob = mobility.mutable_unchecked<1>();
    auto var = variance.mutable_unchecked<1>();
    auto cnt = count.mutable_unchecked<1>();
    auto c = centre.mutable_unchecked<2>();
    const auto in = p.unchecked<2>();
    const mapping::MobilityMap& map = *h.map;
    py::gil_scoped_release unlocked;
    for (py::ssize_t i = 0; i < n; ++i) {
      const Eigen::Vector3d q = toMap(map, Eigen::Vector3d(in(i, 0), in(i, 1), in(i, 2)), frame);
      // Non-finite points are unknown to both (the library checks them).
      const std::optional<mapping::PointQuery> r = snap ? map.snapDown(q, *snap) : map.query(q);
      if (!r) {
        s(i) = static_cast<std::uint8_t>(mapping::VoxelState::kUnknown);
        mob(i) = kNaN;
        var(i) = std::numeric_limits<double>::infinity();
        cnt(i) = 0;
        for (int a = 0; a < 3; ++a) c(i, a) = kNaN;
        continue;
      }
      s(i) = static_cast<std::uint8_t>(r->state);
      mob(i) = r->has_mobility ? r->mobility : kNaN;
      var(i) = r->has_mobility ? r->variance : std::numeric_limits<double>::infinity();
      cnt(i) = r->count;
      const Eigen::Vector3d centre_out = fromMap(map, r->centre, frame);
      for (int a = 0; a < 3; ++a) c(i, a) = centre_out(a);
    }
  }
  py::dict out;
  out["state"] = state;
  out["mobility"] = mobility;
  out["variance"] = variance;
  out["count"] = count;
  out["voxel_centre"] = centre;
  return out;
}

py::dict footprint(const MapHandle& h, const py::object& soles, const std::string& frame_name) {
  const Frame frame = parseFrame(frame_name);
  const auto s = rows(soles, 6, "soles");
  const py::ssize_t n = s.shape(0);
  {
    // As `mobmap query --foot` and the server: a sole must be finite and of a size that
    // can be sampled in reasonable time (NaN or a 100 m sole gave zeros or took seconds).
    const auto in = s.unchecked<2>();
    for (py::ssize_t i = 0; i < n; ++i) {
      for (py::ssize_t k = 0; k < 6; ++k) {
        if (!std::isfinite(in(i, k))) throw py::value_error("footprint: soles[" + std::to_string(i) + "] holds a value that is not finite");
      }
      const double length = in(i, 4), width = in(i, 5);
      if (!mapping::soleSizeAllowed(length, width)) {
        throw py::value_error("footprint: soles[" + std::to_string(i) + "]: length and width must be in (0, " +
                              std::to_string(static_cast<int>(mapping::kMaxSoleSideM)) + "] m, got " + std::to_string(length) +
                              " x " + std::to_string(width));
      }
    }
  }
  auto min_mob = newArray(n), mean_mob = newArray(n), known = newArray(n), height_diff = newArray(n),
       support = newArray(n), tilt = newArray(n);
  {
    auto a = min_mob.mutable_unchecked<1>();
    auto b = mean_mob.mutable_unchecked<1>();
    auto k = known.mutable_unchecked<1>();
    auto d = height_diff.mutable_unchecked<1>();
    auto z = support.mutable_unchecked<1>();
    auto t = tilt.mutable_unchecked<1>();
    const auto in = s.unchecked<2>();
    const mapping::MobilityMap& map = *h.map;
    py::gil_scoped_release unlocked;
    for (py::ssize_t i = 0; i < n; ++i) {
      const Eigen::Vector3d c = toMap(map, Eigen::Vector3d(in(i, 0), in(i, 1), in(i, 2)), frame);
      const mapping::Foot foot{c.x(), c.y(), c.z(), (frame == Frame::kWorld ? map.worldYawToMap(in(i, 3)) : in(i, 3)), in(i, 4), in(i, 5)};
      const mapping::FootprintQuery f = map.footprint(foot);
      a(i) = f.min_mobility;
      b(i) = f.mean_mobility;
      k(i) = f.known_fraction;
      d(i) = f.max_height_difference_m;
      z(i) = f.has_support_plane ? f.support_height_m : kNaN;
      t(i) = f.has_support_plane ? f.support_tilt_deg : kNaN;
    }
  }
  py::dict out;
  out["min_mobility"] = min_mob;
  out["mean_mobility"] = mean_mob;
  out["known_fraction"] = known;
  out["max_height_difference"] = height_diff;
  out["support_height"] = support;
  out["support_tilt_deg"] = tilt;
  return out;
}

// Poses (N, 4) x y z yaw -> float32 arrays (N, ny, nx); the pose taken to the map frame
// first when it is in the world frame (heights are along the map's z, gravity's up).
py::dict heightScan(const MapHandle& h, const py::object& poses, const std::pair<double, double>& size, double resolution,
                    const std::string& frame_name, double clearance) {
  const Frame frame = parseFrame(frame_name);
  const auto p = rows(poses, 4, "poses");
  const mapping::MobilityMap& map = *h.map;
  std::vector<mapping::HeightScanPose> in(static_cast<std::size_t>(p.shape(0)));
  const auto a = p.unchecked<2>();
  // A value that is not finite stays so through the frame change: the library names its pose.
  for (py::ssize_t i = 0; i < p.shape(0); ++i) {
    const Eigen::Vector3d c = toMap(map, Eigen::Vector3d(a(i, 0), a(i, 1), a(i, 2)), frame);
    in[static_cast<std::size_t>(i)] = {c.x(), c.y(), c.z(), frame == Frame::kWorld ? map.worldYawToMap(a(i, 3)) : a(i, 3)};
  }
  const mapping::HeightScanGrid grid{size.first, size.second, resolution, clearance};
  mapping::HeightScan scan;
  try {
    py::gil_scoped_release unlocked;
    scan = map.heightScan(in, grid);
  } catch (const std::invalid_argument& e) {
    throw py::value_error(e.what());
  }
  const std::vector<py::ssize_t> shape{static_cast<py::ssize_t>(scan.poses), scan.ny, scan.nx};
  py::array_t<float> height(shape), mobility(shape);
  std::copy(scan.height.begin(), scan.height.end(), height.mutable_data());
  std::copy(scan.mobility.begin(), scan.mobility.end(), mobility.mutable_data());
  py::dict out;
  out["height"] = height;
  out["mobility"] = mobility;
  return out;
}

// One level's 2.5D layers (mapping/layers.hpp) as float32 arrays (rows, cols), north up.
py::dict layers(const MapHandle& h, std::size_t level, std::optional<double> cell, double clearance) {
  const mapping::MobilityMap& map = *h.map;
  std::vector<mapping::LayerLevel> levels;
  mapping::LevelLayers l;
  {
    py::gil_scoped_release unlocked;
    const auto columns = map.surfaceColumns();
    levels = mapping::layerLevels(*columns, clearance);  // std::invalid_argument: ValueError
    if (level >= levels.size()) {
      throw std::invalid_argument("layers: level " + std::to_string(level) + " of a map with " +
                                  std::to_string(levels.size()) + " levels (lowest first)");
    }
    l = mapping::levelLayers(*columns, levels[level], cell.value_or(columns->resolution()));
  }
  py::list listed;
  for (std::size_t k = 0; k < levels.size(); ++k) {
    py::dict d;
    d["index"] = k;
    d["z_m"] = levels[k].z_m;
    d["share"] = levels[k].share;
    listed.append(d);
  }
  py::dict out;
  out["levels"] = listed;
  out["level"] = level;
  out["z_m"] = l.level.z_m;
  out["cell"] = l.cell_m;
  out["x_min"] = l.x_min;
  out["y_min"] = l.y_min;
  const std::vector<py::ssize_t> shape{l.rows, l.cols};
  for (const std::string& name : mapping::layerNames()) {
    const std::vector<float>& values = mapping::layerByName(l, name);
    py::array_t<float> a(shape);
    std::copy(values.begin(), values.end(), a.mutable_data());
    out[name.c_str()] = a;
  }
  return out;
}

void save(const MapHandle& h, const std::string& path) {
  if (std::filesystem::path(path).extension() != ".ot") throw py::value_error("save: the path must end in .ot, got " + path);
  mapping::MapMetadata meta = h.metadata.value_or(mapping::MapMetadata{});
  mapping::MapRun& run = meta.latest;
  if (!run.format) run.format = "mobmap-map-metadata";
  if (!run.tool) run.tool = "mobmap python";
  run.resolution_m = h.map->tree().getResolution();
  run.R_map_world = h.map->rotationMapWorld();
  run.origin_world = h.map->originWorld();
  if (h.gravity_down_world) run.gravity_down_world = *h.gravity_down_world;
  if (!h.metadata) meta.frames = h.map->framesIntegrated();
  py::gil_scoped_release unlocked;
  mapping::saveMobilityMap(h.map->tree(), path);
  mapping::saveMapMetadata(meta, mapping::mapFileStem(path) + ".json");
}

py::dict info(const MapHandle& h) {
  const mapping::MobilityMap& map = *h.map;
  const mapping::MobilityOcTree& tree = map.tree();
  py::dict out;
  out["resolution_m"] = tree.getResolution();
  out["nodes"] = tree.size();
  out["leaves"] = tree.getNumLeafNodes();
  out["memory_bytes"] = tree.memoryUsage();
  double x0 = 0, y0 = 0, z0 = 0, x1 = 0, y1 = 0, z1 = 0;
  if (tree.size() > 0) {
    tree.getMetricMin(x0, y0, z0);
    tree.getMetricMax(x1, y1, z1);
  }
  out["bounds_min"] = Eigen::Vector3d(x0, y0, z0);
  out["bounds_max"] = Eigen::Vector3d(x1, y1, z1);
  out["R_map_world"] = map.rotationMapWorld();
  out["origin_world"] = map.originWorld();
  out["frames"] = h.metadata ? h.metadata->frames : map.framesIntegrated();
  if (h.metadata) out["path"] = h.metadata->path;
  if (h.gravity_down_world) out["gravity_down_world"] = *h.gravity_down_world;
  return out;
}

}  // namespace

void bindMap(py::module_& m) {
  m.attr("UNKNOWN") = static_cast<int>(mapping::VoxelState::kUnknown);
  m.attr("FREE") = static_cast<int>(mapping::VoxelState::kFree);
  m.attr("SURFACE") = static_cast<int>(mapping::VoxelState::kSurface);

  py::class_<MapHandle, std::shared_ptr<MapHandle>>(m, "Map",
      "A mobility map that does not change while it is read (opened from a file, or a "
      "LiveMapper snapshot). Queries may run from several Python threads at once; the GIL "
      "is released while they run.")
      .def("query", &query, py::arg("points"), py::arg("frame") = "map", py::arg("snap") = py::none(),
           "Points (N, 3) -> dict of arrays: state (mobmap.UNKNOWN, FREE, SURFACE), mobility (NaN where "
           "unknown), variance (inf where unknown), count (observations), voxel_centre (N, 3, in `frame`). "
           "snap=D: the surface found within D metres below each point instead of the point's own voxel.")
      .def("footprint", &footprint, py::arg("soles"), py::arg("frame") = "map",
           "Soles (N, 6): x y z yaw length width (metres, radians; z: where to look for the surface, 0.1 m "
           "up or down) -> dict of arrays: min_mobility, mean_mobility, known_fraction, "
           "max_height_difference, support_height and support_tilt_deg (NaN without a support plane; "
           "heights in the map frame, z up).")
      .def("height_scan", &heightScan, py::arg("poses"), py::arg("size") = std::make_pair(1.6, 1.0),
           py::arg("resolution") = 0.1, py::arg("frame") = "map", py::arg("clearance") = mapping::kDefaultScanClearanceM,
           "Poses (N, 4): x y z yaw of robot bases -> dict of float32 arrays height and mobility, shape "
           "(N, ny, nx): the terrain at each point of a grid of size (length, width) metres centred on the "
           "pose, its x along the yaw, nx = length / resolution + 1, x varying fastest: the highest surface "
           "at or below `clearance` metres above the pose, read no higher than that (what lies wholly above "
           "is overhead and left out). height is relative to the pose's z (map frame, z up); NaN where "
           "unknown. The map's surface columns are built on the first call and kept.")
      .def("layers", &layers, py::arg("level") = 0, py::arg("cell") = py::none(), py::arg("clearance") = 1.0,
           "2.5D layers of one level (index into levels, lowest first) for a robot `clearance` metres tall, "
           "in square cells of `cell` metres (default: the map's resolution) -> dict: levels (index, z_m, share), "
           "level, z_m, cell, x_min, y_min (the grid's lower-left corner, map frame) and float32 arrays (rows, "
           "cols), row 0 the highest y: elevation, elevation_variance, mobility, mobility_variance, step, "
           "slope_deg, known; NaN where unknown. As `mobmap export --layers` (docs/MAPPING.md).")
      .def("save", &save, py::arg("path"),
           "Writes the map to PATH.ot (and its frame to PATH.json beside it) atomically; `mobmap info`, "
           "`query` and open_map read it.")
      .def("info", &info, "Resolution, nodes, leaves, memory, bounds (map frame), the map frame and frames fused.")
      .def("world_to_map", [](const MapHandle& h, const py::object& p) { return transformed(h, p, Frame::kWorld); },
           py::arg("points"), "Points (N, 3) of the poses' world frame in the map frame.")
      .def("map_to_world", [](const MapHandle& h, const py::object& p) { return transformed(h, p, Frame::kMap); },
           py::arg("points"), "Points (N, 3) of the map frame in the poses' world frame.")
      .def_property_readonly("resolution", [](const MapHandle& h) { return h.map->tree().getResolution(); });

  m.def("open_map", [](const std::string& path) {
          auto h = std::make_shared<MapHandle>();
          {
            py::gil_scoped_release unlocked;
            h->map = std::make_shared<const mapping::MobilityMap>(mapping::openMap(path));
            mapping::MapMetadata meta = mapping::readMapMetadata(path);
            if (meta.found) {
              h->gravity_down_world = meta.gravityDownWorld();
              h->metadata = std::move(meta);
            }
          }
          return h;
        }, py::arg("path"), "Opens a map `mobmap build` (or Map.save) wrote: PATH.ot with PATH.json beside it.");
}

}  // namespace mobmap::python
