// mobmap.build: a map from any input, as `mobmap build` builds it (mobmap::builder): the
// same options by the library's field names, the same files byte for byte.

#include "convert.hpp"

#include "mobmap/builder/map_builder.hpp"

#include <pybind11/stl.h>

#include <exception>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace mobmap::python {
namespace {

constexpr const char* kKnown =
    "frames, device, max_range_m, resolution_m, voxel_size_m, depth_scale, depth_format, gravity, gravity_from_floor, "
    "refine_gravity, origin, force, extend, checkpoint_frames, keyframes, free_space, skip_bad_frames, config, "
    "intrinsics, max_pose_gap, poses, depth_topic, camera_info_topic, world_frame, imu_topic, extrinsics, "
    "perception_threads, progress, on_message";

// The callbacks run on mobmap's threads: each takes the GIL, and the first Python error
// stops the run (it is raised when buildMap returns).
struct Callbacks {
  py::object progress, on_message;
  std::mutex mutex;
  std::optional<py::error_already_set> error;
  void keep(py::error_already_set& e) {
    const std::lock_guard<std::mutex> lock(mutex);
    if (!error) error = std::move(e);
  }
  [[nodiscard]] bool failed() {
    const std::lock_guard<std::mutex> lock(mutex);
    return error.has_value();
  }
};

py::dict build(const py::object& input, const std::string& out, const py::kwargs& kwargs) {
  builder::BuildOptions o;
  o.input = py::str(input);
  o.out = out;
  auto calls = std::make_shared<Callbacks>();
  for (const auto& [key_handle, value] : kwargs) {
    const std::string key = py::str(key_handle);
    if (value.is_none()) continue;
    if (key == "frames") o.frames = py::str(value);
    else if (key == "device") o.device = value.cast<std::string>();
    else if (key == "max_range_m") o.max_range_m = value.cast<double>();
    else if (key == "resolution_m") o.resolution_m = value.cast<double>();
    else if (key == "voxel_size_m") o.voxel_size_m = value.cast<double>();
    else if (key == "depth_scale") o.depth_scale = value.cast<double>();
    else if (key == "depth_format") o.depth_format = value.cast<std::string>();
    else if (key == "gravity") {
      if (py::isinstance<py::str>(value) && value.cast<std::string>() == "floor") o.gravity_from_floor = true;
      else o.gravity = vector3(value, "gravity");
    }
    else if (key == "gravity_from_floor") o.gravity_from_floor = value.cast<bool>();
    else if (key == "refine_gravity") o.refine_gravity = value.cast<bool>();
    else if (key == "origin") o.origin = vector3(value, "origin");
    else if (key == "force") o.force = value.cast<bool>();
    else if (key == "extend") o.extend = value.cast<bool>();
    else if (key == "checkpoint_frames") o.checkpoint_frames = value.cast<int>();
    else if (key == "keyframes") {
      const auto k = value.cast<std::vector<double>>();
      if (k.size() != 2) throw py::value_error("keyframes must be (metres, degrees)");
      o.keyframes = std::make_pair(k[0], k[1]);
    }
    else if (key == "free_space") o.free_space = value.cast<bool>();
    else if (key == "skip_bad_frames") o.skip_bad_frames = value.cast<bool>();
    else if (key == "config") o.config = py::str(value);
    else if (key == "intrinsics") o.intrinsics = intrinsicsSpec(value);
    else if (key == "max_pose_gap") o.max_pose_gap_s = value.cast<double>();
    else if (key == "poses") o.poses = py::str(value);
    else if (key == "depth_topic") o.recording.depth_topic = value.cast<std::string>();
    else if (key == "camera_info_topic") o.recording.camera_info_topic = value.cast<std::string>();
    else if (key == "world_frame") o.recording.world_frame = value.cast<std::string>();
    else if (key == "imu_topic") o.recording.imu_topic = value.cast<std::string>();
    else if (key == "extrinsics") o.extrinsics = py::isinstance<py::str>(value) ? value.cast<std::string>() : numberList(value, 7, "extrinsics");
    else if (key == "perception_threads") o.perception_threads = value.cast<int>();
    else if (key == "progress") calls->progress = py::reinterpret_borrow<py::object>(value);
    else if (key == "on_message") calls->on_message = py::reinterpret_borrow<py::object>(value);
    else throw py::type_error("build() got an unexpected keyword argument '" + key + "' (" + kKnown + ")");
  }
  std::vector<std::pair<std::string, std::string>> messages;
  std::mutex messages_mutex;
  builder::BuildHooks hooks;
  hooks.message = [&, calls](builder::Message kind, const std::string& line) {
    const std::string text = pythonText(line);
    const char* level = kind == builder::Message::kWarning ? "warning" : kind == builder::Message::kNote ? "note" : "detail";
    {
      const std::lock_guard<std::mutex> lock(messages_mutex);
      messages.emplace_back(level, text);
    }
    if (!calls->on_message) return;
    py::gil_scoped_acquire gil;
    try {
      calls->on_message(level, text);
    } catch (py::error_already_set& e) {
      calls->keep(e);
    }
  };
  if (calls->progress) {
    hooks.progress = [calls](int done, int total, std::size_t, std::chrono::steady_clock::time_point) {
      py::gil_scoped_acquire gil;
      try {
        calls->progress(done, total);
      } catch (py::error_already_set& e) {
        calls->keep(e);
      }
    };
  }
  // Ctrl-C in Python (or an error in a callback) ends the run with what was fused saved.
  hooks.stop = [calls] {
    if (calls->failed()) return true;
    py::gil_scoped_acquire gil;
    if (PyErr_CheckSignals() != 0) {
      py::error_already_set e;
      calls->keep(e);
      return true;
    }
    return false;
  };
  builder::BuildReport r;
  {
    py::gil_scoped_release unlocked;
    r = builder::buildMap(o, hooks);
  }
  if (calls->error) throw std::move(*calls->error);
  py::dict report;
  report["out"] = r.out;
  report["written"] = r.written;
  report["interrupted"] = r.interrupted;
  report["frames_fused"] = r.frames_fused;
  report["frames_selected"] = r.frames_selected;
  report["frames_without_pose"] = r.frames_without_pose;
  report["frames_without_ground"] = r.frames_without_ground;
  report["frames_in_map"] = r.frames_in_map;
  report["points"] = r.points;
  report["map_nodes"] = r.map_nodes;
  report["seconds"] = r.seconds;
  report["gravity_down_world"] = py::make_tuple(r.gravity_used.x(), r.gravity_used.y(), r.gravity_used.z());
  report["gravity_source"] = pythonText(r.gravity_source);
  report["unreadable"] = r.unreadable;
  py::list lines;
  for (const auto& [level, text] : messages) lines.append(py::make_tuple(level, text));
  report["messages"] = lines;
  return report;
}

}  // namespace

void bindBuild(py::module_& m) {
  m.def("build", &build, py::arg("input"), py::kw_only(), py::arg("out"),
        "build(input, *, out, **options) -> dict: the map `mobmap build INPUT --out OUT` writes, byte for byte, with "
        "the same options by the library's names: frames ('FIRST:LAST:STEP'), max_range_m, resolution_m, voxel_size_m, "
        "depth_scale, depth_format, gravity ((x, y, z) or 'floor'), refine_gravity, origin, force, extend, "
        "checkpoint_frames, keyframes ((metres, degrees)), free_space, skip_bad_frames, config, intrinsics, "
        "max_pose_gap, poses, depth_topic, camera_info_topic, world_frame, imu_topic, extrinsics, perception_threads; "
        "progress(done, total) and on_message(level, line) are called as the run goes (Ctrl-C stops it with the "
        "frames fused so far saved). Returns the run's numbers and its messages.");
}

}  // namespace mobmap::python
