// Paper step 3: PCA normals (eqs. 2-4), with the inverse-iteration fast path and its vector kernels.

#include "mobmap/perception/normals.hpp"

#include "kernels/kernels.hpp"
#include "kernels/local_plane.hpp"
#include "kernels/simd.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace mobmap::perception {

namespace detail {

void smallestEigenvectorExact(const LocalMoments& c, double normal[3], float& curvature) {
  Eigen::Matrix3d cov;
  cov << c.xx, c.xy, c.xz, c.xy, c.yy, c.yz, c.xz, c.yz, c.zz;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(cov);
  for (int r = 0; r < 3; ++r) normal[r] = es.eigenvectors()(r, 0);
  const double total = es.eigenvalues().sum();
  curvature = total > 0 ? static_cast<float>(std::max(0.0, es.eigenvalues()(0)) / total) : 0.f;
}

}  // namespace detail

namespace {

// The offset sums of point i over its first c graph neighbours.
detail::OffsetSums rowOffsets(const std::vector<Eigen::Vector3f>& points, const KnnGraph& g, std::size_t i, int c) {
  return detail::sumOffsets(points.data(), i, &g.indices[i * static_cast<std::size_t>(g.k)], c);
}

}  // namespace

void estimateNormals(const std::vector<Eigen::Vector3f>& points, const KnnGraph& g, const Eigen::Vector3f& viewpoint,
                     std::vector<Eigen::Vector3f>& normals, std::vector<float>& curvature,
                     std::vector<Eigen::Vector3f>* projected, const std::vector<Eigen::Vector3f>* near) {
  const std::size_t n = points.size();
  if (near && near->size() != n) throw std::invalid_argument("estimateNormals: `near` size differs from points");
  if (g.count.size() != n) throw std::invalid_argument("estimateNormals: graph and points sizes differ");
  const Simd simd = activeSimd();
  normals.assign(n, Eigen::Vector3f::Zero());
  curvature.assign(n, 1.f);
  if (projected) *projected = points;
#if MOBMAP_X86_KERNELS
  if (simd == Simd::kAvx512 || simd == Simd::kAvx2) {
    // Eight points at a time; the lanes the kernel leaves (the closed-form solver) are
    // finished here with the same arithmetic as the portable loop below.
    static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float), "points are read as x, y, z triples");
    // (Cast, not ->data(): an empty vector's data() may be null.)
    const auto* xyz = reinterpret_cast<const float*>(points.data());
    const auto* start = near ? reinterpret_cast<const float*>(near->data()) : nullptr;
    auto* proj = projected ? reinterpret_cast<float*>(projected->data()) : nullptr;
    auto* normal_xyz = reinterpret_cast<float*>(normals.data());
    const auto k = static_cast<std::size_t>(g.k);
    // Sixteen at a time with AVX-512 (two groups of eight whose eigenvector iterations
    // overlap), eight with AVX2.
    double moments[2 * 9 * 8] = {};
    float sums[2 * 9 * 8] = {};
    const std::size_t group = simd == Simd::kAvx512 ? 16 : 8;
    for (std::size_t first = 0; first < n; first += group) {
      const int lanes = static_cast<int>(std::min(group, n - first));
      unsigned done = 0;
      if (simd == Simd::kAvx512) {
        detail::avx512::offsetSums8(xyz, n, g.indices.data(), k, g.count.data(), first, std::min(lanes, 8), sums);
        if (lanes > 8) {
          detail::avx512::offsetSums8(xyz, n, g.indices.data(), k, g.count.data(), first + 8, lanes - 8, sums + 72);
        }
        done = detail::avx512::localPlanes16(xyz, sums, g.count.data(), first, lanes, start, viewpoint.data(),
                                             normal_xyz, curvature.data(), proj, moments);
      } else {
        detail::avx2::offsetSums8(xyz, n, g.indices.data(), k, g.count.data(), first, lanes, sums);
        done = detail::avx2::localPlanes8(xyz, sums, g.count.data(), first, lanes, start, viewpoint.data(),
                                          normal_xyz, curvature.data(), proj, moments);
      }
      for (int l = 0; l < lanes; ++l) {
        if (done >> l & 1u) continue;
        const std::size_t i = first + static_cast<std::size_t>(l);
        detail::LocalMoments m;
        double* fields[9] = {&m.mx, &m.my, &m.mz, &m.xx, &m.xy, &m.xz, &m.yy, &m.yz, &m.zz};
        for (int q = 0; q < 9; ++q) *fields[q] = moments[72 * (l / 8) + 8 * q + l % 8];
        double normal[3];
        detail::smallestEigenvectorExact(m, normal, curvature[i]);
        normals[i] = detail::orientedNormal(normal, points[i], viewpoint);
        if (projected) (*projected)[i] = detail::projectedPoint(normal, m, points[i]);
      }
    }
    return;
  }
#endif
  for (std::size_t i = 0; i < n; ++i) {
    const int c = g.count[i];
    if (c < 2) continue;  // with the point itself, 3 points make a plane
    const detail::LocalMoments m = detail::momentsOf(rowOffsets(points, g, i, c), c);
    double normal[3];
    bool done = false;
    if (near) {
      const double start[3] = {(*near)[i].x(), (*near)[i].y(), (*near)[i].z()};
      done = detail::smallestEigenvectorNear(m, start, normal, curvature[i]);
    }
    if (!done) detail::smallestEigenvectorExact(m, normal, curvature[i]);
    normals[i] = detail::orientedNormal(normal, points[i], viewpoint);
    if (projected) (*projected)[i] = detail::projectedPoint(normal, m, points[i]);
  }
}

void projectOntoLocalPlanes(const std::vector<Eigen::Vector3f>& points, const KnnGraph& g, int max_neighbours,
                            const std::vector<int>& which, std::vector<Eigen::Vector3f>& projected) {
  if (projected.size() != points.size() || g.count.size() != points.size()) {
    throw std::invalid_argument("projectOntoLocalPlanes: graph, points and output sizes differ");
  }
  for (int idx : which) {
    const auto i = static_cast<std::size_t>(idx);
    const int c = std::min(g.count[i], max_neighbours);
    if (c < 2) continue;
    const detail::LocalMoments m = detail::momentsOf(rowOffsets(points, g, i, c), c);
    double normal[3];
    float unused = 0.f;
    detail::smallestEigenvectorExact(m, normal, unused);
    projected[i] = detail::projectedPoint(normal, m, points[i]);
  }
}

}  // namespace mobmap::perception
