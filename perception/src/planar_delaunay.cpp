#include "planar_delaunay.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace mobmap::perception::detail {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;

// Shewchuk's first-stage error bounds (Adaptive Precision Floating-Point Arithmetic and
// Fast Robust Geometric Predicates, 1997): when |det| exceeds them, the sign of the
// rounded determinant is the sign of the exact one. They assume no fused multiply-add,
// which this module's compile options rule out.
constexpr double kEpsilon = 0x1p-53;
constexpr double kOrientBound = (3.0 + 16.0 * kEpsilon) * kEpsilon;
constexpr double kInCircleBound = (10.0 + 96.0 * kEpsilon) * kEpsilon;

inline int nextEdge(int e) { return e % 3 == 2 ? e - 2 : e + 1; }
inline int prevEdge(int e) { return e % 3 == 0 ? e + 2 : e - 1; }
inline int sign(double v) { return (v > 0) - (v < 0); }

/// > 0 if (a, b, c) turn left, < 0 right, 0 collinear; exact. (|left| + |right|
/// bounds the error whatever their signs; Shewchuk's sharper case split costs branches.)
inline int orientation(double ax, double ay, double bx, double by, double cx, double cy) {
  const double left = (ax - cx) * (by - cy), right = (ay - cy) * (bx - cx), det = left - right;
  if (std::abs(det) > kOrientBound * (std::abs(left) + std::abs(right))) return sign(det);
  return static_cast<int>(CGAL::orientation(Kernel::Point_2(ax, ay), Kernel::Point_2(bx, by), Kernel::Point_2(cx, cy)));
}

/// > 0 if d lies inside the circle through the counter-clockwise a, b, c; exact.
inline int inCircle(double ax, double ay, double bx, double by, double cx, double cy, double dx, double dy) {
  const double adx = ax - dx, ady = ay - dy, bdx = bx - dx, bdy = by - dy, cdx = cx - dx, cdy = cy - dy;
  const double bdxcdy = bdx * cdy, cdxbdy = cdx * bdy, alift = adx * adx + ady * ady;
  const double cdxady = cdx * ady, adxcdy = adx * cdy, blift = bdx * bdx + bdy * bdy;
  const double adxbdy = adx * bdy, bdxady = bdx * ady, clift = cdx * cdx + cdy * cdy;
  const double det = alift * (bdxcdy - cdxbdy) + blift * (cdxady - adxcdy) + clift * (adxbdy - bdxady);
  const double permanent = (std::abs(bdxcdy) + std::abs(cdxbdy)) * alift +
                           (std::abs(cdxady) + std::abs(adxcdy)) * blift +
                           (std::abs(adxbdy) + std::abs(bdxady)) * clift;
  if (std::abs(det) > kInCircleBound * permanent) return sign(det);
  return static_cast<int>(CGAL::side_of_oriented_circle(Kernel::Point_2(ax, ay), Kernel::Point_2(bx, by),
                                                        Kernel::Point_2(cx, cy), Kernel::Point_2(dx, dy)));
}

}  // namespace

inline int PlanarDelaunay::orient(int a, int b, int p) const {
  const double* A = &xy_[2 * static_cast<std::size_t>(a)];
  const double* B = &xy_[2 * static_cast<std::size_t>(b)];
  const double* P = &xy_[2 * static_cast<std::size_t>(p)];
  return orientation(A[0], A[1], B[0], B[1], P[0], P[1]);
}

int PlanarDelaunay::addTriangle(int a, int b, int c) {
  const int t = static_cast<int>(tv_.size()) / 3;
  tv_.insert(tv_.end(), {a, b, c});
  th_.insert(th_.end(), {-1, -1, -1});
  return t;
}

// Half-edge e = u -> v of the triangle (u, v, p), p the point just inserted; its twin
// lies in (v, u, w). Flip if p is strictly inside that triangle's circumcircle. An
// infinite triangle (s, t, inf) stands for the half-plane left of s -> t (outside the
// hull edge t -> s): p is "inside" it when it lies strictly in that half-plane, as in
// CGAL. Points on a circle's boundary do not flip.
bool PlanarDelaunay::mustFlip(int e) const {
  const int f = twin(e);
  const int u = corner(e), v = corner(nextEdge(e)), p = corner(prevEdge(e)), w = corner(prevEdge(f));
  if (u == n_) return orient(w, v, p) > 0;  // (v, inf, w) is the half-plane left of w -> v
  if (v == n_) return orient(u, w, p) > 0;  // (inf, u, w): left of u -> w
  if (w == n_) return orient(v, u, p) > 0;  // (v, u, inf): left of v -> u
  const double* V = &xy_[2 * static_cast<std::size_t>(v)];
  const double* U = &xy_[2 * static_cast<std::size_t>(u)];
  const double* W = &xy_[2 * static_cast<std::size_t>(w)];
  const double* P = &xy_[2 * static_cast<std::size_t>(p)];
  return inCircle(V[0], V[1], U[0], U[1], W[0], W[1], P[0], P[1]) > 0;
}

// (u, v, p) + (v, u, w) -> (u, w, p) + (w, v, p).
void PlanarDelaunay::flip(int e) {
  const int f = twin(e);
  const int b1 = e - e % 3, b2 = f - f % 3;
  const int u = corner(e), v = corner(nextEdge(e)), p = corner(prevEdge(e)), w = corner(prevEdge(f));
  const int vp = twin(nextEdge(e)), pu = twin(prevEdge(e)), uw = twin(nextEdge(f)), wv = twin(prevEdge(f));
  setCorners(b1, u, w, p);
  setCorners(b2, w, v, p);
  link(b1, uw);
  link(b1 + 1, b2 + 2);
  link(b1 + 2, pu);
  link(b2, wv);
  link(b2 + 1, vp);
  stack_.push_back(b1);
  stack_.push_back(b2);
}

void PlanarDelaunay::legalize() {
  while (!stack_.empty()) {
    const int e = stack_.back();
    stack_.pop_back();
    if (mustFlip(e)) flip(e);
  }
}

// (a, b, c) -> (a, b, p), (b, c, p), (c, a, p); c (or a, b) may be the infinite vertex.
void PlanarDelaunay::insertInFace(int p, int t) {
  const int base = 3 * t;
  const int a = corner(base), b = corner(base + 1), c = corner(base + 2);
  const int bc = twin(base + 1), ca = twin(base + 2);
  const int b1 = 3 * addTriangle(b, c, p), b2 = 3 * addTriangle(c, a, p);
  setCorners(base, a, b, p);
  link(base + 1, b1 + 2);
  link(base + 2, b2 + 1);
  link(b1, bc);
  link(b1 + 1, b2 + 2);
  link(b2, ca);
  stack_.insert(stack_.end(), {base, b1, b2});
  legalize();
}

// p on half-edge e = u -> v of (u, v, s), twin in (v, u, x):
// -> (v, s, p), (s, u, p), (u, x, p), (x, v, p).
void PlanarDelaunay::insertInEdge(int p, int e) {
  const int f = twin(e);
  const int bt = e - e % 3, bo = f - f % 3;
  const int u = corner(e), v = corner(nextEdge(e)), s = corner(prevEdge(e)), x = corner(prevEdge(f));
  const int vs = twin(nextEdge(e)), su = twin(prevEdge(e)), ux = twin(nextEdge(f)), xv = twin(prevEdge(f));
  const int b1 = 3 * addTriangle(s, u, p), b2 = 3 * addTriangle(x, v, p);
  setCorners(bt, v, s, p);
  setCorners(bo, u, x, p);
  link(bt, vs);
  link(bt + 1, b1 + 2);
  link(bt + 2, b2 + 1);
  link(b1, su);
  link(b1 + 1, bo + 2);
  link(bo, ux);
  link(bo + 1, b2 + 2);
  link(b2, xv);
  stack_.insert(stack_.end(), {bt, b1, bo, b2});
  legalize();
}

// Visibility walk from triangle t to the triangle holding p. Returns that triangle
// (an infinite one when p is outside the hull), or -1 if p duplicates a vertex (then
// `duplicate`) or the walk did not end. `on_edge` is the half-edge p lies on, or -1.
int PlanarDelaunay::locate(int p, int t, int& on_edge, bool& duplicate) const {
  on_edge = -1;
  duplicate = false;
  // Start in a finite triangle: across the hull edge from an infinite one.
  for (int k = 0; k < 3; ++k) {
    if (corner(3 * t + k) == n_) {
      t = twin(3 * t + (k + 1) % 3) / 3;
      break;
    }
  }
  int came_through = -1;  // half-edge of t the walk entered by (p lies left of it)
  const std::size_t limit = tv_.size() / 3 + 2;
  for (std::size_t step = 0; step < limit; ++step) {
    const int base = 3 * t;
    if (corner(base) == n_ || corner(base + 1) == n_ || corner(base + 2) == n_) return t;  // entered across the hull
    int zero = -1, zeros = 0;
    bool moved = false;
    for (int k = 0; k < 3; ++k) {
      const int e = base + k;
      if (e == came_through) continue;
      const int o = orient(corner(e), corner(nextEdge(e)), p);
      if (o < 0) {
        came_through = twin(e);
        t = came_through / 3;
        moved = true;
        break;
      }
      if (o == 0) {
        zero = e;
        ++zeros;
      }
    }
    if (moved) continue;
    if (zeros >= 2) {
      duplicate = true;
      return -1;
    }
    on_edge = zero;
    return t;
  }
  return -1;
}

bool PlanarDelaunay::build(const double* x, const double* y, int n) {
  n_ = n;
  tv_.clear();
  th_.clear();
  stack_.clear();
  xy_.resize(2 * static_cast<std::size_t>(std::max(n, 0)));
  order_.clear();
  double x0 = 0, x1 = 0, y0 = 0, y1 = 0;
  for (int i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    xy_[2 * k] = x[i];
    xy_[2 * k + 1] = y[i];
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) continue;  // never inserted
    if (order_.empty()) {
      x0 = x1 = x[i];
      y0 = y1 = y[i];
    }
    x0 = std::min(x0, x[i]);
    x1 = std::max(x1, x[i]);
    y0 = std::min(y0, y[i]);
    y1 = std::max(y1, y[i]);
    order_.push_back(i);
  }
  const int m = static_cast<int>(order_.size());
  if (m < 3) return true;
  tv_.reserve(static_cast<std::size_t>(6 * m + 12));
  th_.reserve(static_cast<std::size_t>(6 * m + 12));

  // Insertion order: rounds of growing density, sparsest first, the caller's order within
  // a round (a biased randomised insertion order, after Amenta, Choi and Rote 2003). A
  // point joins round k < kRounds - 1 with probability 3/4^(k+1) (from a hash of its
  // position in the input, so the result is reproducible). Against the caller's order
  // alone (image rows) this halves the flips (2.9 per point instead of 5.5): a point
  // inserted in rows mostly lands outside the hull and meets long thin triangles.
  constexpr int kRounds = 5;
  level_.resize(static_cast<std::size_t>(m));
  int count[kRounds] = {0};
  for (int j = 0; j < m; ++j) {
    std::uint32_t h = static_cast<std::uint32_t>(j) * 2654435761u;
    h ^= h >> 15;
    h *= 2246822519u;
    h ^= h >> 13;
    int level = 0;
    while (level < kRounds - 1 && (h & (3u << (2 * level))) == 0) ++level;
    level_[static_cast<std::size_t>(j)] = static_cast<std::uint8_t>(level);
    ++count[level];
  }
  int start[kRounds];
  for (int level = kRounds - 1, at = 0; level >= 0; --level) {
    start[level] = at;
    at += count[level];
  }
  sorted_.resize(static_cast<std::size_t>(m));
  for (int j = 0; j < m; ++j) {
    sorted_[static_cast<std::size_t>(start[level_[static_cast<std::size_t>(j)]]++)] = order_[static_cast<std::size_t>(j)];
  }
  const std::vector<int>& order = sorted_;

  // A coarse grid (about 8 points per cell) remembers a triangle near the point last
  // inserted in each cell; the walk to the next point in that cell starts there. The
  // cell is at least 1/m of the larger extent, so a thin strip of points gets at most
  // about 3m cells.
  // (Extents beyond the double range, from coordinates near it, give one cell.)
  const double wanted = std::max(1.0, m / 8.0), w = x1 - x0, h = y1 - y0;
  const double cell = std::max({std::sqrt(w * h / wanted), std::max(w, h) / m, 1e-12});
  const auto cellIndex = [&](double offset, std::size_t cells) -> std::size_t {
    const double q = offset / cell;  // NaN when the extent overflowed
    return q >= 0 && q < static_cast<double>(cells) ? static_cast<std::size_t>(q) : q >= 0 ? cells - 1 : 0;
  };
  const std::size_t limit = static_cast<std::size_t>(m) + 1;
  const std::size_t gw = cellIndex(w, limit) + 1, gh = cellIndex(h, limit) + 1;
  grid_.assign(gw * gh, -1);
  const auto cellOf = [&](int p) { return cellIndex(y[p] - y0, gh) * gw + cellIndex(x[p] - x0, gw); };

  // The first triangle: the first point, the first point apart from it, the first point
  // off their line. Points passed over on the way are inserted later.
  const int p0 = order[0];
  int j1 = 1;
  while (j1 < m && x[order[static_cast<std::size_t>(j1)]] == x[p0] && y[order[static_cast<std::size_t>(j1)]] == y[p0]) ++j1;
  int j2 = j1 + 1, turn = 0;
  while (j2 < m && (turn = orient(p0, order[static_cast<std::size_t>(j1)], order[static_cast<std::size_t>(j2)])) == 0) ++j2;
  if (j2 >= m) return true;  // all on one line: no triangle
  const int q1 = order[static_cast<std::size_t>(j1)], q2 = order[static_cast<std::size_t>(j2)];
  const int a = p0, b = turn > 0 ? q1 : q2, c = turn > 0 ? q2 : q1;
  addTriangle(a, b, c);  // half-edges 0-2
  addTriangle(b, a, n);  // 3-5: outside a -> b
  addTriangle(c, b, n);  // 6-8: outside b -> c
  addTriangle(a, c, n);  // 9-11: outside c -> a
  link(0, 3);
  link(1, 6);
  link(2, 9);
  link(4, 11);
  link(7, 5);
  link(10, 8);

  int last = 0;
  for (int j = 1; j < m; ++j) {
    if (j == j1 || j == j2) continue;
    const int p = order[static_cast<std::size_t>(j)];
    int& near = grid_[cellOf(p)];
    int edge = -1;
    bool duplicate = false;
    const int t = locate(p, near >= 0 ? near : last, edge, duplicate);
    if (duplicate) continue;
    if (t < 0) return false;
    if (edge >= 0) {
      insertInEdge(p, edge);
      last = edge / 3;
    } else {
      insertInFace(p, t);
      last = t;
    }
    near = last;
  }
  return true;
}

}  // namespace mobmap::perception::detail
