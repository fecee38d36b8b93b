#include "io/ground_truth.hpp"

#include "io/files.hpp"
#include "io/io_error.hpp"

#include <nlohmann/json.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>

namespace mobmap::app {
namespace {

// Distance from p to a convex planar polygon.
double polygonDistance(const std::vector<Eigen::Vector3d>& poly, const Eigen::Vector3d& p) {
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < poly.size(); ++i) n += poly[i].cross(poly[(i + 1) % poly.size()]);
  n.normalize();
  const double h = n.dot(p - poly[0]);
  const Eigen::Vector3d q = p - h * n;  // projection on the plane
  bool inside = true;
  for (std::size_t i = 0; i < poly.size() && inside; ++i) {
    const Eigen::Vector3d& a = poly[i];
    const Eigen::Vector3d& b = poly[(i + 1) % poly.size()];
    inside = n.dot((b - a).cross(q - a)) >= 0;
  }
  if (inside) return std::abs(h);
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Eigen::Vector3d& a = poly[i];
    const Eigen::Vector3d& b = poly[(i + 1) % poly.size()];
    const double t = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
    best = std::min(best, (p - (a + t * (b - a))).norm());
  }
  return best;
}

Eigen::Vector3d vec(const nlohmann::json& j) { return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()}; }

}  // namespace

double TruthSurface::distance(const Eigen::Vector3d& p) const {
  if (pyramid_field) {
    const double u = (p.x() - x0) / pitch, v = (p.y() - y0) / pitch;
    if (u < 0 || v < 0 || u > nx || v > ny) return std::numeric_limits<double>::infinity();
    const double fu = u - std::floor(u), fv = v - std::floor(v);
    const double h = height * (1.0 - 2.0 * std::max(std::abs(fu - 0.5), std::abs(fv - 0.5)));
    return std::abs(p.z() - h);  // vertical distance: facets are 48 degrees, a fair proxy
  }
  if (rough_field) {  // the prism over the footprint's rectangle up to top_m
    Eigen::AlignedBox2d box;
    for (const auto& poly : polygons) {
      for (const Eigen::Vector3d& v : poly) box.extend(v.head<2>());
    }
    const double dx = std::max({box.min().x() - p.x(), 0.0, p.x() - box.max().x()});
    const double dy = std::max({box.min().y() - p.y(), 0.0, p.y() - box.max().y()});
    const double dz = std::max({-p.z(), 0.0, p.z() - top_m});
    return std::sqrt(dx * dx + dy * dy + dz * dz);
  }
  double best = std::numeric_limits<double>::infinity();
  for (const auto& poly : polygons) best = std::min(best, polygonDistance(poly, p));
  return best;
}

GroundTruth loadGroundTruth(const std::string& path) {
  GroundTruth t;
  try {
    const auto j = nlohmann::json::parse(readTextFile(path, 64 << 20));
    if (j.value("format", "") != "mobmap-ground-truth") throw IoError(path, "not a mobmap ground_truth.json");
    t.gravity_down = vec(j.at("gravity_down_world"));
    Eigen::Vector3d shift = Eigen::Vector3d::Zero();
    if (j.contains("moving_obstacle")) shift = vec(j["moving_obstacle"].at("to")) - vec(j["moving_obstacle"].at("from"));
    for (const auto& js : j.at("surfaces")) {
      TruthSurface s;
      s.id = js.at("id").get<int>();
      s.name = js.at("name").get<std::string>();
      s.kind = js.at("kind").get<std::string>();
      s.slope_deg = js.at("slope_deg").get<double>();
      s.roughness = js.at("roughness").get<double>();
      s.expected_mobility = js.at("expected_mobility").get<double>();
      if (js.contains("pixels_seen")) s.seen = js.at("pixels_seen").get<long long>() > 0;
      const bool moving = js.value("moving", false);
      const auto& g = js.at("geometry");
      if (g.at("type") == "pyramid_field") {
        s.pyramid_field = true;
        s.x0 = g.at("x0").get<double>();
        s.y0 = g.at("y0").get<double>();
        s.nx = g.at("nx").get<int>();
        s.ny = g.at("ny").get<int>();
        s.pitch = g.at("pitch_m").get<double>();
        s.height = g.at("height_m").get<double>();
      } else if (g.at("type") == "rough_field") {
        s.rough_field = true;
        s.top_m = g.at("top_m").get<double>();
        for (const auto& jp : g.at("footprint")) {
          std::vector<Eigen::Vector3d> poly;
          for (const auto& v : jp) poly.push_back(vec(v));
          if (poly.size() < 3) throw IoError(path, "surface " + std::to_string(s.id) + " has a polygon with fewer than 3 vertices");
          s.polygons.push_back(std::move(poly));
        }
      } else {
        for (const auto& jp : g.at("polygons")) {
          std::vector<Eigen::Vector3d> poly;
          for (const auto& v : jp) poly.push_back(vec(v) + (moving ? shift : Eigen::Vector3d::Zero()));
          if (poly.size() < 3) throw IoError(path, "surface " + std::to_string(s.id) + " has a polygon with fewer than 3 vertices");
          s.polygons.push_back(std::move(poly));
        }
      }
      t.surfaces.push_back(std::move(s));
    }
  } catch (const nlohmann::json::exception& e) {
    throw IoError(path, std::string("malformed ground truth: ") + e.what());
  }
  return t;
}

Evaluation evaluateMap(const mapping::MobilityMap& map, const GroundTruth& truth, int min_count, double tolerance_m,
                       double edge_band_m) {
  Evaluation ev;
  ev.surfaces.resize(truth.surfaces.size());
  for (std::size_t i = 0; i < truth.surfaces.size(); ++i) ev.surfaces[i].surface = &truth.surfaces[i];
  const auto& tree = map.tree();
  const double res = tree.getResolution();
  const double edge_band = edge_band_m >= 0 ? edge_band_m : 0.5 * std::sqrt(3.0) * res;
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) {
    if (!tree.isNodeOccupied(*it) || !it->hasMobility() || it->count() < min_count) continue;
    const Eigen::Vector3d p = map.mapToWorld(Eigen::Vector3d(it.getX(), it.getY(), it.getZ()));
    int best = -1;
    double best_d = tolerance_m;
    for (std::size_t i = 0; i < truth.surfaces.size(); ++i) {
      if (!truth.surfaces[i].seen) continue;  // its neighbours' points, displaced by noise
      const double d = truth.surfaces[i].distance(p);
      if (d <= best_d) {
        best_d = d;
        best = static_cast<int>(i);
      }
    }
    if (best < 0) {
      ++ev.unassigned;
      continue;
    }
    SurfaceScore& sc = ev.surfaces[static_cast<std::size_t>(best)];
    const double expected = sc.surface->expected_mobility;
    const double err = std::abs(it->mobility() - expected);
    // An edge voxel: its cell also holds (touches) a surface whose answer differs.
    bool edge = false;
    double err_any = err;
    for (std::size_t i = 0; i < truth.surfaces.size(); ++i) {
      if (static_cast<int>(i) == best || !truth.surfaces[i].seen) continue;
      if (std::abs(truth.surfaces[i].expected_mobility - expected) <= 0.1) continue;
      if (truth.surfaces[i].distance(p) <= edge_band) {
        edge = true;
        err_any = std::min(err_any, std::abs(it->mobility() - truth.surfaces[i].expected_mobility));
      }
    }
    {
      const bool pred = it->mobility() >= 0.5, truth_trav = expected >= 0.5;
      if (pred && truth_trav) ++ev.true_traversable;
      if (pred && !truth_trav) ++ev.false_traversable;
      if (!pred && !truth_trav) ++ev.true_untraversable;
      if (!pred && truth_trav) ++ev.false_untraversable;
    }
    if (edge) {
      ++ev.edge_voxels;
      ev.edge_mean_abs_error += err;
      ev.edge_mean_abs_error_any += err_any;
      continue;
    }
    ++sc.voxels;
    sc.mean_abs_error += err;
    sc.worst_abs_error = std::max(sc.worst_abs_error, err);
    const bool pred = it->mobility() >= 0.5, truth_trav = expected >= 0.5;
    sc.right_side += pred == truth_trav;
    sc.area_observed_m2 += res * res / std::max(0.1, std::cos(sc.surface->slope_deg * M_PI / 180));
  }
  if (ev.edge_voxels > 0) {
    ev.edge_mean_abs_error /= ev.edge_voxels;
    ev.edge_mean_abs_error_any /= ev.edge_voxels;
  }
  for (auto& sc : ev.surfaces) {
    if (sc.voxels == 0) continue;
    sc.mean_abs_error /= sc.voxels;
    sc.right_side /= sc.voxels;
  }
  return ev;
}

}  // namespace mobmap::app
