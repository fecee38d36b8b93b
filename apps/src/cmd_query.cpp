#include "commands.hpp"
#include "io_error.hpp"
#include "map_files.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <sstream>

namespace mobmap::app {
namespace {

nlohmann::json pointJson(const mapping::PointQuery& q) {
  nlohmann::json j{{"state", mapping::toString(q.state)},
                   {"voxel_centre", {q.centre.x(), q.centre.y(), q.centre.z()}},
                   {"voxel_size_m", q.size_m},
                   {"count", q.count},
                   {"occupancy", q.occupancy}};
  j["mobility"] = q.has_mobility ? nlohmann::json(q.mobility) : nlohmann::json(nullptr);
  j["variance"] = q.has_mobility ? nlohmann::json(q.variance) : nlohmann::json(nullptr);
  return j;
}

void printPoint(const mapping::PointQuery& q) {
  std::printf("%-8s voxel (%.3f, %.3f, %.3f) size %.3f m", mapping::toString(q.state), q.centre.x(), q.centre.y(),
              q.centre.z(), q.size_m);
  if (q.has_mobility) {
    std::printf("  mobility %.3f  variance %.4g  observations %d\n", q.mobility, q.variance, q.count);
  } else {
    std::printf("  mobility unknown\n");
  }
}

}  // namespace

Command addQueryCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("query", "Ask a map about points (state, mobility) or about a foot placement");
  struct Options {
    std::string map;
    std::vector<double> xyz;
    std::vector<double> foot;
    double snap = -1;
    std::string frame = "map";
    bool json = false;
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("MAP", o->map, "A .ot map written by `mobmap build`")->required();
  cmd->add_option("XYZ", o->xyz, "A point X Y Z (metres); without it, points are read as 'x y z' lines from standard input")->expected(3);
  cmd->add_option("--foot", o->foot, "X Y Z YAW LENGTH WIDTH: a rectangular sole (yaw in radians about +z)")->expected(6);
  cmd->add_option("--snap", o->snap, "Search down along gravity up to this many metres for the supporting surface");
  cmd->add_option("--input-frame", o->frame, "Frame of the given coordinates: map (gravity aligned) or world (the data's own)")
      ->check(CLI::IsMember({"map", "world"}))->capture_default_str();
  cmd->add_flag("--json", o->json, "One JSON object per answer");
  return [o]() {
    const mapping::MobilityMap map = loadMap(o->map);
    auto toMap = [&](Eigen::Vector3d p) { return o->frame == "world" ? map.worldToMap(p) : p; };
    if (!o->foot.empty()) {
      const Eigen::Vector3d c = toMap({o->foot[0], o->foot[1], o->foot[2]});
      double yaw = o->foot[3];
      if (o->frame == "world") {  // rotate the heading with the frame
        const Eigen::Vector3d h = map.rotationMapWorld() * Eigen::Vector3d(std::cos(yaw), std::sin(yaw), 0);
        yaw = std::atan2(h.y(), h.x());
      }
      if (!(o->foot[4] > 0 && o->foot[5] > 0)) throw UsageError("--foot LENGTH and WIDTH must be > 0");
      const auto f = map.footprint({c.x(), c.y(), c.z(), yaw, o->foot[4], o->foot[5]});
      if (o->json) {
        std::cout << nlohmann::json{{"min_mobility", f.min_mobility}, {"mean_mobility", f.mean_mobility},
                                    {"known_fraction", f.known_fraction},
                                    {"max_height_difference_m", f.max_height_difference_m}, {"samples", f.samples}}
                         .dump()
                  << "\n";
      } else {
        std::printf("sole: min mobility %.3f, mean %.3f, known %.0f %% of %d samples, height difference %.3f m\n",
                    f.min_mobility, f.mean_mobility, 100 * f.known_fraction, f.samples, f.max_height_difference_m);
      }
      return 0;
    }
    auto answer = [&](const Eigen::Vector3d& p_in) {
      const Eigen::Vector3d p = toMap(p_in);
      mapping::PointQuery q;
      bool found = true;
      if (o->snap >= 0) {
        const auto s = map.snapDown(p, o->snap);
        found = s.has_value();
        if (found) q = *s;
      } else {
        q = map.query(p);
      }
      if (o->json) {
        nlohmann::json j = found ? pointJson(q) : nlohmann::json{{"state", "no surface within snap distance"}};
        j["query"] = {p.x(), p.y(), p.z()};
        std::cout << j.dump() << "\n";
      } else if (found) {
        printPoint(q);
      } else {
        std::printf("no surface within %.3f m below (%.3f, %.3f, %.3f)\n", o->snap, p.x(), p.y(), p.z());
      }
    };
    if (!o->xyz.empty()) {
      answer({o->xyz[0], o->xyz[1], o->xyz[2]});
      return 0;
    }
    std::string line;
    int line_no = 0;
    while (std::getline(std::cin, line)) {
      ++line_no;
      if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
      std::istringstream in(line);
      Eigen::Vector3d p;
      std::string extra;
      if (!(in >> p.x() >> p.y() >> p.z()) || (in >> extra) || !p.allFinite()) {
        throw UsageError("standard input line " + std::to_string(line_no) + ": expected 'x y z', got '" + line + "'");
      }
      answer(p);
    }
    return 0;
  };
}

Command addInfoCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("info", "Describe a map: resolution, bounds, nodes, memory, mobility histogram, metadata");
  auto map_path = std::make_shared<std::string>();
  cmd->add_option("MAP", *map_path, "A .ot map")->required();
  return [map_path]() {
    const mapping::MobilityMap map = loadMap(*map_path);
    const auto& t = map.tree();
    double x0, y0, z0, x1, y1, z1;
    t.getMetricMin(x0, y0, z0);
    t.getMetricMax(x1, y1, z1);
    std::size_t surface = 0, free = 0, unknown_mob = 0;
    int hist[10] = {0};
    for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) {
      if (!t.isNodeOccupied(*it)) {
        ++free;
        continue;
      }
      ++surface;
      if (!it->hasMobility()) {
        ++unknown_mob;
        continue;
      }
      ++hist[std::min(9, static_cast<int>(it->mobility() * 10))];
    }
    std::printf("%s: %s, resolution %.3f m\n", map_path->c_str(), t.getTreeType().c_str(), t.getResolution());
    std::printf("bounds (map frame, z up): x %.2f..%.2f  y %.2f..%.2f  z %.2f..%.2f m\n", x0, x1, y0, y1, z0, z1);
    std::printf("nodes %zu, leaves %zu (surface %zu, free %zu), memory %.1f MB (%zu bytes per node)\n", t.size(),
                t.getNumLeafNodes(), surface, free, t.memoryUsage() / 1e6, t.memoryUsageNode());
    std::printf("surface voxels without a mobility estimate: %zu\nmobility histogram of surface voxels:\n", unknown_mob);
    const std::size_t known = surface - unknown_mob;
    for (int b = 0; b < 10; ++b) {
      const int bar = known ? static_cast<int>(50.0 * hist[b] / known) : 0;
      std::printf("  %.1f-%.1f %8d %s\n", b / 10.0, (b + 1) / 10.0, hist[b], std::string(static_cast<std::size_t>(bar), '#').c_str());
    }
    const auto meta = readMapMetadata(*map_path);
    if (!meta.empty()) std::printf("metadata (%s.json):\n%s\n", mapStem(*map_path).c_str(), meta.dump(1).c_str());
    return 0;
  };
}

}  // namespace mobmap::app
