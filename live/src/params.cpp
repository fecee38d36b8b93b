#include "params.hpp"

#include "mobmap/mapping/live_mapper.hpp"

#include <cmath>
#include <cstdlib>
#include <functional>
#include <map>
#include <stdexcept>

namespace mobmap::live {
namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
}

double number(const std::string& text, const std::string& what) {
  const std::string t = trim(text);
  char* end = nullptr;
  const double v = std::strtod(t.c_str(), &end);
  if (t.empty() || end != t.c_str() + t.size()) throw std::invalid_argument(what + " must be a number, got \"" + text + "\"");
  return v;
}

int integer(const std::string& text, const std::string& what) {
  const double v = number(text, what);
  if (v != std::floor(v) || std::abs(v) > 1e9) throw std::invalid_argument(what + " must be a whole number, got \"" + text + "\"");
  return static_cast<int>(v);
}

bool boolean(const std::string& text, const std::string& what) {
  const std::string t = trim(text);
  if (t == "true" || t == "True" || t == "1") return true;
  if (t == "false" || t == "False" || t == "0") return false;
  throw std::invalid_argument(what + " must be true or false, got \"" + text + "\"");
}

std::string text(const std::string& s) {
  std::string t = trim(s);
  if (t.size() >= 2 && (t.front() == '"' || t.front() == '\'') && t.back() == t.front()) t = t.substr(1, t.size() - 2);
  return t;
}

std::vector<double> numbers(const std::string& s, const std::string& what) {
  std::string t = trim(s);
  if (t.size() < 2 || t.front() != '[' || t.back() != ']') throw std::invalid_argument(what + " must be a list [a, b, c], got \"" + s + "\"");
  t = t.substr(1, t.size() - 2);
  std::vector<double> out;
  if (trim(t).empty()) return out;
  std::size_t at = 0;
  for (;;) {
    const std::size_t comma = t.find(',', at);
    out.push_back(number(t.substr(at, comma - at), what));
    if (comma == std::string::npos) break;
    at = comma + 1;
  }
  return out;
}

using Setter = std::function<void(Params&, const std::string&, const std::string&)>;

const std::vector<std::pair<std::string, Setter>>& table() {
  const auto str = [](std::string Params::*m) { return Setter([m](Params& p, const std::string& v, const std::string&) { p.*m = text(v); }); };
  const auto flag = [](bool Params::*m) { return Setter([m](Params& p, const std::string& v, const std::string& w) { p.*m = boolean(v, w); }); };
  const auto real = [](double Params::*m) { return Setter([m](Params& p, const std::string& v, const std::string& w) { p.*m = number(v, w); }); };
  const auto whole = [](int Params::*m) { return Setter([m](Params& p, const std::string& v, const std::string& w) { p.*m = integer(v, w); }); };
  const auto robot = [](double mapping::RobotParams::*m) {
    return Setter([m](Params& p, const std::string& v, const std::string& w) { p.reach.robot.*m = number(v, w); });
  };
  static const std::vector<std::pair<std::string, Setter>> t = {
      {"world_frame", str(&Params::world_frame)},
      {"base_frame", str(&Params::base_frame)},
      {"map_frame", str(&Params::map_frame)},
      {"compressed", flag(&Params::compressed)},
      {"use_points", flag(&Params::use_points)},
      {"use_imu", flag(&Params::use_imu)},
      {"gravity", Setter([](Params& p, const std::string& v, const std::string& w) { p.gravity = numbers(v, w); })},
      {"resolution", real(&Params::resolution)},
      {"max_range", real(&Params::max_range)},
      {"config", str(&Params::config)},
      {"threads", whole(&Params::threads)},
      {"tf_wait", real(&Params::tf_wait)},
      {"max_pose_gap", real(&Params::max_pose_gap)},
      {"warn_period", real(&Params::warn_period)},
      {"cloud_rate", real(&Params::cloud_rate)},
      {"occupancy_rate", real(&Params::occupancy_rate)},
      {"grid_map_rate", real(&Params::grid_map_rate)},
      {"octomap_rate", real(&Params::octomap_rate)},
      {"status_rate", real(&Params::status_rate)},
      {"grid_map_size", real(&Params::grid_map_size)},
      {"grid_map_resolution", real(&Params::grid_map_resolution)},
      {"clearance", real(&Params::clearance)},
      {"occupancy_cell", real(&Params::occupancy_cell)},
      {"save_path", str(&Params::save_path)},
      {"save_on_exit", str(&Params::save_on_exit)},
      {"http_port", whole(&Params::http_port)},
      {"http_address", str(&Params::http_address)},
      {"sole_length", robot(&mapping::RobotParams::sole_length_m)},
      {"sole_width", robot(&mapping::RobotParams::sole_width_m)},
      {"min_mobility", robot(&mapping::RobotParams::min_mobility)},
      {"max_tilt", robot(&mapping::RobotParams::max_tilt_deg)},
      {"max_step", robot(&mapping::RobotParams::max_step_m)},
      {"max_stride", robot(&mapping::RobotParams::max_stride_m)},
      {"swing_clearance", robot(&mapping::RobotParams::swing_clearance_m)},
      {"max_gap", robot(&mapping::RobotParams::max_gap_m)},
      {"stance_width", robot(&mapping::RobotParams::stance_width_m)},
  };
  return t;
}

void positive(double v, const std::string& name, bool zero_ok = false) {
  if (!std::isfinite(v) || v < 0 || (!zero_ok && v == 0)) {
    throw std::invalid_argument(name + " must be a finite number " + (zero_ok ? "of at least 0" : "above 0") + ", got " +
                                std::to_string(v));
  }
}

}  // namespace

const std::vector<std::string>& paramNames() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const auto& [name, set] : table()) n.push_back(name);
    return n;
  }();
  return names;
}

void setParam(Params& p, const std::string& name, const std::string& value, const std::string& prefix) {
  for (const auto& [n, set] : table()) {
    if (n == name) {
      set(p, value, prefix + name);
      return;
    }
  }
  throw std::invalid_argument("unknown parameter " + prefix + name + " (docs/ROS.md lists them)");
}

void validate(Params& p, const std::string& prefix) {
  p.reach.start_rule = mapping::ReachParams::Start::kLargestLevel;
  for (const auto& [v, name] : std::vector<std::pair<double, const char*>>{
           {p.resolution, "resolution"}, {p.max_range, "max_range"}, {p.grid_map_size, "grid_map_size"},
           {p.grid_map_resolution, "grid_map_resolution"}, {p.clearance, "clearance"}, {p.occupancy_cell, "occupancy_cell"}}) {
    positive(v, prefix + name);
  }
  for (const auto& [v, name] : std::vector<std::pair<double, const char*>>{
           {p.tf_wait, "tf_wait"}, {p.max_pose_gap, "max_pose_gap"}, {p.warn_period, "warn_period"}, {p.cloud_rate, "cloud_rate"},
           {p.occupancy_rate, "occupancy_rate"}, {p.grid_map_rate, "grid_map_rate"}, {p.octomap_rate, "octomap_rate"},
           {p.status_rate, "status_rate"}}) {
    positive(v, prefix + name, true);
  }
  if (p.grid_map_size / p.grid_map_resolution > 2000) {
    throw std::invalid_argument(prefix + "grid_map_size / " + prefix + "grid_map_resolution: at most 2000 cells a side");
  }
  if (!p.gravity.empty() && p.gravity.size() != 3) throw std::invalid_argument(prefix + "gravity must be 3 numbers (down, world frame)");
  if (p.threads < 0 || p.threads > mapping::LiveMapper::kMaxPerceptionThreads) {
    throw std::invalid_argument(prefix + "threads must be 0 to " + std::to_string(mapping::LiveMapper::kMaxPerceptionThreads));
  }
  if (p.http_port > 65535) throw std::invalid_argument(prefix + "http_port must be at most 65535");
  try {
    mapping::validate(p.reach);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("robot limits: ") + e.what());
  }
}

}  // namespace mobmap::live
