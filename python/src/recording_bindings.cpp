// mobmap.open_recording: any input `mobmap build` reads (a 7-Scenes / 3DMatch folder, TUM
// RGB-D, .pcd frames, a depth PNG, a ROS 1 or ROS 2 bag, an .oni file) through the
// library's readers, frame by frame into numpy.

#include "convert.hpp"
#include "map_handle.hpp"

#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/recording.hpp"
#include "mobmap/sources/sequence.hpp"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cstdio>
#include <cstring>

namespace mobmap::python {
namespace {

namespace py = pybind11;

using SequencePtr = std::shared_ptr<sources::Sequence>;

py::object poseArray(const std::optional<Eigen::Isometry3d>& T) {
  if (!T) return py::none();
  py::array_t<double> out({4, 4});
  Eigen::Map<Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(out.mutable_data()) = T->matrix();
  return std::move(out);
}

py::dict frameDict(const sources::Sequence& seq, const sources::Frame& f) {
  py::dict d;
  d["number"] = f.number;
  d["stamp"] = f.stamp_s ? py::object(py::float_(*f.stamp_s)) : py::none();
  const sources::Recording* rec = seq.recording();
  d["frame_id"] = rec != nullptr ? py::object(py::str(rec->cameraFrame())) : py::none();
  if (f.depth) {
    py::array_t<float> depth({f.depth->height, f.depth->width});
    std::memcpy(depth.mutable_data(), f.depth->depth_m.data(), f.depth->depth_m.size() * sizeof(float));
    d["depth"] = depth;
    d["points"] = py::none();
  } else {
    // A cloud without a pinhole image (an unorganized .pcd): its points, camera frame.
    py::array_t<float> points({static_cast<py::ssize_t>(f.points.size()), py::ssize_t{3}});
    for (std::size_t i = 0; i < f.points.size(); ++i) std::memcpy(points.mutable_data(i, 0), f.points[i].data(), 3 * sizeof(float));
    d["depth"] = py::none();
    d["points"] = points;
  }
  const auto& k = f.depth && f.intrinsics.width > 0 ? f.intrinsics : seq.intrinsics();
  d["intrinsics"] = seq.hasDepth() || f.depth ? py::object(py::make_tuple(k.fx, k.fy, k.cx, k.cy)) : py::none();
  d["pose"] = poseArray(f.T_world_camera);
  return d;
}

sources::Frame loadFrame(const sources::Sequence& seq, int n) {
  py::gil_scoped_release release;
  return seq.load(n);
}

// The frames with a pose (a lone file's one frame), in order; each read as it is reached.
class FrameIterator {
 public:
  explicit FrameIterator(SequencePtr seq) : seq_(std::move(seq)) {}
  py::dict next() {
    if (i_ >= seq_->frames().size()) throw py::stop_iteration();
    const sources::Frame f = loadFrame(*seq_, seq_->frames()[i_++]);
    return frameDict(*seq_, f);
  }

 private:
  SequencePtr seq_;
  std::size_t i_ = 0;
};

SequencePtr openRecording(const std::string& path, const py::kwargs& kwargs) {
  sources::SequenceOptions o;
  for (const auto& [key_handle, value] : kwargs) {
    const std::string key = py::str(key_handle);
    if (key == "depth_topic") o.recording.depth_topic = value.cast<std::string>();
    else if (key == "camera_info_topic") o.recording.camera_info_topic = value.cast<std::string>();
    else if (key == "world_frame") o.recording.world_frame = value.cast<std::string>();
    else if (key == "imu_topic") o.recording.imu_topic = value.cast<std::string>();
    else if (key == "max_pose_gap") o.max_pose_gap_s = value.cast<double>();
    else if (key == "poses") o.poses = py::str(value);
    else if (key == "intrinsics") o.intrinsics = intrinsicsSpec(value);
    else if (key == "depth_format") o.depth_format = value.cast<std::string>();
    else {
      throw py::type_error("open_recording() got an unexpected keyword argument '" + key +
                           "' (depth_topic, camera_info_topic, world_frame, imu_topic, max_pose_gap, intrinsics, poses, depth_format)");
    }
  }
  if (!(o.max_pose_gap_s >= 0.0)) throw py::value_error("max_pose_gap must be a number of seconds >= 0");
  py::gil_scoped_release release;
  return SequencePtr(sources::openSequence(path, o));
}

// A recording's own property (its topics, TF tree), or `otherwise` for a folder or a file.
template <typename F>
py::object ofRecording(const sources::Sequence& s, F get, py::object otherwise = py::none()) {
  const sources::Recording* r = s.recording();
  return r != nullptr ? py::cast(get(*r)) : otherwise;
}

}  // namespace

void bindRecording(py::module_& m) {
  py::class_<FrameIterator>(m, "_FrameIterator")
      .def("__iter__", [](FrameIterator& it) -> FrameIterator& { return it; })
      .def("__next__", &FrameIterator::next);
  py::class_<sources::Sequence, SequencePtr>(m, "Recording",
      "Depth frames as `mobmap build` reads them. Iterating gives each frame with a pose (a lone file's one "
      "frame), in order, as a dict: number, stamp (s, or None when the input has no time stamps), frame_id (a "
      "bag's camera frame, else None), depth ((H, W) float32 metres, 0 where there is none; undistorted when a "
      "bag's camera_info has plumb_bob distortion; None for a cloud without a pinhole image), points ((N, 3) "
      "float32 in the camera frame for such a cloud, else None), intrinsics (fx, fy, cx, cy), pose (4x4 camera "
      "to world, or None). rec[n] reads frame n (a bag's depth image n whatever its pose).")
      .def("__iter__", [](const SequencePtr& s) { return FrameIterator(s); })
      .def("__len__", [](const sources::Sequence& s) { return s.frames().size(); })
      .def("__getitem__", [](const sources::Sequence& s, int n) {
        const sources::Recording* r = s.recording();
        const bool known = r != nullptr ? (n >= 0 && n < r->imageCount())
                                        : std::binary_search(s.frames().begin(), s.frames().end(), n);
        if (!known) throw py::index_error("no frame " + std::to_string(n));
        return frameDict(s, loadFrame(s, n));
      })
      .def_property_readonly("format", &sources::Sequence::format)
      .def_property_readonly("description", [](const sources::Sequence& s) { return pythonText(s.describe()); },
                             "What was read and how, as `build` prints it")
      .def_property_readonly("intrinsics", [](const sources::Sequence& s) -> py::object {
        if (!s.hasDepth()) return py::none();
        const auto& k = s.intrinsics();
        return py::dict(py::arg("fx") = k.fx, py::arg("fy") = k.fy, py::arg("cx") = k.cx, py::arg("cy") = k.cy,
                        py::arg("width") = k.width, py::arg("height") = k.height);
      })
      .def_property_readonly("gravity_down", [](const sources::Sequence& s) -> py::object {
        const auto g = s.gravityDown();
        if (!g) return py::none();
        return py::make_tuple(g->x(), g->y(), g->z());
      }, "Gravity (down) in the world frame, or None when the input does not say it")
      .def_property_readonly("gravity_source", [](const sources::Sequence& s) -> py::object {
        if (!s.gravityDown()) return py::none();
        return py::str(s.gravitySource());
      })
      .def_property_readonly("posed", &sources::Sequence::posed, "False for a lone file, whose frame has no pose")
      .def_property_readonly("frames", &sources::Sequence::frames, "Numbers of the frames with a pose")
      .def_property_readonly("skipped", [](const sources::Sequence& s) { return pythonText(s.skipped()); },
                             "Frames left out and why, or ''")
      .def_property_readonly("path", [](const sources::Sequence& s) {
        return ofRecording(s, [](const sources::Recording& r) { return r.path(); });
      }, "A recording's path, else None")
      .def_property_readonly("images", [](const sources::Sequence& s) {
        return ofRecording(s, [](const sources::Recording& r) { return r.imageCount(); });
      }, "Depth images on a recording's depth topic, else None")
      .def_property_readonly("depth_topic", [](const sources::Sequence& s) {
        return ofRecording(s, [](const sources::Recording& r) { return r.depthTopic(); });
      })
      .def_property_readonly("camera_info_topic", [](const sources::Sequence& s) {
        return ofRecording(s, [](const sources::Recording& r) { return r.cameraInfoTopic(); });
      })
      .def_property_readonly("world_frame", [](const sources::Sequence& s) {
        return ofRecording(s, [](const sources::Recording& r) { return r.worldFrame(); });
      })
      .def_property_readonly("camera_frame", [](const sources::Sequence& s) {
        return ofRecording(s, [](const sources::Recording& r) { return r.cameraFrame(); });
      })
      .def_property_readonly("fault", [](const sources::Sequence& s) {
        return ofRecording(s, [](const sources::Recording& r) { return r.fault(); }, py::str(""));
      }, "Where a recording's bytes ended early or failed a check, or ''")
      .def_property_readonly("topics", [](const sources::Sequence& s) {
        py::list out;
        if (const sources::Recording* r = s.recording()) {
          for (const auto& t : r->topics()) {
            out.append(py::dict(py::arg("name") = t.name, py::arg("type") = t.type, py::arg("count") = t.count,
                                py::arg("rate_hz") = t.rate_hz));
          }
        }
        return out;
      }, "A recording's topics (name, type, count, rate_hz); empty for other inputs")
      .def_property_readonly("tf", [](const sources::Sequence& s) {
        py::list out;
        if (const sources::Recording* r = s.recording()) {
          for (const auto& e : r->tf().edges()) {
            out.append(py::dict(py::arg("parent") = e.parent, py::arg("child") = e.child,
                                py::arg("static") = e.is_static, py::arg("samples") = e.samples));
          }
        }
        return out;
      }, "A recording's TF links (parent, child, static, samples); empty for other inputs");
  m.def("open_recording", &openRecording, py::arg("path"),
        "Opens depth frames as `mobmap build` reads them: a 7-Scenes / 3DMatch folder, a TUM RGB-D folder, "
        ".pcd frames (with poses=), a single .pcd or 16-bit depth .png, an .oni file, a ROS 2 bag (folder, "
        ".db3 or .mcap) or a ROS 1 .bag (or .bag.active). Keyword arguments: intrinsics ((fx, fy, cx, cy) or a "
        "camera file, instead of the input's own), poses (a TUM trajectory file: for .pcd frames, or a bag's "
        "camera poses by stamp instead of its TF tree), max_pose_gap (s, 0.05), depth_format ('sunrgbd' for SUN "
        "RGB-D's depth PNGs), and for bags depth_topic, "
        "camera_info_topic, world_frame, imu_topic. RecordingError (an OSError) names the file and the problem; "
        "ValueError for an invalid argument.");
}

}  // namespace mobmap::python
