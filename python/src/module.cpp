// The native part of `import mobmap` (python/mobmap/__init__.py re-exports it).

#include "convert.hpp"
#include "map_handle.hpp"

#include "mobmap/mapping/footstep_planner.hpp"
#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/sources/io_error.hpp"
#include "mobmap/util/field_error.hpp"

#include <pybind11/pybind11.h>

PYBIND11_MODULE(_mobmap, m) {
  m.doc() = "Mobility maps for legged robots: queries, planning and live mapping in numpy";
  // The library's own errors about files and inputs reach Python with their message, the
  // fields it names spelled as Python's keywords; a value the library cannot take is a
  // ValueError.
  namespace py = pybind11;
  static py::exception<mobmap::mapping::MapIoError> map_io_error(m, "MapIoError", PyExc_OSError);
  static py::exception<mobmap::mapping::PlanInputError> plan_input_error(m, "PlanInputError", PyExc_ValueError);
  static py::exception<mobmap::sources::IoError> recording_error(m, "RecordingError", PyExc_OSError);
  py::register_exception_translator([](std::exception_ptr p) {
    using mobmap::python::pythonText;
    try {
      if (p) std::rethrow_exception(p);
    } catch (const mobmap::mapping::MapIoError& e) {
      PyErr_SetString(map_io_error.ptr(), pythonText(e.what()).c_str());
    } catch (const mobmap::mapping::PlanInputError& e) {
      PyErr_SetString(plan_input_error.ptr(), pythonText(e.what()).c_str());
    } catch (const mobmap::sources::IoError& e) {
      PyErr_SetString(recording_error.ptr(), pythonText(e.what()).c_str());
    } catch (const mobmap::util::ValueError& e) {
      PyErr_SetString(PyExc_ValueError, pythonText(e.what()).c_str());
    }
  });
  mobmap::python::bindMap(m);
  mobmap::python::bindPlanning(m);
  mobmap::python::bindLive(m);
  mobmap::python::bindRecording(m);
  mobmap::python::bindBuild(m);
}
