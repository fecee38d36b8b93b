#pragma once
// The Python Map: a map that never changes under its reader, opened from a file or a
// LiveMapper's snapshot (internal to the Python module).

#include "mobmap/mapping/map_metadata.hpp"
#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/mapping/reachability.hpp"

#include <pybind11/pybind11.h>

#include <memory>
#include <optional>
#include <string>

namespace mobmap::python {

struct MapHandle {
  std::shared_ptr<const mapping::MobilityMap> map;
  /// MAP.json as read, for a map opened from a file.
  std::optional<mapping::MapMetadata> metadata;
  /// Gravity (down) in the world frame, when known (for MAP.json on save).
  std::optional<Eigen::Vector3d> gravity_down_world;
  /// The soles judged and the walks worked out for plan() and reachable() on this map,
  /// kept for the next call (per robot and start; 256 MB at most).
  std::shared_ptr<mapping::ReachCache> reach_cache = std::make_shared<mapping::ReachCache>(std::size_t{256} << 20);
};

void bindMap(pybind11::module_& m);
void bindPlanning(pybind11::module_& m);
void bindLive(pybind11::module_& m);
void bindRecording(pybind11::module_& m);
void bindBuild(pybind11::module_& m);

}  // namespace mobmap::python
