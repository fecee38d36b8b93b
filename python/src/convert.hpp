#pragma once
// Checks and conversions between numpy arrays and the library's types (internal to the
// Python module). Every wrong shape or dtype is a ValueError naming the argument.

#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/perception/camera.hpp"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <string>

namespace mobmap::python {

namespace py = pybind11;

/// A library message as Python users read it: each field it names (`max_pose_gap_s`)
/// spelled as the keyword argument that sets it (`max_pose_gap`); fields whose keyword is
/// their own name keep it.
std::string pythonText(const std::string& message);

/// `n` numbers as "a,b,c" (each to 17 significant digits); ValueError naming `what` unless
/// `value` holds `n` numbers.
std::string numberList(const py::handle& value, std::size_t n, const char* what);

/// A camera as the library's intrinsics spec: a str (a camera file, "fx,fy,cx,cy") as it
/// is, or (fx, fy, cx, cy). ValueError otherwise.
std::string intrinsicsSpec(const py::handle& value);

/// The frame points and soles are given in: the map's (z up, `mobmap build`'s map
/// frame) or the world frame of the poses.
enum class Frame { kMap, kWorld };
Frame parseFrame(const std::string& frame);

/// `value` (an array or nested sequences) as a C-contiguous float64 (N, cols) array;
/// ValueError naming `what` unless it is 2-D with `cols` columns of a real or integer dtype.
py::array_t<double, py::array::c_style> rows(const py::handle& value, py::ssize_t cols, const char* what);

/// A 3-vector from a sequence or array of 3 numbers; ValueError naming `what`.
Eigen::Vector3d vector3(const py::handle& value, const char* what);

/// A 4x4 rigid transform; its rotation snapped to the nearest rotation, as `mobmap build`
/// does with pose files. ValueError naming `what` if it is not 4x4 or not rigid.
Eigen::Isometry3d rigid(const py::handle& value, const char* what);

/// A depth image: uint16 millimetres (0 and 65535: no measurement, as in a depth PNG)
/// or float32 metres (0 or NaN: none), shape (H, W). ValueError otherwise.
perception::DepthImage depthImage(const py::handle& value);

/// (fx, fy, cx, cy) for an image of width x height; ValueError naming the problem.
perception::PinholeIntrinsics intrinsics(const py::handle& value, int width, int height);

/// A new float64 array of `n` rows and `cols` columns (cols 0: one-dimensional).
py::array_t<double> newArray(py::ssize_t n, py::ssize_t cols = 0);

}  // namespace mobmap::python
