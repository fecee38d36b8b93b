// Paper step 2: statistical outlier removal (eq. 1).

#include "mobmap/perception/denoising.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace mobmap::perception {

std::vector<bool> statisticalOutlierMask(const KnnGraph& g, double alpha, int k) {
  if (k <= 0) k = g.k;
  if (k > g.k) throw std::invalid_argument("statisticalOutlierMask: k exceeds the graph's k");
  const std::size_t n = g.count.size();
  std::vector<double> mean_d(n, 0.0);
  std::vector<bool> keep(n, false);
  // Each point's sum runs over its row in order, a chain of dependent additions: four
  // points' chains at a time keep the adder busy, and their square roots are taken
  // four at a time (the same sums, to the bit: a vector square root rounds as the
  // scalar one). Rows with fewer than k neighbours (padded) are summed but not used.
  const auto stride = static_cast<std::size_t>(g.k);
  std::size_t i4 = 0;
  for (; i4 + 4 <= n; i4 += 4) {
    const float* r = &g.sq_dist[i4 * stride];
    double d[4] = {0.0, 0.0, 0.0, 0.0};
    std::size_t j = 0;
#if defined(__SSE2__)
    alignas(16) float root[4][4];
    for (; j + 4 <= static_cast<std::size_t>(k); j += 4) {
      for (std::size_t q = 0; q < 4; ++q) _mm_store_ps(root[q], _mm_sqrt_ps(_mm_loadu_ps(r + q * stride + j)));
      for (std::size_t c = 0; c < 4; ++c) {
        for (std::size_t q = 0; q < 4; ++q) d[q] += root[q][c];
      }
    }
#endif
    for (; j < static_cast<std::size_t>(k); ++j) {
      for (std::size_t q = 0; q < 4; ++q) d[q] += std::sqrt(r[q * stride + j]);
    }
    for (std::size_t q = 0; q < 4; ++q) mean_d[i4 + q] = d[q] / k;
  }
  for (; i4 < n; ++i4) {
    double d = 0.0;
    for (int j = 0; j < k; ++j) d += std::sqrt(g.sq_dist[i4 * stride + static_cast<std::size_t>(j)]);
    mean_d[i4] = d / k;
  }
  double sum = 0.0, sum2 = 0.0;
  std::size_t m = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (g.count[i] < k) continue;  // too isolated to have k neighbours: an outlier
    sum += mean_d[i];
    sum2 += mean_d[i] * mean_d[i];
    ++m;
  }
  if (m == 0) return keep;
  const double mu = sum / static_cast<double>(m);
  const double sigma = std::sqrt(std::max(0.0, sum2 / static_cast<double>(m) - mu * mu));
  for (std::size_t i = 0; i < n; ++i) {
    keep[i] = g.count[i] >= k && std::abs(mean_d[i] - mu) <= alpha * sigma + 1e-12;
  }
  return keep;
}

}  // namespace mobmap::perception
