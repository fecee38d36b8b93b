#include "mobmap/perception/neighbours.hpp"

#include "spatial_hash.hpp"

#include <algorithm>
#include <numeric>
#include <stdexcept>

namespace mobmap::perception {
namespace {

// Selects the k nearest of the candidates (distances d2, indices idx), sorted by
// (distance, index) so ties do not depend on the order candidates were visited.
class KSelect {
 public:
  explicit KSelect(int k) : k_(static_cast<std::size_t>(k)) {}
  void clear() {
    d2_.clear();
    idx_.clear();
  }
  void add(float d2, int index) {
    d2_.push_back(d2);
    idx_.push_back(index);
  }
  /// The selection; valid until the next clear().
  const std::vector<std::pair<float, int>>& select() {
    out_.clear();
    if (d2_.size() > k_) {
      scratch_.assign(d2_.begin(), d2_.end());
      std::nth_element(scratch_.begin(), scratch_.begin() + static_cast<std::ptrdiff_t>(k_ - 1), scratch_.end());
      const float thr = scratch_[k_ - 1];
      for (std::size_t j = 0; j < d2_.size(); ++j) {
        if (d2_[j] <= thr) out_.emplace_back(d2_[j], idx_[j]);
      }
    } else {
      for (std::size_t j = 0; j < d2_.size(); ++j) out_.emplace_back(d2_[j], idx_[j]);
    }
    std::sort(out_.begin(), out_.end());  // pair order: distance, then index
    if (out_.size() > k_) out_.resize(k_);
    return out_;
  }
  [[nodiscard]] std::size_t size() const { return d2_.size(); }

 private:
  std::size_t k_;
  std::vector<float> d2_, scratch_;
  std::vector<int> idx_;
  std::vector<std::pair<float, int>> out_;
};

void store(KnnGraph& g, int i, const std::vector<std::pair<float, int>>& cand) {
  const std::size_t base = static_cast<std::size_t>(i) * static_cast<std::size_t>(g.k);
  for (std::size_t j = 0; j < cand.size(); ++j) {
    g.sq_dist[base + j] = cand[j].first;
    g.indices[base + j] = cand[j].second;
  }
  g.count[static_cast<std::size_t>(i)] = static_cast<int>(cand.size());
}

void allocate(KnnGraph& g, std::size_t n, int k) {
  g.k = k;
  g.indices.assign(n * static_cast<std::size_t>(k), -1);
  g.sq_dist.assign(n * static_cast<std::size_t>(k), 0.f);
  g.count.assign(n, 0);
}

}  // namespace

KnnGraph buildKnnGraph(const std::vector<Eigen::Vector3f>& points, int k, float cell_m, float max_radius_m) {
  if (k < 1) throw std::invalid_argument("buildKnnGraph: k must be >= 1, got " + std::to_string(k));
  if (!(cell_m > 0.f) || !(max_radius_m > 0.f)) {
    throw std::invalid_argument("buildKnnGraph: cell_m and max_radius_m must be > 0");
  }
  KnnGraph g;
  allocate(g, points.size(), k);
  if (points.empty()) return g;
  const detail::CellBuckets buckets(points, cell_m);
  const int max_ring = std::max(1, static_cast<int>(std::ceil(max_radius_m / cell_m)));
  std::vector<int> block;  // candidates of the 3x3x3 block of the current cell
  std::vector<Eigen::Vector3f> block_points;
  KSelect sel(k);
  const float max_r2 = max_radius_m * max_radius_m;
  auto gather = [&](const Eigen::Vector3i& cc, int ring, std::vector<int>& out) {
    out.clear();
    for (int dx = -ring; dx <= ring; ++dx) {
      for (int dy = -ring; dy <= ring; ++dy) {
        for (int dz = -ring; dz <= ring; ++dz) {
          const int nb = buckets.find(cc.x() + dx, cc.y() + dy, cc.z() + dz);
          if (nb < 0) continue;
          out.insert(out.end(), buckets.order.begin() + buckets.start[static_cast<std::size_t>(nb)],
                     buckets.order.begin() + buckets.start[static_cast<std::size_t>(nb) + 1]);
        }
      }
    }
  };
  std::vector<int> wide;
  for (std::size_t c = 0; c < buckets.cells.size(); ++c) {
    const Eigen::Vector3i cc = buckets.cells[c];
    gather(cc, 1, block);
    block_points.resize(block.size());
    for (std::size_t j = 0; j < block.size(); ++j) block_points[j] = points[static_cast<std::size_t>(block[j])];
    for (int s = buckets.start[c]; s < buckets.start[c + 1]; ++s) {
      const int i = buckets.order[static_cast<std::size_t>(s)];
      const Eigen::Vector3f p = points[static_cast<std::size_t>(i)];
      sel.clear();
      for (std::size_t j = 0; j < block.size(); ++j) {
        if (block[j] != i) sel.add((block_points[j] - p).squaredNorm(), block[j]);
      }
      const auto* chosen = &sel.select();
      // Exact when there are k and the k-th lies within the guaranteed radius
      // ring * cell_m; otherwise widen the block one ring at a time.
      int ring = 1;
      while ((static_cast<int>(chosen->size()) < k || chosen->back().first > (ring * cell_m) * (ring * cell_m)) &&
             ring < max_ring) {
        ++ring;
        gather(cc, ring, wide);
        sel.clear();
        for (int j : wide) {
          if (j != i) sel.add((points[static_cast<std::size_t>(j)] - p).squaredNorm(), j);
        }
        chosen = &sel.select();
      }
      // Beyond max_radius nothing counts as a neighbour.
      std::size_t keep = chosen->size();
      while (keep > 0 && (*chosen)[keep - 1].first > max_r2) --keep;
      store(g, i, std::vector<std::pair<float, int>>(chosen->begin(), chosen->begin() + static_cast<std::ptrdiff_t>(keep)));
    }
  }
  return g;
}

KnnGraph bruteForceKnnGraph(const std::vector<Eigen::Vector3f>& points, int k) {
  KnnGraph g;
  allocate(g, points.size(), k);
  KSelect sel(k);
  for (std::size_t i = 0; i < points.size(); ++i) {
    sel.clear();
    for (std::size_t j = 0; j < points.size(); ++j) {
      if (j != i) sel.add((points[j] - points[i]).squaredNorm(), static_cast<int>(j));
    }
    store(g, static_cast<int>(i), sel.select());
  }
  return g;
}

}  // namespace mobmap::perception
