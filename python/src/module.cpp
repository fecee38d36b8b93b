// The native part of `import mobmap` (python/mobmap/__init__.py re-exports it).

#include "map_handle.hpp"

#include "mobmap/mapping/footstep_planner.hpp"
#include "mobmap/mapping/mobility_map.hpp"

#include <pybind11/pybind11.h>

PYBIND11_MODULE(_mobmap, m) {
  m.doc() = "Mobility maps for legged robots: queries, planning and live mapping in numpy";
  // The library's own errors about files and inputs reach Python with their message.
  pybind11::register_exception<mobmap::mapping::MapIoError>(m, "MapIoError", PyExc_OSError);
  pybind11::register_exception<mobmap::mapping::PlanInputError>(m, "PlanInputError", PyExc_ValueError);
  mobmap::python::bindMap(m);
  mobmap::python::bindPlanning(m);
  mobmap::python::bindLive(m);
  mobmap::python::bindRecording(m);
}
