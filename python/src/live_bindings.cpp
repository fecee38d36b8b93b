// mobmap.LiveMapper (frames in from Python, snapshots out while fusion goes on) and
// mobmap.analyze (one frame through the per-frame pipeline).

#include "convert.hpp"
#include "map_handle.hpp"

#include "mobmap/mapping/live_mapper.hpp"
#include "mobmap/perception/pipeline.hpp"

#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <memory>

namespace mobmap::python {
namespace {

class PyLiveMapper {
 public:
  explicit PyLiveMapper(const py::kwargs& kwargs) {
    mapping::LiveMapper::Config config;
    for (const auto& [key, value] : kwargs) {
      const std::string name = py::str(key);
      if (name == "gravity_down_world") {
        config.gravity_down_world = vector3(value, "gravity_down_world");
      } else if (name == "origin_world") {
        config.origin_world = vector3(value, "origin_world");
      } else if (name == "resolution_m") {
        config.map.resolution_m = py::cast<double>(value);
      } else if (name == "max_range_m") {
        config.map.max_range_m = py::cast<double>(value);
        config.perception.max_range_m = config.map.max_range_m;
      } else if (name == "voxel_m") {
        voxel_ = py::cast<double>(value);
      } else if (name == "perception_threads") {
        config.perception_threads = py::cast<int>(value);
      } else if (name == "clear_free_space") {
        config.clear_free_space = py::cast<bool>(value);
      } else {
        throw py::type_error("LiveMapper() got an unexpected keyword argument '" + name +
                             "' (known: gravity_down_world, origin_world, resolution_m, max_range_m, voxel_m, "
                             "perception_threads, clear_free_space)");
      }
    }
    if (voxel_) config.perception = perception::scaledToVoxel(config.perception, *voxel_);
    gravity_ = config.gravity_down_world;
    mapper_ = std::make_unique<mapping::LiveMapper>(std::move(config));
  }

  void push(const py::object& depth, const py::handle& k, const py::handle& T_world_camera, double stamp) {
    mapping::DepthFrame frame;
    frame.depth = depthImage(depth);
    frame.intrinsics = intrinsics(k, frame.depth.width, frame.depth.height);
    frame.T_world_camera = rigid(T_world_camera, "T_world_camera");
    frame.stamp_s = stamp;
    py::gil_scoped_release unlocked;  // push() waits while perception is busy
    mapper_->push(std::move(frame));
  }

  std::shared_ptr<MapHandle> snapshot() const {
    auto h = std::make_shared<MapHandle>();
    h->map = mapper_->snapshot();
    h->gravity_down_world = gravity_;
    return h;
  }

  void finish() {
    py::gil_scoped_release unlocked;
    mapper_->finish();
  }

  py::dict stats() const {
    const mapping::LiveMapper::Stats s = mapper_->stats();
    py::dict out;
    out["pushed"] = s.pushed;
    out["dropped"] = s.dropped;
    out["fused"] = s.fused;
    out["failed"] = s.failed;
    out["snapshot_copies"] = s.snapshot_copies;
    return out;
  }

 private:
  std::unique_ptr<mapping::LiveMapper> mapper_;
  std::optional<double> voxel_;
  Eigen::Vector3d gravity_;
};

py::dict analyze(const py::object& depth, const py::handle& k, const py::object& gravity) {
  const perception::DepthImage image = depthImage(depth);
  const perception::PinholeIntrinsics intr = intrinsics(k, image.width, image.height);
  std::optional<Eigen::Vector3f> down;
  if (!gravity.is_none()) down = vector3(gravity, "gravity").cast<float>();
  perception::FrameResult r;
  {
    py::gil_scoped_release unlocked;
    static const perception::FramePipeline pipeline;  // the defaults of `mobmap analyze`
    r = pipeline.process(image, intr, down);
  }
  const auto n = static_cast<py::ssize_t>(r.segments.size());
  py::array_t<std::int32_t> points(n);
  py::array_t<bool> ground(n), rough(n);
  auto slope = newArray(n), roughness = newArray(n), mobility = newArray(n), variance = newArray(n),
       area = newArray(n), centroid = newArray(n, 3), normal = newArray(n, 3);
  for (py::ssize_t s = 0; s < n; ++s) {
    const perception::Segment& seg = r.segments[static_cast<std::size_t>(s)];
    points.mutable_at(s) = static_cast<std::int32_t>(seg.points.size());
    ground.mutable_at(s) = seg.is_ground;
    rough.mutable_at(s) = seg.is_rough;
    slope.mutable_at(s) = seg.slope_deg;
    roughness.mutable_at(s) = seg.roughness;
    mobility.mutable_at(s) = seg.mobility;
    variance.mutable_at(s) = seg.variance;
    area.mutable_at(s) = seg.area_m2;
    for (int a = 0; a < 3; ++a) {
      centroid.mutable_at(s, a) = seg.centroid(a);
      normal.mutable_at(s, a) = seg.normal(a);
    }
  }
  py::array_t<std::int32_t> labels({static_cast<py::ssize_t>(image.height), static_cast<py::ssize_t>(image.width)});
  auto l = labels.mutable_unchecked<2>();
  for (int v = 0; v < image.height; ++v) {
    for (int u = 0; u < image.width; ++u) {
      const int p = r.point_of_pixel[static_cast<std::size_t>(v) * static_cast<std::size_t>(image.width) + static_cast<std::size_t>(u)];
      l(v, u) = p < 0 ? -1 : r.segment_of_point[static_cast<std::size_t>(p)];
    }
  }
  py::dict segments;
  segments["points"] = points;
  segments["is_ground"] = ground;
  segments["is_rough"] = rough;
  segments["slope_deg"] = slope;
  segments["roughness"] = roughness;
  segments["mobility"] = mobility;
  segments["variance"] = variance;
  segments["area_m2"] = area;
  segments["centroid"] = centroid;
  segments["normal"] = normal;
  py::dict out;
  out["segments"] = segments;
  out["segment_image"] = labels;
  if (r.ground_plane) {
    out["ground_plane"] = Eigen::Vector4d(r.ground_plane->cast<double>());
  } else {
    out["ground_plane"] = py::none();
  }
  py::dict stages;
  for (const auto& st : r.stages) stages[py::str(st.name)] = st.milliseconds;
  out["stages_ms"] = stages;
  return out;
}

}  // namespace

void bindLive(py::module_& m) {
  py::class_<PyLiveMapper>(m, "LiveMapper",
      "Maps while the map is read: push() frames from one thread, snapshot() from any other. Perception "
      "runs on two threads, fusion on a third; the GIL is released while push() waits and while finish() "
      "runs. Keyword arguments: gravity_down_world (3 numbers, default (0, 0, -1)), origin_world (default: "
      "the first camera position rounded to 100 m), resolution_m (0.02), max_range_m (3), voxel_m "
      "(perception voxels, default 0.01), perception_threads (2), clear_free_space (True).")
      .def(py::init<const py::kwargs&>())
      .def("push", &PyLiveMapper::push, py::arg("depth"), py::arg("intrinsics"), py::arg("T_world_camera"),
           py::arg("stamp") = 0.0,
           "Queues a depth frame: depth (H, W) uint16 millimetres or float32 metres; intrinsics (fx, fy, cx, cy); "
           "T_world_camera 4x4 (camera to world; its rotation is snapped to the nearest rotation). Waits while "
           "two frames wait for perception.")
      .def("snapshot", &PyLiveMapper::snapshot, "The map after the last frame fused, as a Map that never changes.")
      .def("finish", &PyLiveMapper::finish,
           "Returns when every frame pushed is fused; the snapshot is then final (the same map, byte for "
           "byte, as `mobmap build` of those frames with the same gravity and origin).")
      .def("stats", &PyLiveMapper::stats, "Frames pushed, dropped, fused, failed, and snapshot copies.");
  m.def("analyze", &analyze, py::arg("depth"), py::arg("intrinsics"), py::arg("gravity") = py::none(),
        "One depth frame through the paper's per-frame pipeline with `mobmap analyze`'s defaults; gravity "
        "(down) in the camera frame if known. Returns a dict: segments (arrays per segment: points, "
        "is_ground, is_rough, slope_deg, roughness, mobility, variance, area_m2, centroid (S, 3), normal "
        "(S, 3); camera frame), segment_image (H, W; the segment of each pixel, -1 none), ground_plane (a, b, "
        "c, d or None) and stages_ms.");
}

}  // namespace mobmap::python
