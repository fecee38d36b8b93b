#include "convert.hpp"

#include "mobmap/mapping/gravity.hpp"
#include "mobmap/util/field_error.hpp"

#include <pybind11/stl.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <vector>
#include <limits>

namespace mobmap::python {

std::string pythonText(const std::string& message) {
  return util::respellFields(message, [](std::string_view field) -> std::optional<std::string> {
    if (field == "max_pose_gap_s") return std::string("`max_pose_gap`");  // open_recording's keyword
    return std::nullopt;
  });
}

std::string numberList(const py::handle& value, std::size_t n, const char* what) {
  const auto v = value.cast<std::vector<double>>();
  if (v.size() != n) throw py::value_error(std::string(what) + " must hold " + std::to_string(n) + " numbers");
  std::string text;
  for (const double x : v) {
    char cell[40];
    std::snprintf(cell, sizeof cell, "%.17g", x);
    text += (text.empty() ? "" : ",") + std::string(cell);
  }
  return text;
}

std::string intrinsicsSpec(const py::handle& value) {
  if (py::isinstance<py::str>(value)) return value.cast<std::string>();  // a camera file, or "fx,fy,cx,cy"
  if (value.cast<std::vector<double>>().size() != 4) {
    throw py::value_error("intrinsics must be (fx, fy, cx, cy) or a camera file's path");
  }
  return numberList(value, 4, "intrinsics");
}


Frame parseFrame(const std::string& frame) {
  if (frame == "map") return Frame::kMap;
  if (frame == "world") return Frame::kWorld;
  throw py::value_error("frame must be \"map\" or \"world\", got \"" + frame + "\"");
}

namespace {

bool realOrInteger(const py::dtype& dtype) {
  const char kind = dtype.kind();
  return kind == 'f' || kind == 'i' || kind == 'u';
}

std::string shapeOf(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

}  // namespace

py::array_t<double, py::array::c_style> rows(const py::handle& value, py::ssize_t cols, const char* what) {
  const py::array array = py::array::ensure(value);
  if (!array) throw py::value_error(std::string(what) + " must be an array of shape (N, " + std::to_string(cols) + ")");
  if (!realOrInteger(array.dtype())) {
    throw py::value_error(std::string(what) + " must be a numeric array, got dtype " + std::string(py::str(array.dtype())));
  }
  if (array.ndim() != 2 || array.shape(1) != cols) {
    throw py::value_error(std::string(what) + " must have shape (N, " + std::to_string(cols) + "), got " + shapeOf(array));
  }
  return py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
}

Eigen::Vector3d vector3(const py::handle& value, const char* what) {
  const py::array a = py::array::ensure(value);
  if (!a || !realOrInteger(a.dtype()) || a.size() != 3 || a.ndim() != 1) {
    throw py::value_error(std::string(what) + " must be three numbers (x, y, z)");
  }
  const auto d = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
  const Eigen::Vector3d v(d.at(0), d.at(1), d.at(2));
  if (!v.allFinite()) throw py::value_error(std::string(what) + " must be finite");
  return v;
}

Eigen::Isometry3d rigid(const py::handle& value, const char* what) {
  const py::array a = py::array::ensure(value);
  if (!a || !realOrInteger(a.dtype()) || a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4) {
    throw py::value_error(std::string(what) + " must be a 4x4 array");
  }
  const auto d = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = d.at(r, c);
  }
  if (const auto problem = mapping::checkRigid(m)) throw py::value_error(std::string(what) + ": " + *problem);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.matrix() = m;
  T.linear() = mapping::nearestRotation(T.linear());
  return T;
}

perception::DepthImage depthImage(const py::handle& value) {
  const py::array depth = py::array::ensure(value);
  if (!depth) throw py::value_error("depth must be a 2-D numpy array (H, W)");
  if (depth.ndim() != 2) throw py::value_error("depth must be a 2-D image (H, W), got " + shapeOf(depth));
  const auto h = static_cast<int>(depth.shape(0)), w = static_cast<int>(depth.shape(1));
  if (h < 1 || w < 1) throw py::value_error("depth is empty");
  perception::DepthImage image(w, h);
  if (py::isinstance<py::array_t<std::uint16_t>>(depth)) {
    // As a depth PNG is read: millimetres, 0 and 65535 meaning no measurement.
    const auto mm = py::array_t<std::uint16_t, py::array::c_style | py::array::forcecast>::ensure(depth);
    const std::uint16_t* v = mm.data();
    for (std::size_t i = 0; i < image.depth_m.size(); ++i) image.depth_m[i] = perception::metresFromMillimetres(v[i]);
    return image;
  }
  if (py::isinstance<py::array_t<float>>(depth)) {
    const auto m = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(depth);
    const float* v = m.data();
    for (std::size_t i = 0; i < image.depth_m.size(); ++i) image.depth_m[i] = std::isfinite(v[i]) ? v[i] : 0.f;
    return image;
  }
  throw py::value_error("depth must be uint16 (millimetres) or float32 (metres), got dtype " +
                        std::string(py::str(depth.dtype())));
}

perception::PinholeIntrinsics intrinsics(const py::handle& value, int width, int height) {
  const py::array a = py::array::ensure(value);
  if (!a || !realOrInteger(a.dtype()) || a.ndim() != 1 || a.size() != 4) {
    throw py::value_error("intrinsics must be four numbers (fx, fy, cx, cy)");
  }
  const auto d = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
  perception::PinholeIntrinsics k{width, height, d.at(0), d.at(1), d.at(2), d.at(3)};
  try {
    perception::validate(k);
  } catch (const std::invalid_argument& e) {
    throw py::value_error(e.what());
  }
  return k;
}

py::array_t<double> newArray(py::ssize_t n, py::ssize_t cols) {
  if (cols == 0) return py::array_t<double>(n);
  return py::array_t<double>({n, cols});
}

}  // namespace mobmap::python
