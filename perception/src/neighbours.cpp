#include "mobmap/perception/neighbours.hpp"

#include "kernels/kernels.hpp"
#include "kernels/spatial_hash.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

namespace mobmap::perception {
namespace {

// A candidate as one 64-bit key: the squared distance's bit pattern (monotone for
// non-negative floats) above the point index. Sorting keys orders by (distance,
// index), so ties never depend on the order in which candidates were visited.
std::uint64_t packKey(float d2, int index) {
  std::uint32_t bits = 0;
  std::memcpy(&bits, &d2, sizeof bits);
  return (static_cast<std::uint64_t>(bits) << 32) | static_cast<std::uint32_t>(index);
}
float keyDistance(std::uint64_t key) {
  const auto bits = static_cast<std::uint32_t>(key >> 32);
  float d2 = 0.f;
  std::memcpy(&d2, &bits, sizeof d2);
  return d2;
}
int keyIndex(std::uint64_t key) { return static_cast<int>(static_cast<std::uint32_t>(key)); }

// The one definition of squared distance used by every search here, so the grid
// search and the brute-force reference agree to the last bit.
inline float sqDist(float ax, float ay, float az, float bx, float by, float bz) {
  const float dx = ax - bx, dy = ay - by, dz = az - bz;
  return dx * dx + dy * dy + dz * dz;
}
inline float sqDist(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  return sqDist(a.x(), a.y(), a.z(), b.x(), b.y(), b.z());
}

// Keeps the k smallest keys, sorted. Candidate lists are short (tens of keys), where
// a bounded insertion sort beats nth_element followed by sort.
// Returns the new count; keys[0 .. count) holds the result.
std::size_t selectSmallest(std::uint64_t* keys, std::size_t size, std::size_t k) {
  if (size > 4 * k + 64) {  // long lists (sparse regions, brute force)
    std::nth_element(keys, keys + (k - 1), keys + size);
    std::sort(keys, keys + k);
    return k;
  }
  std::size_t n = 0;
  for (std::size_t j = 0; j < size; ++j) {
    const std::uint64_t key = keys[j];
    if (n == k && key >= keys[k - 1]) continue;
    std::size_t pos = n < k ? n++ : k - 1;  // the slot freed at the end
    while (pos > 0 && keys[pos - 1] > key) {
      keys[pos] = keys[pos - 1];
      --pos;
    }
    keys[pos] = key;
  }
  return n;
}

// The same result as selectSmallest for keys whose distances all lie in [0, limit2]:
// a counting sort into equal bands of squared distance (equal areas of a surface,
// so a few keys each), then insertion sorts of only the bands up to the k-th key.
// Candidates arrive in block order, unrelated to distance, so the plain insertion
// sort shifts half its list per key; here each key moves within its band only
// (denoising 41.5 -> 35 ms on the real frames, docs/PERFORMANCE.md).
std::size_t selectSmallestBanded(std::uint64_t* keys, std::size_t size, std::size_t k, float limit2,
                                 std::vector<std::uint64_t>& scratch, std::vector<std::uint8_t>& band_of) {
  constexpr int kBands = 16;
  if (!(limit2 > 0.f) || size > 4 * k + 64) return selectSmallest(keys, size, k);
  const float scale = static_cast<float>(kBands) / limit2;
  std::array<std::uint32_t, kBands + 1> start{};
  if (band_of.size() < size) band_of.resize(size);
  if (scratch.size() < size) scratch.resize(size);
  for (std::size_t j = 0; j < size; ++j) {
    const int b = std::min(kBands - 1, static_cast<int>(keyDistance(keys[j]) * scale));
    band_of[j] = static_cast<std::uint8_t>(b);
    ++start[static_cast<std::size_t>(b) + 1];
  }
  for (int b = 0; b < kBands; ++b) start[b + 1] += start[b];
  std::array<std::uint32_t, kBands> fill{};
  std::copy(start.begin(), start.end() - 1, fill.begin());
  for (std::size_t j = 0; j < size; ++j) scratch[fill[band_of[j]]++] = keys[j];
  const std::size_t n = std::min(size, k);
  for (int b = 0; b < kBands && start[b] < n; ++b) {
    for (std::uint32_t j = start[b] + 1; j < start[b + 1]; ++j) {
      const std::uint64_t key = scratch[j];
      std::uint32_t pos = j;
      while (pos > start[b] && scratch[pos - 1] > key) {
        scratch[pos] = scratch[pos - 1];
        --pos;
      }
      scratch[pos] = key;
    }
  }
  std::copy(scratch.begin(), scratch.begin() + static_cast<std::ptrdiff_t>(n), keys);
  return n;
}

// Sizes g for n rows of k without clearing the rows: a graph reused frame after frame
// keeps its buffers, and writing 20-40 MB of padding that the search overwrites cost
// ~1.2 ms per real frame. Every row's count starts at 0; padTails completes the rows.
void allocate(KnnGraph& g, std::size_t n, int k) {
  g.k = k;
  g.indices.resize(n * static_cast<std::size_t>(k));
  g.sq_dist.resize(n * static_cast<std::size_t>(k));
  g.count.assign(n, 0);
}

// Entries past a row's count read index -1 and distance 0 (rows are short rarely).
void padTails(KnnGraph& g) {
  const auto k = static_cast<std::size_t>(g.k);
  for (std::size_t i = 0; i < g.count.size(); ++i) {
    const auto c = static_cast<std::size_t>(g.count[i]);
    if (c == k) continue;
    std::fill(g.indices.data() + i * k + c, g.indices.data() + (i + 1) * k, -1);
    std::fill(g.sq_dist.data() + i * k + c, g.sq_dist.data() + (i + 1) * k, 0.f);
  }
}

void storeKeys(KnnGraph& g, std::size_t row, const std::uint64_t* keys, std::size_t count) {
  const std::size_t base = row * static_cast<std::size_t>(g.k);
  for (std::size_t j = 0; j < count; ++j) {
    g.sq_dist[base + j] = keyDistance(keys[j]);
    g.indices[base + j] = keyIndex(keys[j]);
  }
  g.count[row] = static_cast<int>(count);
}

void checkArguments(int k, float cell_m, float max_radius_m) {
  if (k < 1) throw std::invalid_argument("buildKnnGraph: k must be >= 1, got " + std::to_string(k));
  if (!(cell_m > 0.f) || !(max_radius_m > 0.f)) {
    throw std::invalid_argument("buildKnnGraph: cell_m and max_radius_m must be > 0");
  }
}

// Plain loops with SortedCellSearch's kernel interface, for any CPU (the compiler
// vectorises the distance pass with what the target has). They have no ranking: the
// k nearest are always selected by bands (selectSmallestBanded).
struct PortableKernels {
  static constexpr Simd kSimd = Simd::kPortable;
  static constexpr bool kRanks = false;
  static void distancesAndCounts(const float* x, const float* y, const float* z, std::size_t n, float px, float py,
                                 float pz, const float limit[4], float* d2, int count[4]) {
    int c0 = 0, c1 = 0, c2 = 0, c3 = 0;
    const float l0 = limit[0], l1 = limit[1], l2 = limit[2], l3 = limit[3];
    for (std::size_t j = 0; j < n; ++j) {
      const float d = sqDist(x[j], y[j], z[j], px, py, pz);
      d2[j] = d;
      c0 += d <= l0, c1 += d <= l1, c2 += d <= l2, c3 += d <= l3;  // NaN padding: never
    }
    count[0] = c0, count[1] = c1, count[2] = c2, count[3] = c3;
  }
  static std::size_t compactKeys(const float* d2, const int* index, std::size_t n, int self, float limit,
                                 std::uint64_t* keys) {
    std::size_t out = 0;
    for (std::size_t j = 0; j < n; ++j) {
      keys[out] = packKey(d2[j], index[j]);
      out += static_cast<std::size_t>((d2[j] <= limit) & (index[j] != self));
    }
    return out;
  }
};

#if MOBMAP_X86_KERNELS
// The vector kernels SortedCellSearch runs on (kernels/kernels.hpp).
struct Avx512Kernels {
  static constexpr Simd kSimd = Simd::kAvx512;
  static constexpr bool kRanks = true;
  static constexpr auto distancesAndCounts = &detail::avx512::distancesAndCounts;
  static constexpr auto compactKeys = &detail::avx512::compactKeys;
  static constexpr auto rankSmallest = &detail::avx512::rankSmallest;
};
struct Avx2Kernels {
  static constexpr Simd kSimd = Simd::kAvx2;
  static constexpr bool kRanks = true;
  static constexpr auto distancesAndCounts = &detail::avx2::distancesAndCounts;
  static constexpr auto compactKeys = &detail::avx2::compactKeys;
  static constexpr auto rankSmallest = &detail::avx2::rankSmallest;
};
#endif

// Exact kNN queries against a bucketed cloud, answered cell by cell so that the 3x3x3
// block of candidates is gathered once per cell, not once per point. The points are
// sorted by cell into arrays of coordinates, so a cell's block is a few contiguous
// copies; the distance, limit and selection loops are the `Kernels` (portable, AVX2
// or AVX-512). Same graph, bit for bit, with each: the distances are the same
// operations in the same order, and keys order by (distance, index) whatever the
// order candidates are found in.
template <typename Kernels>
class SortedCellSearch {
 public:
  SortedCellSearch(const std::vector<Eigen::Vector3f>& points, int k, float cell_m, float max_radius_m)
      : k_(static_cast<std::size_t>(k)),
        cell_(cell_m),
        max_r2_(max_radius_m * max_radius_m),
        inv_cell_(1.f / cell_m),
        max_ring_(std::max(1, static_cast<int>(std::ceil(max_radius_m / cell_m)))) {
    // Own copies of the buckets' arrays (moved out), not references into them: the hot
    // loops read them, and plain members keep them as cheap to reach as before.
    detail::CellBuckets buckets(points, cell_m, Kernels::kSimd);
    index_ = std::move(buckets.index);
    cells_ = std::move(buckets.cells);
    start_ = std::move(buckets.start);
    id_ = std::move(buckets.order);
    x_.resize(points.size()), y_.resize(points.size()), z_.resize(points.size());
    for (std::size_t s = 0; s < points.size(); ++s) {
      const Eigen::Vector3f& p = points[static_cast<std::size_t>(id_[s])];
      x_[s] = p.x(), y_[s] = p.y(), z_[s] = p.z();
    }
  }

  template <typename Want, typename RowOf>
  void run(KnnGraph& g, Want want, RowOf row_of) {
    for (std::size_t c = 0; c < cells_.size(); ++c) {
      bool any = false;
      for (int s = start_[c]; s < start_[c + 1] && !any; ++s) any = want(id_[static_cast<std::size_t>(s)]);
      if (!any) continue;
      gather(cells_[c], 1, block_);
      float last_kth2 = 0.f;  // k-th squared distance of the previous point in this cell
      short_.clear();
      for (int s = start_[c]; s < start_[c + 1]; ++s) {
        const int i = id_[static_cast<std::size_t>(s)];
        if (!want(i)) continue;
        // Any limit within the block's guarantee (every point closer than one cell plus
        // the point's distance to its own cell's faces is in it) gives the exact answer
        // once k candidates lie within it. Neighbouring points see the same density:
        // limits just above the previous point's k-th distance usually hold k
        // candidates, and fewer candidates make the selection cheaper. All four are
        // counted in the pass that computes the distances.
        const float margin = faceMargin(cells_[c], static_cast<std::size_t>(s));
        const float guarantee = std::min((cell_ + margin) * (cell_ + margin), max_r2_);
        const float limit[4] = {std::min(1.15f * last_kth2, guarantee), std::min(1.4f * last_kth2, guarantee),
                                std::min(1.8f * last_kth2, guarantee), guarantee};
        int count[4];
        distances(block_, s, limit, count);
        if (count[3] < static_cast<int>(k_) && guarantee < max_r2_) {
          short_.push_back(s);  // searched in wider rings below, with the cell's other short points
          continue;
        }
        const std::size_t n = select(block_, i, limit[tightestHolding(count)], g, static_cast<std::size_t>(row_of(i)));
        if (n == k_) last_kth2 = g.sq_dist[static_cast<std::size_t>(row_of(i)) * k_ + k_ - 1];
      }
      // Points without k neighbours within that: ring r of cells guarantees r cells
      // (plus the face margin) of radius; one block per ring serves all of this cell's
      // short points.
      for (int ring = 2; !short_.empty() && ring <= max_ring_; ++ring) {
        if (ring == 2) copyBlock(block_, wide_);
        gather(cells_[c], ring, wide_, /*shell_only=*/true);
        std::size_t still = 0;
        for (int s : short_) {
          const int i = id_[static_cast<std::size_t>(s)];
          const float margin = faceMargin(cells_[c], static_cast<std::size_t>(s));
          const float inner = static_cast<float>(ring - 1) * cell_ + margin;
          // The last ring reaches the maximum radius (max_ring_ cells cover it).
          const float outer = static_cast<float>(ring) * cell_ + margin;
          const float outer2 = ring == max_ring_ ? max_r2_ : std::min(outer * outer, max_r2_);
          float limit[4];
          for (int q = 0; q < 3; ++q) {
            const float r = inner + 0.25f * static_cast<float>(q + 1) * cell_;
            limit[q] = std::min(r * r, outer2);
          }
          limit[3] = outer2;
          int count[4];
          distances(wide_, s, limit, count);
          if (count[3] < static_cast<int>(k_) && ring < max_ring_ && outer2 < max_r2_) {
            short_[still++] = s;
            continue;
          }
          select(wide_, i, limit[tightestHolding(count)], g, static_cast<std::size_t>(row_of(i)));
        }
        short_.resize(still);
      }
    }
  }

 private:
  struct Block {
    std::vector<float> x, y, z, d2;
    std::vector<int> id;
    std::size_t points = 0;  // real points
    std::size_t n = 0;       // padded to a multiple of 16 with NaN points
  };

  // The points of the cells within `ring` of cc (Chebyshev distance); with shell_only,
  // appends those at exactly `ring` to a block that holds ring - 1.
  void gather(const Eigen::Vector3i& cc, int ring, Block& b, bool shell_only = false) const {
    if (!shell_only) b.points = 0;
    detail::forEachCellWithin(cc, ring, shell_only, [&](int x, int y, int z) { append(x, y, z, b); });
    pad(b);
  }
  void copyBlock(const Block& from, Block& to) const {
    if (to.x.size() < from.n + 16) grow(to, from.n + 16);
    std::copy_n(from.x.begin(), from.points, to.x.begin());
    std::copy_n(from.y.begin(), from.points, to.y.begin());
    std::copy_n(from.z.begin(), from.points, to.z.begin());
    std::copy_n(from.id.begin(), from.points, to.id.begin());
    to.points = from.points;
  }
  void append(int cx, int cy, int cz, Block& b) const {
    const int nb = index_.find(detail::cellKey(cx, cy, cz));
    if (nb < 0) return;
    const auto from = static_cast<std::size_t>(start_[static_cast<std::size_t>(nb)]);
    const auto to = static_cast<std::size_t>(start_[static_cast<std::size_t>(nb) + 1]);
    std::size_t n = b.points;
    if (b.x.size() < n + (to - from) + 16) grow(b, 2 * (n + (to - from) + 16));
    for (std::size_t s = from; s < to; ++s, ++n) {
      b.x[n] = x_[s], b.y[n] = y_[s], b.z[n] = z_[s];
      b.id[n] = id_[s];
    }
    b.points = n;
  }
  static void pad(Block& b) {
    std::size_t n = b.points;
    if (b.x.size() < n + 16) grow(b, n + 16);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (; n % 16 != 0; ++n) {
      b.x[n] = b.y[n] = b.z[n] = nan;
      b.id[n] = -1;
    }
    b.n = n;
  }
  static void grow(Block& b, std::size_t size) {
    size = std::max<std::size_t>(size, 1024);
    b.x.resize(size), b.y.resize(size), b.z.resize(size), b.d2.resize(size), b.id.resize(size);
  }

  // The distance from sorted point s to the nearest face of its cell cc, less a slack
  // for rounding: every point within r cells plus this of s lies within r cells of cc
  // (Chebyshev), so the block of that ring holds it. Measured in cell units with the
  // product CellBuckets floors (a point in cell cc + 2 has x * inv >= cc + 2), so the
  // bound holds for the cells as assigned; the slack covers the rounding of that
  // product (a few units in its last place) and of the squared distances. For a point
  // on a face the margin is slightly negative: a point just beyond the block, one cell
  // and a fraction of a float step away, can round to exactly one cell's distance
  // (taking the bare cell as the radius, the search missed it there).
  [[nodiscard]] float faceMargin(const Eigen::Vector3i& cc, std::size_t s) const {
    const float t[3] = {x_[s] * inv_cell_, y_[s] * inv_cell_, z_[s] * inv_cell_};
    float u = 0.5f, scale = 0.f;
    for (int a = 0; a < 3; ++a) {
      const auto lo = static_cast<float>(cc(a));
      u = std::min({u, t[a] - lo, lo + 1.f - t[a]});
      scale = std::max(scale, std::abs(t[a]));
    }
    const float slack = 1e-5f + 1e-6f * scale;
    return (u - slack) * cell_;
  }

  // The first of the four limits (ascending) within which k candidates lie; the last
  // when none holds k (it is the widest the block can answer).
  [[nodiscard]] int tightestHolding(const int count[4]) const {
    int q = 0;
    while (q < 3 && count[q] < static_cast<int>(k_)) ++q;
    return q;
  }

  // Distances from sorted point s to the block; count[q] excludes the point itself.
  void distances(Block& b, int s, const float limit[4], int count[4]) const {
    const auto p = static_cast<std::size_t>(s);
    Kernels::distancesAndCounts(b.x.data(), b.y.data(), b.z.data(), b.n, x_[p], y_[p], z_[p], limit, b.d2.data(),
                                count);
    for (int q = 0; q < 4; ++q) --count[q];  // the point itself, at distance 0
  }

  // The k nearest of the block's points within `limit` (other than `self`) into row `row`.
  std::size_t select(const Block& b, int self, float limit, KnnGraph& g, std::size_t row) {
    if (keys_.size() < b.n + detail::kRankMaxKeys) keys_.resize(b.n + detail::kRankMaxKeys);
    const std::size_t m = Kernels::compactKeys(b.d2.data(), b.id.data(), b.n, self, limit, keys_.data());
    const std::size_t base = row * k_;
    if constexpr (Kernels::kRanks) {
      if (m <= detail::kRankMaxKeys) {
        const std::size_t n = Kernels::rankSmallest(keys_.data(), m, k_, &g.sq_dist[base], &g.indices[base]);
        g.count[row] = static_cast<int>(n);
        return n;
      }
    }
    const std::size_t n = selectSmallestBanded(keys_.data(), m, k_, limit, scratch_, band_of_);
    storeKeys(g, row, keys_.data(), n);
    return n;
  }

  std::size_t k_;
  float cell_, max_r2_;
  float inv_cell_;  // 1 / cell_ as CellBuckets computes it
  int max_ring_;
  detail::CellHash index_{1};
  std::vector<Eigen::Vector3i> cells_;
  std::vector<int> start_;                 // cell c holds sorted points start_[c] .. start_[c+1]
  std::vector<int> id_;                    // the sorted points' indices in the input
  std::vector<float> x_, y_, z_;           // their coordinates
  Block block_, wide_;
  std::vector<int> short_;
  std::vector<std::uint64_t> keys_, scratch_;
  std::vector<std::uint8_t> band_of_;
};

// Runs `search.run(g, want, row_of)` with the search the chosen instruction set uses.
template <typename Want, typename RowOf>
void searchInto(KnnGraph& g, const std::vector<Eigen::Vector3f>& points, int k, float cell_m, float max_radius_m,
                Want want, RowOf row_of) {
  const Simd simd = activeSimd();
#if MOBMAP_X86_KERNELS
  if (simd == Simd::kAvx512) {
    SortedCellSearch<Avx512Kernels> search(points, k, cell_m, max_radius_m);
    search.run(g, want, row_of);
    return;
  }
  if (simd == Simd::kAvx2) {
    SortedCellSearch<Avx2Kernels> search(points, k, cell_m, max_radius_m);
    search.run(g, want, row_of);
    return;
  }
#endif
  (void)simd;
  SortedCellSearch<PortableKernels> search(points, k, cell_m, max_radius_m);
  search.run(g, want, row_of);
}

}  // namespace

KnnGraph buildKnnGraph(const std::vector<Eigen::Vector3f>& points, int k, float cell_m, float max_radius_m) {
  KnnGraph g;
  buildKnnGraph(points, k, cell_m, max_radius_m, g);
  return g;
}

void buildKnnGraph(const std::vector<Eigen::Vector3f>& points, int k, float cell_m, float max_radius_m, KnnGraph& g) {
  checkArguments(k, cell_m, max_radius_m);
  allocate(g, points.size(), k);
  if (!points.empty()) {
    searchInto(g, points, k, cell_m, max_radius_m, [](int) { return true; }, [](int i) { return i; });
  }
  padTails(g);
}

KnnGraph restrictKnnGraph(const KnnGraph& g, const std::vector<Eigen::Vector3f>& points, const std::vector<bool>& keep,
                          int k, float cell_m, float max_radius_m, std::size_t* recomputed) {
  KnnGraph out;
  restrictKnnGraph(g, points, keep, k, cell_m, max_radius_m, out, recomputed);
  return out;
}

namespace {

// The rows of the kept points, renumbered, from (src_*, src_k) into (dst_*, k): a kept
// point's row is the first k kept entries of its old row. dst may be src itself: row i
// goes to row new_index[i] <= i with k <= src_k, and entry j of a row to entry c <= j,
// so no entry is written before it has been read. Marks in `redo` the rows that must be
// searched again and returns their number.
std::size_t compactRows(const int* src_idx, const float* src_d2, const int* src_count, int src_k, int* dst_idx,
                        float* dst_d2, int* dst_count, int k, const std::vector<int>& new_index, float max_r2,
                        std::vector<bool>& redo) {
  std::size_t n_redo = 0;
  for (std::size_t i = 0; i < new_index.size(); ++i) {
    const int ni = new_index[i];
    if (ni < 0) continue;
    const std::size_t base = i * static_cast<std::size_t>(src_k);
    const std::size_t obase = static_cast<std::size_t>(ni) * static_cast<std::size_t>(k);
    const int old_count = src_count[i];
    int c = 0;
    for (int j = 0; j < old_count && c < k; ++j) {
      const int nb = new_index[static_cast<std::size_t>(src_idx[base + static_cast<std::size_t>(j)])];
      const float d2 = src_d2[base + static_cast<std::size_t>(j)];
      if (nb < 0 || d2 > max_r2) continue;
      dst_idx[obase + static_cast<std::size_t>(c)] = nb;
      dst_d2[obase + static_cast<std::size_t>(c)] = d2;
      ++c;
    }
    dst_count[static_cast<std::size_t>(ni)] = c;
    // The row is exact if it found k kept neighbours, or if the original row already
    // held every point within the radius (it was not full). Otherwise removed points
    // took places that farther kept points now fill: search again.
    if (c < k && old_count == src_k) {
      redo[static_cast<std::size_t>(ni)] = true;
      ++n_redo;
    }
  }
  return n_redo;
}

// Checks restrictKnnGraph's arguments; returns each point's index among the kept ones
// (-1 if removed) and their number.
std::vector<int> keptNumbering(const KnnGraph& g, const std::vector<Eigen::Vector3f>& points,
                               const std::vector<bool>& keep, int k, float cell_m, float max_radius_m, int& n_kept) {
  checkArguments(k, cell_m, max_radius_m);
  if (k > g.k) throw std::invalid_argument("restrictKnnGraph: k exceeds the graph's k");
  if (keep.size() != points.size() || g.count.size() != points.size()) {
    throw std::invalid_argument("restrictKnnGraph: graph, points and mask sizes differ");
  }
  std::vector<int> new_index(points.size(), -1);
  n_kept = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (keep[i]) new_index[i] = n_kept++;
  }
  return new_index;
}

// Searches the rows marked in `redo` again among the kept points, and pads the rows.
void researchRows(KnnGraph& out, const std::vector<Eigen::Vector3f>& points, const std::vector<bool>& keep,
                  int n_kept, const std::vector<bool>& redo, std::size_t n_redo, int k, float cell_m,
                  float max_radius_m) {
  if (n_redo > 0) {  // only then is the kept cloud needed as a cloud of its own
    std::vector<Eigen::Vector3f> kept;
    kept.reserve(static_cast<std::size_t>(n_kept));
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (keep[i]) kept.push_back(points[i]);
    }
    searchInto(out, kept, k, cell_m, max_radius_m,
               [&](int i) { return static_cast<bool>(redo[static_cast<std::size_t>(i)]); }, [](int i) { return i; });
  }
  padTails(out);
}

}  // namespace

void restrictKnnGraph(const KnnGraph& g, const std::vector<Eigen::Vector3f>& points, const std::vector<bool>& keep,
                      int k, float cell_m, float max_radius_m, KnnGraph& out, std::size_t* recomputed) {
  if (&out == &g) throw std::invalid_argument("restrictKnnGraph: the output graph is the input graph");
  int n_kept = 0;
  const std::vector<int> new_index = keptNumbering(g, points, keep, k, cell_m, max_radius_m, n_kept);
  allocate(out, static_cast<std::size_t>(n_kept), k);
  std::vector<bool> redo(static_cast<std::size_t>(n_kept), false);
  const std::size_t n_redo = compactRows(g.indices.data(), g.sq_dist.data(), g.count.data(), g.k, out.indices.data(),
                                         out.sq_dist.data(), out.count.data(), k, new_index,
                                         max_radius_m * max_radius_m, redo);
  if (recomputed) *recomputed = n_redo;
  researchRows(out, points, keep, n_kept, redo, n_redo, k, cell_m, max_radius_m);
}

void restrictKnnGraphInPlace(KnnGraph& g, const std::vector<Eigen::Vector3f>& points, const std::vector<bool>& keep,
                             int k, float cell_m, float max_radius_m, std::size_t* recomputed) {
  int n_kept = 0;
  const std::vector<int> new_index = keptNumbering(g, points, keep, k, cell_m, max_radius_m, n_kept);
  std::vector<bool> redo(static_cast<std::size_t>(n_kept), false);
  const std::size_t n_redo = compactRows(g.indices.data(), g.sq_dist.data(), g.count.data(), g.k, g.indices.data(),
                                         g.sq_dist.data(), g.count.data(), k, new_index,
                                         max_radius_m * max_radius_m, redo);
  // Shrinking keeps the buffers' capacity for the next frame.
  g.k = k;
  g.indices.resize(static_cast<std::size_t>(n_kept) * static_cast<std::size_t>(k));
  g.sq_dist.resize(static_cast<std::size_t>(n_kept) * static_cast<std::size_t>(k));
  g.count.resize(static_cast<std::size_t>(n_kept));
  if (recomputed) *recomputed = n_redo;
  researchRows(g, points, keep, n_kept, redo, n_redo, k, cell_m, max_radius_m);
}

KnnGraph bruteForceKnnGraph(const std::vector<Eigen::Vector3f>& points, int k) {
  KnnGraph g;
  allocate(g, points.size(), k);
  std::vector<std::uint64_t> keys;
  for (std::size_t i = 0; i < points.size(); ++i) {
    keys.clear();
    for (std::size_t j = 0; j < points.size(); ++j) {
      if (j != i) keys.push_back(packKey(sqDist(points[j], points[i]), static_cast<int>(j)));
    }
    const std::size_t count = selectSmallest(keys.data(), keys.size(), static_cast<std::size_t>(k));
    storeKeys(g, i, keys.data(), count);
  }
  padTails(g);
  return g;
}

}  // namespace mobmap::perception
