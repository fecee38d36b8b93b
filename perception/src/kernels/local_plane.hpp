#pragma once
// Local least-squares planes (internal): the PCA plane of a point and its first c
// graph neighbours (paper eqs. 2-4). Every sum is written out in a fixed order, so the
// vector kernels (kernels/avx512.cpp) can repeat the arithmetic to the last bit. The
// orders are those Eigen 3.4 evaluated for the expressions this code replaced (dot
// products and norms left to right, a trace right to left, a matrix-vector product
// left to right in its first two rows and right to left in its third; checked on two
// million random inputs), so the pipeline's results did not change either.

#include "kernels/kernels.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace mobmap::perception::detail {

/// Sums over the neighbours of their offsets d = q - p from the point, and of d d^T
/// (upper triangle), in single precision: offsets are a few centimetres, so the sums
/// lose nothing that matters (relative error ~1e-7 of entries ~1e-4 m^2).
struct OffsetSums {
  float sx = 0, sy = 0, sz = 0, xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0;
};

inline OffsetSums sumOffsets(const Eigen::Vector3f* points, std::size_t i, const int* nb, int c) {
  const Eigen::Vector3f p = points[i];
  OffsetSums s;
  for (int j = 0; j < c; ++j) {
    const Eigen::Vector3f d = points[static_cast<std::size_t>(nb[j])] - p;
    s.sx += d.x(), s.sy += d.y(), s.sz += d.z();
    s.xx += d.x() * d.x(), s.xy += d.x() * d.y(), s.xz += d.x() * d.z();
    s.yy += d.y() * d.y(), s.yz += d.y() * d.z(), s.zz += d.z() * d.z();
  }
  return s;
}

/// Mean (relative to the point) and covariance of the point and its c neighbours, in
/// double precision. The point itself contributes d = 0.
struct LocalMoments {
  double mx = 0, my = 0, mz = 0;
  double xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0;
};

inline LocalMoments momentsOf(const OffsetSums& s, int c) {
  // One division: multiplying by 1 / (c + 1) differs from dividing by c + 1 by at most
  // a unit in the last place, and divisions were the vector kernels' slowest
  // instructions.
  const double inv_m = 1.0 / (c + 1.0);
  LocalMoments o;
  o.mx = static_cast<double>(s.sx) * inv_m, o.my = static_cast<double>(s.sy) * inv_m;
  o.mz = static_cast<double>(s.sz) * inv_m;
  o.xx = static_cast<double>(s.xx) * inv_m - o.mx * o.mx;
  o.xy = static_cast<double>(s.xy) * inv_m - o.mx * o.my;
  o.xz = static_cast<double>(s.xz) * inv_m - o.mx * o.mz;
  o.yy = static_cast<double>(s.yy) * inv_m - o.my * o.my;
  o.yz = static_cast<double>(s.yz) * inv_m - o.my * o.mz;
  o.zz = static_cast<double>(s.zz) * inv_m - o.mz * o.mz;
  return o;
}

/// A symmetric 3x3 matrix as its upper triangle.
struct Symmetric3 {
  double b00, b11, b22, b01, b02, b12;
};

/// adj(C)^4, the matrix the eigenvector iteration multiplies by: adj(C), squared twice.
inline Symmetric3 iterationMatrix(const LocalMoments& c) {
  Symmetric3 b{c.yy * c.zz - c.yz * c.yz, c.xx * c.zz - c.xz * c.xz, c.xx * c.yy - c.xy * c.xy,
               c.xz * c.yz - c.xy * c.zz, c.xy * c.yz - c.xz * c.yy, c.xy * c.xz - c.xx * c.yz};
  for (int square = 0; square < 2; ++square) {
    const Symmetric3 j = b;
    b = {(j.b00 * j.b00 + j.b01 * j.b01) + j.b02 * j.b02, (j.b01 * j.b01 + j.b11 * j.b11) + j.b12 * j.b12,
         (j.b02 * j.b02 + j.b12 * j.b12) + j.b22 * j.b22, (j.b00 * j.b01 + j.b01 * j.b11) + j.b02 * j.b12,
         (j.b00 * j.b02 + j.b01 * j.b12) + j.b02 * j.b22, (j.b01 * j.b02 + j.b11 * j.b12) + j.b12 * j.b22};
  }
  return b;
}

/// Smallest eigenvector of the covariance from a nearby unit vector `start`:
/// x <- adj(C)^4 x until it stops moving (at most 8 steps). adj(C) has the eigenvalues
/// l1 l2, l0 l2, l0 l1 on the eigenvectors v0, v1, v2, so each step shrinks the other
/// components by (l0 / l1)^4 and (l0 / l2)^4, as four steps of adj(C) itself would, at
/// the price of two matrix squares (on the benchmark's real frames, AVX-512: 3.0 loop
/// steps per sixteen points instead of 5.3, and 0.4 % of the points left to the exact
/// solver instead of 8.4 %).
/// The entries stay far from underflow: offsets of a few centimetres give adj(C) ~1e-8
/// m^4 and adj(C)^4 ~1e-32. It is defined for singular matrices too (an exact plane:
/// one step lands on v0). False (use the exact solver) if `start` is not near
/// unit length, or the iteration does not converge, collapses (start orthogonal to v0,
/// rank <= 1) or finds no plane (smallest eigenvalue over a quarter of the sum).
inline bool smallestEigenvectorNear(const LocalMoments& c, const double start[3], double normal[3],
                                    float& curvature) {
  if ((start[0] * start[0] + start[1] * start[1]) + start[2] * start[2] < 0.25) return false;
  const Symmetric3 b = iterationMatrix(c);
  const double scale = std::max({std::abs(b.b00), std::abs(b.b11), std::abs(b.b22), std::abs(b.b01),
                                 std::abs(b.b02), std::abs(b.b12)});
  double x0 = start[0], x1 = start[1], x2 = start[2];
  for (int step = 0; step < 8; ++step) {
    const double y0 = (b.b00 * x0 + b.b01 * x1) + b.b02 * x2;
    const double y1 = (b.b01 * x0 + b.b11 * x1) + b.b12 * x2;
    const double y2 = b.b02 * x0 + (b.b12 * x1 + b.b22 * x2);
    const double norm = std::sqrt((y0 * y0 + y1 * y1) + y2 * y2);
    if (!(norm > 1e-30 * scale) || !std::isfinite(norm)) return false;
    const double inv = 1.0 / norm;
    const double n0 = y0 * inv, n1 = y1 * inv, n2 = y2 * inv;
    // Converged: a step that moves x by under 1e-5 rad leaves it within ~1e-4 rad of v0
    // unless (l0 / l1)^4 > 0.9, a neighbourhood with no plane, which goes to the exact
    // solver through the curvature test below.
    const double d0 = n0 - x0, d1 = n1 - x1, d2 = n2 - x2;
    const bool converged = (d0 * d0 + d1 * d1) + d2 * d2 <= kStepUnder1e5Squared;
    x0 = n0, x1 = n1, x2 = n2;
    if (converged) {
      const double total = c.xx + (c.yy + c.zz);
      const double cx0 = (c.xx * x0 + c.xy * x1) + c.xz * x2;
      const double cx1 = (c.xy * x0 + c.yy * x1) + c.yz * x2;
      const double cx2 = c.xz * x0 + (c.yz * x1 + c.zz * x2);
      const double lambda0 = std::max(0.0, (x0 * cx0 + x1 * cx1) + x2 * cx2);  // Rayleigh quotient
      if (!(total > 0) || lambda0 > 0.25 * total) return false;
      normal[0] = x0, normal[1] = x1, normal[2] = x2;
      curvature = static_cast<float>(lambda0 / total);
      return true;
    }
  }
  return false;
}

/// The closed-form eigen-decomposition (Eigen's computeDirect): smallest eigenvector,
/// and curvature = lambda_min / sum (0 when the sum is not positive). In normals.cpp.
void smallestEigenvectorExact(const LocalMoments& c, double normal[3], float& curvature);

/// The unit normal turned towards `viewpoint` (paper eq. 4), in single precision.
inline Eigen::Vector3f orientedNormal(const double normal[3], const Eigen::Vector3f& point,
                                      const Eigen::Vector3f& viewpoint) {
  const Eigen::Vector3f v = viewpoint - point;
  double n0 = normal[0], n1 = normal[1], n2 = normal[2];
  if ((n0 * static_cast<double>(v.x()) + n1 * static_cast<double>(v.y())) + n2 * static_cast<double>(v.z()) < 0) {
    n0 = -n0, n1 = -n1, n2 = -n2;
  }
  const double len = std::sqrt((n0 * n0 + n1 * n1) + n2 * n2);
  return {static_cast<float>(n0 / len), static_cast<float>(n1 / len), static_cast<float>(n2 / len)};
}

/// The point moved along the (unit) normal onto the plane through the neighbourhood
/// mean: one planar moving-least-squares step.
inline Eigen::Vector3f projectedPoint(const double normal[3], const LocalMoments& c, const Eigen::Vector3f& point) {
  const double t = (normal[0] * c.mx + normal[1] * c.my) + normal[2] * c.mz;
  return {static_cast<float>(static_cast<double>(point.x()) + normal[0] * t),
          static_cast<float>(static_cast<double>(point.y()) + normal[1] * t),
          static_cast<float>(static_cast<double>(point.z()) + normal[2] * t)};
}

}  // namespace mobmap::perception::detail
