// mobmap.open_recording: a robot's recording (ROS 1 or ROS 2 bag) read by the library's
// readers, as `mobmap build` reads it, frame by frame into numpy.

#include "map_handle.hpp"

#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/recording.hpp"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstring>

namespace mobmap::python {
namespace {

namespace py = pybind11;

py::dict frameDict(const sources::Recording& rec, const sources::RecordingFrame& f) {
  py::dict d;
  d["number"] = f.number;
  d["stamp"] = static_cast<double>(f.stamp_ns) * 1e-9;
  d["frame_id"] = f.frame_id;
  py::array_t<float> depth({f.depth.height, f.depth.width});
  std::memcpy(depth.mutable_data(), f.depth.depth_m.data(), f.depth.depth_m.size() * sizeof(float));
  d["depth"] = depth;
  const auto& k = rec.intrinsics();
  d["intrinsics"] = py::make_tuple(k.fx, k.fy, k.cx, k.cy);
  if (f.T_world_camera) {
    py::array_t<double> T({4, 4});
    Eigen::Map<Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(T.mutable_data()) = f.T_world_camera->matrix();
    d["pose"] = T;
  } else {
    d["pose"] = py::none();
  }
  return d;
}

// The frames with a pose, in order; each read as it is reached.
class FrameIterator {
 public:
  explicit FrameIterator(std::shared_ptr<sources::Recording> rec) : rec_(std::move(rec)) {}
  py::dict next() {
    if (i_ >= rec_->frames().size()) throw py::stop_iteration();
    const int n = rec_->frames()[i_++];
    sources::RecordingFrame f;
    {
      py::gil_scoped_release release;
      f = rec_->load(n);
    }
    return frameDict(*rec_, f);
  }

 private:
  std::shared_ptr<sources::Recording> rec_;
  std::size_t i_ = 0;
};

std::shared_ptr<sources::Recording> openRecording(const std::string& path, const py::kwargs& kwargs) {
  sources::RecordingOptions o;
  for (const auto& [key_handle, value] : kwargs) {
    const std::string key = py::str(key_handle);
    if (key == "depth_topic") o.depth_topic = value.cast<std::string>();
    else if (key == "camera_info_topic") o.camera_info_topic = value.cast<std::string>();
    else if (key == "world_frame") o.world_frame = value.cast<std::string>();
    else if (key == "imu_topic") o.imu_topic = value.cast<std::string>();
    else if (key == "max_pose_gap") o.max_pose_gap_s = value.cast<double>();
    else if (key == "intrinsics") {
      const auto k = value.cast<std::vector<double>>();
      if (k.size() != 4) throw py::value_error("intrinsics must be (fx, fy, cx, cy)");
      o.intrinsics = [k](int width, int height) {
        perception::PinholeIntrinsics in{width, height, k[0], k[1], k[2], k[3]};
        perception::validate(in);
        return in;
      };
    } else {
      throw py::type_error("open_recording() got an unexpected keyword argument '" + key +
                           "' (depth_topic, camera_info_topic, world_frame, imu_topic, max_pose_gap, intrinsics)");
    }
  }
  if (!(o.max_pose_gap_s >= 0.0)) throw py::value_error("max_pose_gap must be a number of seconds >= 0");
  py::gil_scoped_release release;
  return std::shared_ptr<sources::Recording>(sources::Recording::open(path, o));
}

}  // namespace

void bindRecording(py::module_& m) {
  py::register_exception<sources::IoError>(m, "RecordingError", PyExc_OSError);
  py::class_<FrameIterator>(m, "_FrameIterator")
      .def("__iter__", [](FrameIterator& it) -> FrameIterator& { return it; })
      .def("__next__", &FrameIterator::next);
  py::class_<sources::Recording, std::shared_ptr<sources::Recording>>(m, "Recording",
      "A robot's recording as `mobmap build` reads it. Iterating gives each depth image with a pose, in stamp "
      "order, as a dict: number, stamp (s), frame_id, depth ((H, W) float32 metres, 0 where there is none; "
      "undistorted when its camera_info has plumb_bob distortion), intrinsics (fx, fy, cx, cy), pose (4x4 camera "
      "to world). rec[n] reads image n whatever its pose (pose None when it has none).")
      .def("__iter__", [](const std::shared_ptr<sources::Recording>& r) { return FrameIterator(r); })
      .def("__len__", [](const sources::Recording& r) { return r.frames().size(); })
      .def("__getitem__", [](const sources::Recording& r, int n) {
        if (n < 0 || n >= r.imageCount()) throw py::index_error("no depth image " + std::to_string(n));
        sources::RecordingFrame f;
        {
          py::gil_scoped_release release;
          f = r.load(n);
        }
        return frameDict(r, f);
      })
      .def_property_readonly("path", &sources::Recording::path)
      .def_property_readonly("format", &sources::Recording::format)
      .def_property_readonly("depth_topic", &sources::Recording::depthTopic)
      .def_property_readonly("camera_info_topic", &sources::Recording::cameraInfoTopic)
      .def_property_readonly("world_frame", &sources::Recording::worldFrame)
      .def_property_readonly("camera_frame", &sources::Recording::cameraFrame)
      .def_property_readonly("intrinsics", [](const sources::Recording& r) {
        const auto& k = r.intrinsics();
        return py::dict(py::arg("fx") = k.fx, py::arg("fy") = k.fy, py::arg("cx") = k.cx, py::arg("cy") = k.cy,
                        py::arg("width") = k.width, py::arg("height") = k.height);
      })
      .def_property_readonly("gravity_down", [](const sources::Recording& r) -> py::object {
        const auto g = r.gravityDown();
        if (!g) return py::none();
        return py::make_tuple(g->x(), g->y(), g->z());
      }, "Gravity (down) in the world frame, or None when the recording does not say it")
      .def_property_readonly("gravity_source", &sources::Recording::gravitySource)
      .def_property_readonly("frames", &sources::Recording::frames, "Numbers of the depth images with a pose")
      .def_property_readonly("images", &sources::Recording::imageCount, "Depth images on the depth topic")
      .def_property_readonly("skipped", &sources::Recording::skipped)
      .def_property_readonly("fault", &sources::Recording::fault)
      .def_property_readonly("topics", [](const sources::Recording& r) {
        py::list out;
        for (const auto& t : r.topics()) {
          out.append(py::dict(py::arg("name") = t.name, py::arg("type") = t.type, py::arg("count") = t.count,
                              py::arg("rate_hz") = t.rate_hz));
        }
        return out;
      })
      .def_property_readonly("tf", [](const sources::Recording& r) {
        py::list out;
        for (const auto& e : r.tf().edges()) {
          out.append(py::dict(py::arg("parent") = e.parent, py::arg("child") = e.child, py::arg("static") = e.is_static,
                              py::arg("samples") = e.samples));
        }
        return out;
      });
  m.def("open_recording", &openRecording, py::arg("path"),
        "Opens a ROS 2 bag (folder with metadata.yaml, .db3 or .mcap) or a ROS 1 .bag as `mobmap build` reads it. "
        "Keyword arguments: depth_topic, camera_info_topic, world_frame, imu_topic, max_pose_gap (s, 0.05), "
        "intrinsics (fx, fy, cx, cy instead of its camera_info). RecordingError (an OSError) names the file and "
        "the problem.");
}

}  // namespace mobmap::python
