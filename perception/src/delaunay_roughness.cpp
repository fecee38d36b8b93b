// CGAL lives here only: its headers are heavy and no public header needs them.
#include "mobmap/perception/stages.hpp"

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

std::pair<double, double> delaunayRoughness(const std::vector<Eigen::Vector3f>& points, const std::vector<int>& idx,
                                            const Eigen::Vector4f& plane, double max_edge_m) {
  if (idx.size() < 3) return {1.0, 0.0};
  // Orthonormal basis (e1, e2) of the plane.
  const Eigen::Vector3d n = plane.head<3>().cast<double>().normalized();
  const Eigen::Vector3d helper = std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d e1 = n.cross(helper).normalized();
  const Eigen::Vector3d e2 = n.cross(e1);
  std::vector<std::pair<Kernel::Point_2, int>> projected;
  projected.reserve(idx.size());
  for (int i : idx) {
    const Eigen::Vector3d p = points[static_cast<std::size_t>(i)].cast<double>();
    projected.emplace_back(Kernel::Point_2(p.dot(e1), p.dot(e2)), i);
  }
  // Segments arrive in a spatially coherent order (voxels in the order the image's rows
  // first reached them): then inserting in that order, each point located from the
  // previous one, skips CGAL's Hilbert sort (~2 ms of ~21 per frame). Any other order
  // (an unorganized cloud) gets the sorted insertion. The triangulation is the same
  // unless four or more points lie on one circle (then which diagonal is drawn may
  // depend on the order).
  double step_sum = 0.0;
  for (std::size_t j = 1; j < projected.size(); ++j) {
    step_sum += std::sqrt(CGAL::squared_distance(projected[j].first, projected[j - 1].first));
  }
  Delaunay dt;
  if (step_sum <= 2.0 * max_edge_m * static_cast<double>(projected.size() - 1)) {
    Delaunay::Vertex_handle last;
    for (const auto& [q, i] : projected) {
      last = dt.insert(q, last == Delaunay::Vertex_handle() ? Delaunay::Face_handle() : last->face());
      last->info() = i;
    }
  } else {
    dt.insert(projected.begin(), projected.end());  // spatially sorted insertion
  }
  const double max_edge2 = max_edge_m * max_edge_m;
  double true_area = 0.0, projected_area = 0.0;
  for (auto f = dt.finite_faces_begin(); f != dt.finite_faces_end(); ++f) {
    const Eigen::Vector3d a = points[static_cast<std::size_t>(f->vertex(0)->info())].cast<double>();
    const Eigen::Vector3d b = points[static_cast<std::size_t>(f->vertex(1)->info())].cast<double>();
    const Eigen::Vector3d c = points[static_cast<std::size_t>(f->vertex(2)->info())].cast<double>();
    if ((b - a).squaredNorm() > max_edge2 || (c - b).squaredNorm() > max_edge2 || (a - c).squaredNorm() > max_edge2) {
      continue;  // bridges a gap in the segment
    }
    const Eigen::Vector3d cross = (b - a).cross(c - a);
    true_area += 0.5 * cross.norm();             // eq. 8: area of the 3D triangle
    projected_area += 0.5 * std::abs(cross.dot(n));  // eq. 9: same triangle projected on the plane
  }
  if (projected_area <= 0.0) return {1.0, 0.0};
  return {true_area / projected_area, true_area};  // eq. 10
}

}  // namespace mobmap::perception
