// Paper step 7: Delaunay roughness (eqs. 8-10).
// CGAL lives here and in planar_delaunay.cpp only: its headers are heavy and no public
// header needs them.
#include "mobmap/perception/roughness.hpp"
#include "planar_delaunay.hpp"

#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <Eigen/Geometry>

namespace mobmap::perception {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using VertexBase = CGAL::Triangulation_vertex_base_with_info_2<int, Kernel>;
using Tds = CGAL::Triangulation_data_structure_2<VertexBase>;
using Delaunay = CGAL::Delaunay_triangulation_2<Kernel, Tds>;

}  // namespace

std::vector<std::array<int, 3>> delaunayTriangles(const std::vector<Eigen::Vector2d>& points, Triangulator which) {
  std::vector<std::array<int, 3>> out;
  if (which == Triangulator::kCgal) {
    std::vector<std::pair<Kernel::Point_2, int>> in;
    in.reserve(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (points[i].allFinite()) in.emplace_back(Kernel::Point_2(points[i].x(), points[i].y()), static_cast<int>(i));
    }
    Delaunay dt;
    dt.insert(in.begin(), in.end());
    for (auto f = dt.finite_faces_begin(); f != dt.finite_faces_end(); ++f) {
      out.push_back({f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()});
    }
    return out;
  }
  std::vector<double> x(points.size()), y(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    x[i] = points[i].x();
    y[i] = points[i].y();
  }
  detail::PlanarDelaunay dt;
  if (!dt.build(x.data(), y.data(), static_cast<int>(points.size()))) return delaunayTriangles(points, Triangulator::kCgal);
  const auto& c = dt.corners();
  for (std::size_t t = 0; t + 2 < c.size(); t += 3) {
    if (c[t] != dt.infinite() && c[t + 1] != dt.infinite() && c[t + 2] != dt.infinite()) out.push_back({c[t], c[t + 1], c[t + 2]});
  }
  return out;
}

std::pair<double, double> delaunayRoughness(const std::vector<Eigen::Vector3f>& points, const std::vector<int>& idx,
                                            const Eigen::Vector4f& plane, double max_edge_m, Triangulator which) {
  if (idx.size() < 3) return {1.0, 0.0};
  // Orthonormal basis (e1, e2) of the plane.
  const Eigen::Vector3d n = plane.head<3>().cast<double>().normalized();
  const Eigen::Vector3d helper = std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d e1 = n.cross(helper).normalized();
  const Eigen::Vector3d e2 = n.cross(e1);
  thread_local std::vector<double> px, py;
  px.resize(idx.size());
  py.resize(idx.size());
  for (std::size_t j = 0; j < idx.size(); ++j) {
    const Eigen::Vector3d p = points[static_cast<std::size_t>(idx[j])].cast<double>();
    px[j] = p.dot(e1);
    py[j] = p.dot(e2);
  }
  const double max_edge2 = max_edge_m * max_edge_m;
  double true_area = 0.0, projected_area = 0.0;
  const auto addTriangle = [&](int ia, int ib, int ic) {
    const Eigen::Vector3d a = points[static_cast<std::size_t>(ia)].cast<double>();
    const Eigen::Vector3d b = points[static_cast<std::size_t>(ib)].cast<double>();
    const Eigen::Vector3d c = points[static_cast<std::size_t>(ic)].cast<double>();
    if ((b - a).squaredNorm() > max_edge2 || (c - b).squaredNorm() > max_edge2 || (a - c).squaredNorm() > max_edge2) {
      return;  // bridges a gap in the segment
    }
    const Eigen::Vector3d cross = (b - a).cross(c - a);
    true_area += 0.5 * cross.norm();                 // eq. 8: area of the 3D triangle
    projected_area += 0.5 * std::abs(cross.dot(n));  // eq. 9: same triangle projected on the plane
  };

  thread_local detail::PlanarDelaunay own;
  if (which == Triangulator::kOwn && own.build(px.data(), py.data(), static_cast<int>(idx.size()))) {
    const auto& c = own.corners();
    const int inf = own.infinite();
    for (std::size_t t = 0; t + 2 < c.size(); t += 3) {
      if (c[t] == inf || c[t + 1] == inf || c[t + 2] == inf) continue;
      addTriangle(idx[static_cast<std::size_t>(c[t])], idx[static_cast<std::size_t>(c[t + 1])],
                  idx[static_cast<std::size_t>(c[t + 2])]);
    }
  } else {
    // CGAL. Segments arrive in a spatially coherent order (voxels in the order the
    // image's rows first reached them): then inserting in that order, each point
    // located from the previous one, skips CGAL's spatial sort. Any other order (an
    // unorganized cloud) gets the sorted insertion.
    double step_sum = 0.0;
    for (std::size_t j = 1; j < idx.size(); ++j) step_sum += std::hypot(px[j] - px[j - 1], py[j] - py[j - 1]);
    std::vector<std::pair<Kernel::Point_2, int>> projected;
    projected.reserve(idx.size());
    for (std::size_t j = 0; j < idx.size(); ++j) projected.emplace_back(Kernel::Point_2(px[j], py[j]), idx[j]);
    Delaunay dt;
    if (step_sum <= 2.0 * max_edge_m * static_cast<double>(idx.size() - 1)) {
      Delaunay::Vertex_handle last;
      for (const auto& [q, i] : projected) {
        last = dt.insert(q, last == Delaunay::Vertex_handle() ? Delaunay::Face_handle() : last->face());
        last->info() = i;
      }
    } else {
      dt.insert(projected.begin(), projected.end());  // spatially sorted insertion
    }
    for (auto f = dt.finite_faces_begin(); f != dt.finite_faces_end(); ++f) {
      addTriangle(f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info());
    }
  }
  if (projected_area <= 0.0) return {1.0, 0.0};
  return {true_area / projected_area, true_area};  // eq. 10
}

}  // namespace mobmap::perception
