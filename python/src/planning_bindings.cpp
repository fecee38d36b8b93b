// mobmap.plan and mobmap.reachable: footsteps and reachability with the robot's limits
// as keyword arguments (the names of RobotParams and PlanParams).

#include "convert.hpp"
#include "map_handle.hpp"

#include "mobmap/mapping/footstep_planner.hpp"
#include "mobmap/mapping/reachability.hpp"

#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

namespace mobmap::python {
namespace {

// Applies the keyword arguments through `set` (false: not one of `known`): TypeError for
// an unknown name or a value that is not a number.
void apply(const py::kwargs& kwargs, const std::function<bool(const std::string&, double)>& set,
           const std::vector<std::string>& known, const char* function) {
  for (const auto& [key, value] : kwargs) {
    const std::string name = py::str(key);
    if (std::find(known.begin(), known.end(), name) == known.end()) {
      std::string list;
      for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
      throw py::type_error(std::string(function) + "() got an unexpected keyword argument '" + name + "' (known: " +
                           list + ")");
    }
    double number = 0;
    try {
      number = py::cast<double>(value);
    } catch (const py::cast_error&) {
      throw py::type_error(std::string(function) + "(): " + name + " must be a number");
    }
    set(name, number);
  }
}

Eigen::Vector3d pointToMap(const MapHandle& h, const py::handle& p, const char* what, Frame frame) {
  const Eigen::Vector3d v = vector3(p, what);
  return frame == Frame::kWorld ? h.map->worldToMap(v) : v;
}

py::dict plan(const MapHandle& h, const py::handle& start, const py::handle& goal, const std::string& frame_name,
              const py::kwargs& robot) {
  const Frame frame = parseFrame(frame_name);
  mapping::PlanParams params;
  apply(
      robot, [&](const std::string& name, double v) { return mapping::setPlanParameter(params, name, v); },
      mapping::planParameterNames(), "plan");
  const Eigen::Vector3d s = pointToMap(h, start, "start", frame), g = pointToMap(h, goal, "goal", frame);
  mapping::Plan p;
  {
    py::gil_scoped_release unlocked;
    p = mapping::planFootsteps(h.map->surfaceColumns(), s, g, params, {}, h.reach_cache.get());
  }
  const auto n = static_cast<py::ssize_t>(p.footsteps.size());
  auto xyz = newArray(n, 3), yaw = newArray(n), min_mobility = newArray(n), tilt = newArray(n);
  auto mean_mobility = newArray(n), poor_fraction = newArray(n);
  py::array_t<std::uint8_t> side(n);
  auto o = xyz.mutable_unchecked<2>();
  for (py::ssize_t i = 0; i < n; ++i) {
    const mapping::Footstep& f = p.footsteps[static_cast<std::size_t>(i)];
    Eigen::Vector3d c(f.x, f.y, f.z);
    double heading = f.yaw;
    if (frame == Frame::kWorld) {
      c = h.map->mapToWorld(c);
      heading = h.map->mapYawToWorld(f.yaw);
    }
    for (int k = 0; k < 3; ++k) o(i, k) = c(k);
    yaw.mutable_at(i) = heading;
    min_mobility.mutable_at(i) = f.min_mobility;
    mean_mobility.mutable_at(i) = f.mean_mobility;
    poor_fraction.mutable_at(i) = f.poor_fraction;
    tilt.mutable_at(i) = f.tilt_deg;
    side.mutable_at(i) = f.side == mapping::Side::kLeft ? 0 : 1;
  }
  py::dict out;
  out["found"] = p.found;
  out["reason"] = pythonText(p.reason);
  out["xyz"] = xyz;
  out["yaw"] = yaw;
  out["side"] = side;
  out["min_mobility"] = min_mobility;
  out["mean_mobility"] = mean_mobility;
  out["poor_fraction"] = poor_fraction;
  out["tilt_deg"] = tilt;
  out["cost"] = p.cost;
  out["length_m"] = p.length_m;
  out["max_step_height_m"] = p.max_step_height_m;
  out["expansions"] = p.expansions;
  out["planning_time_s"] = p.planning_time_s;
  out["time_limit_reached"] = p.time_limit_reached;
  return out;
}

py::array_t<bool> reachable(const MapHandle& h, const py::handle& start, const py::object& points,
                            const std::string& frame_name, double max_drop, const py::kwargs& robot) {
  const Frame frame = parseFrame(frame_name);
  if (!(max_drop >= 0 && std::isfinite(max_drop))) throw py::value_error("max_drop must be a distance >= 0 in metres");
  mapping::ReachParams params;
  std::vector<std::string> known = mapping::robotParameterNames();
  known.emplace_back("start_radius_m");
  apply(
      robot,
      [&](const std::string& name, double v) {
        if (name != "start_radius_m") return mapping::setRobotParameter(params.robot, name, v);
        params.start_radius_m = v;
        return true;
      },
      known, "reachable");
  const Eigen::Vector3d s = pointToMap(h, start, "start", frame);
  const auto p = rows(points, 3, "points");
  py::array_t<bool> out(p.shape(0));
  auto o = out.mutable_unchecked<1>();
  const auto in = p.unchecked<2>();
  {
    py::gil_scoped_release unlocked;
    const auto kept = h.reach_cache->reachability(h.map->surfaceColumns(), s, params);
    const mapping::Reachability& reach = *kept;
    for (py::ssize_t i = 0; i < p.shape(0); ++i) {
      Eigen::Vector3d q(in(i, 0), in(i, 1), in(i, 2));
      if (frame == Frame::kWorld) q = h.map->worldToMap(q);
      const mapping::Place* place = q.allFinite() ? reach.placeBelow(q, max_drop) : nullptr;
      o(i) = place != nullptr && place->reachable;
    }
  }
  return out;
}

}  // namespace

void bindPlanning(py::module_& m) {
  m.def("plan", &plan, py::arg("map"), py::arg("start"), py::arg("goal"), py::arg("frame") = "map",
        "Footsteps from START to GOAL (points on or above the surfaces, in `frame`). Keyword arguments "
        "set the robot (sole_length_m, max_step_m, min_mobility, ...: RobotParams) and the search "
        "(heuristic_weight, time_limit_s, ...: PlanParams). Returns a dict: found, reason (why not, in "
        "words), xyz (N, 3) and yaw of the footsteps (the start stance first), side (0 left, 1 right), "
        "min_mobility, mean_mobility, poor_fraction (what the standability rule checks), tilt_deg, cost, length_m, max_step_height_m, expansions, planning_time_s.");
  m.def("reachable", &reachable, py::arg("map"), py::arg("start"), py::arg("points"), py::arg("frame") = "map",
        py::arg("max_drop") = 0.5,
        "For each point (N, 3): whether the surface found within MAX_DROP metres below it is one the robot "
        "can walk to from START, by whole soles and steps within its limits (the keyword arguments of "
        "plan()'s robot). A bool array.");
}

}  // namespace mobmap::python
