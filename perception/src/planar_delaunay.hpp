#pragma once
// The library's own 2D Delaunay triangulation, for the roughness of segments (paper
// eqs. 8-10). Internal: delaunayRoughness() is the public way in.
#include <cstdint>
#include <vector>

namespace mobmap::perception::detail {

/// Incremental Delaunay triangulation (Lawson flips). Points go in by rounds of growing
/// density, each located by a walk from a triangle near it (a coarse grid keeps one per
/// cell), so any input order is fine and no sort is needed. Like CGAL's
/// Delaunay_triangulation_2 it closes the plane with an infinite vertex (index n), so
/// points outside the hull need no special case. Its predicates are exact: a
/// floating-point filter with Shewchuk's error bounds, CGAL's exact predicates when the
/// filter cannot decide. Duplicate points are skipped. For points with no four on a
/// circle the result is the unique Delaunay triangulation, CGAL's; with cocircular points
/// which diagonal is drawn may depend on the order of insertion.
class PlanarDelaunay {
 public:
  /// Triangulates points (x[i], y[i]), i < n; points with a non-finite coordinate are
  /// left out. Returns false only if a walk did not end within its step limit (never
  /// seen; the caller then uses CGAL).
  bool build(const double* x, const double* y, int n);
  /// Corners of every triangle, three per triangle, counter-clockwise; triangles with a
  /// corner equal to `infinite()` lie outside the hull and are not triangles of the set.
  const std::vector<int>& corners() const { return tv_; }
  int infinite() const { return n_; }

 private:
  int orient(int a, int b, int p) const;
  bool mustFlip(int e) const;
  int addTriangle(int a, int b, int c);
  int corner(int h) const { return tv_[static_cast<std::size_t>(h)]; }  // where half-edge h starts
  int twin(int h) const { return th_[static_cast<std::size_t>(h)]; }
  void setCorners(int base, int a, int b, int c) {
    tv_[static_cast<std::size_t>(base)] = a;
    tv_[static_cast<std::size_t>(base + 1)] = b;
    tv_[static_cast<std::size_t>(base + 2)] = c;
  }
  void link(int e, int f) {
    th_[static_cast<std::size_t>(e)] = f;
    th_[static_cast<std::size_t>(f)] = e;
  }
  int locate(int p, int t, int& on_edge, bool& duplicate) const;
  void insertInFace(int p, int t);
  void insertInEdge(int p, int e);
  void flip(int e);
  void legalize();

  std::vector<double> xy_;  // x, y of each point, side by side
  int n_ = 0;
  std::vector<int> tv_;     // corner vertex of each half-edge: half-edge e runs tv_[e] -> tv_[next(e)]
  std::vector<int> th_;     // twin half-edge
  std::vector<int> stack_;   // half-edges still to check in legalize()
  std::vector<int> order_;   // finite input points, in input order
  std::vector<int> sorted_;  // the same in insertion order
  std::vector<int> grid_;    // a triangle near the last point inserted in each cell
  std::vector<std::uint8_t> level_;  // insertion round of each finite point
};

}  // namespace mobmap::perception::detail
