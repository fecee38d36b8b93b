#pragma once
// Small helpers the stages share (internal): walking a kNN graph's rows and summing
// outer products in a fixed order.

#include "mobmap/perception/neighbours.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <vector>

namespace mobmap::perception {

// Calls f(neighbour index) for the graph neighbours of point i closer than
// sqrt(max_d2). Rows are sorted by distance (neighbours.hpp), so the scan stops at the
// first one beyond.
template <typename F>
inline void forNeighboursWithin(const KnnGraph& g, std::size_t i, float max_d2, F&& f) {
  const std::size_t base = i * static_cast<std::size_t>(g.k);
  for (int j = 0; j < g.count[i]; ++j) {
    const std::size_t e = base + static_cast<std::size_t>(j);
    if (g.sq_dist[e] > max_d2) break;
    f(static_cast<std::size_t>(g.indices[e]));
  }
}

// Asks for the graph row of points[pos], if the list reaches that far, ahead of the
// scan that will read it: breadth-first searches and orphan lists jump between rows in
// ways the hardware prefetcher cannot predict.
inline void prefetchRow(const KnnGraph& g, const std::vector<int>& points, std::size_t pos) {
  if (pos >= points.size()) return;
  const std::size_t base = static_cast<std::size_t>(points[pos]) * static_cast<std::size_t>(g.k);
  __builtin_prefetch(g.sq_dist.data() + base);
  __builtin_prefetch(g.indices.data() + base);
}

// Sum of the outer products d * d^T of a sequence of vectors: its six distinct entries,
// each summed in the order of the sequence, so the matrix is the one summing the full
// products gives, to the bit, for 2/3 of the work.
struct OuterSum {
  double xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0;
  void add(const Eigen::Vector3d& d) {
    xx += d.x() * d.x();
    xy += d.x() * d.y();
    xz += d.x() * d.z();
    yy += d.y() * d.y();
    yz += d.y() * d.z();
    zz += d.z() * d.z();
  }
  [[nodiscard]] Eigen::Matrix3d matrix() const {
    Eigen::Matrix3d m;
    m << xx, xy, xz, xy, yy, yz, xz, yz, zz;
    return m;
  }
};

}  // namespace mobmap::perception
