#pragma once
// Open-addressing hash from packed integer cell coordinates to a value (internal).

#include "kernels/simd.hpp"
#include "kernels/kernels.hpp"

#include <Eigen/Core>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <vector>

namespace mobmap::perception::detail {

/// Packs a cell coordinate (21 bits per axis, offset so negatives fit) into 63 bits.
/// Valid for |coordinate / cell| < 2^20.
inline std::uint64_t cellKey(std::int64_t ix, std::int64_t iy, std::int64_t iz) {
  constexpr std::int64_t kOffset = 1 << 20;
  return (static_cast<std::uint64_t>(ix + kOffset) << 42) |
         (static_cast<std::uint64_t>(iy + kOffset) << 21) | static_cast<std::uint64_t>(iz + kOffset);
}

/// static_cast<int>(std::floor(x)) for |x| < 2^31, without the long inline sequence
/// std::floor becomes on baseline x86-64 (a VGA frame's voxel keys took 25-40 % longer
/// with it).
inline int floorToInt(float x) {
  const int t = static_cast<int>(x);  // towards zero; exact, as is the float of t
  return t - static_cast<int>(static_cast<float>(t) > x);
}

inline Eigen::Vector3i cellOf(const Eigen::Vector3f& p, float inv_cell) {
  return {floorToInt(p.x() * inv_cell), floorToInt(p.y() * inv_cell), floorToInt(p.z() * inv_cell)};
}

/// The packed cell keys of the points, in order: computed before a scan of lookups so
/// that CellHash::slotAhead can ask for a slot before it is needed. `simd` picks the
/// kernel (the same keys from each; a resolved choice, not kAuto).
inline std::vector<std::uint64_t> cellKeys(const std::vector<Eigen::Vector3f>& points, float inv_cell, Simd simd) {
  static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float), "points are read as x, y, z triples");
  std::vector<std::uint64_t> keys(points.size());
  std::size_t done = 0;
#if MOBMAP_X86_KERNELS
  // (Cast, not ->data(): an empty vector's data() may be null.)
  const auto* xyz = reinterpret_cast<const float*>(points.data());
  if (simd == Simd::kAvx512) done = avx512::cellKeys(xyz, points.size(), inv_cell, keys.data());
  if (simd == Simd::kAvx2) done = avx2::cellKeys(xyz, points.size(), inv_cell, keys.data());
#else
  (void)simd;
#endif
  for (std::size_t i = done; i < points.size(); ++i) {
    const Eigen::Vector3i c = cellOf(points[i], inv_cell);
    keys[i] = cellKey(c.x(), c.y(), c.z());
  }
  return keys;
}

/// key -> int32 value; capacity a power of two, linear probing. Each slot holds its key
/// and value side by side, so a lookup touches one cache line, and the number of the
/// fill it belongs to: a slot of an earlier fill counts as empty, so reset() empties
/// the table without writing it (a table kept from frame to frame is not cleared,
/// megabytes each time).
class CellHash {
 public:
  explicit CellHash(std::size_t expected) { reset(expected); }
  /// Empties the table, sized for `expected` keys (its capacity the same as a new
  /// table's: a table grown for a larger fill is allocated anew, not kept).
  void reset(std::size_t expected) {
    std::size_t cap = 16;
    while (cap < expected * 2) cap <<= 1;
    size_ = 0;
    if (cap != slots_.size() || fill_ == ~0u) {
      slots_.assign(cap, Slot{});
      fill_ = 1;
    } else {
      ++fill_;
    }
    mask_ = cap - 1;
  }
  /// Returns a reference to the value slot of `key`, inserting -1 if absent. The
  /// reference is valid until the next insertion (the table doubles at half load).
  int& slot(std::uint64_t key) {
    if (2 * (size_ + 1) > slots_.size()) grow();
    std::size_t i = hash(key) & mask_;
    while (slots_[i].fill == fill_ && slots_[i].key != key) i = (i + 1) & mask_;
    Slot& s = slots_[i];
    if (s.fill != fill_) {
      s = Slot{key, -1, fill_};
      ++size_;
    }
    return s.value;
  }
  /// slot(keys[i]) in a scan over `keys`, having first asked for the cache line of
  /// keys[i + kAhead]'s slot: the first lookup of every key misses the cache otherwise
  /// (the table is a few MB and keys land at random places in it).
  int& slotAhead(const std::vector<std::uint64_t>& keys, std::size_t i) {
    if (i + kAhead < keys.size()) __builtin_prefetch(slots_.data() + (hash(keys[i + kAhead]) & mask_));
    return slot(keys[i]);
  }
  [[nodiscard]] int find(std::uint64_t key) const {
    std::size_t i = hash(key) & mask_;
    while (slots_[i].fill == fill_) {
      if (slots_[i].key == key) return slots_[i].value;
      i = (i + 1) & mask_;
    }
    return -1;
  }

 private:
  static constexpr std::size_t kAhead = 32;
  struct Slot {
    std::uint64_t key = 0;
    int value = -1;
    unsigned fill = 0;  // the fill this slot was written in; 0: never
  };
  void grow() {
    std::vector<Slot> old(slots_.size() * 2);
    old.swap(slots_);
    mask_ = slots_.size() - 1;
    for (const Slot& s : old) {
      if (s.fill != fill_) continue;
      std::size_t i = hash(s.key) & mask_;
      while (slots_[i].fill == fill_) i = (i + 1) & mask_;
      slots_[i] = s;
    }
  }
  static std::size_t hash(std::uint64_t k) {
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdULL;
    k ^= k >> 33;
    return static_cast<std::size_t>(k);
  }
  std::vector<Slot> slots_;
  std::size_t mask_ = 0;
  std::size_t size_ = 0;
  unsigned fill_ = 0;
};

/// Calls f(x, y, z) for every cell within Chebyshev distance `ring` of cc or, with
/// shell_only, for the cells at exactly `ring` (what ring r adds to ring r - 1).
template <typename F>
inline void forEachCellWithin(const Eigen::Vector3i& cc, int ring, bool shell_only, F&& f) {
  for (int dx = -ring; dx <= ring; ++dx) {
    for (int dy = -ring; dy <= ring; ++dy) {
      // Inside the shell's x and y sides only its two z faces are new.
      const int step = shell_only && std::abs(dx) != ring && std::abs(dy) != ring ? 2 * ring : 1;
      for (int dz = -ring; dz <= ring; dz += step) f(cc.x() + dx, cc.y() + dy, cc.z() + dz);
    }
  }
}

/// Points bucketed by cell: cell c holds order[start[c] .. start[c+1]).
/// (The kNN search moves the arrays out and looks cells up in `index` itself.)
struct CellBuckets {
  std::vector<Eigen::Vector3i> cells;  ///< coordinate of each non-empty cell
  std::vector<int> start;              ///< size cells.size() + 1
  std::vector<int> order;              ///< point indices grouped by cell
  CellHash index{1};                   ///< cellKey -> cell number

  /// `simd`: the kernel of the cell keys (resolved, not kAuto).
  CellBuckets(const std::vector<Eigen::Vector3f>& points, float cell_m, Simd simd) : index(points.size() / 2 + 16) {
    const float inv = 1.f / cell_m;
    std::vector<int> cell_of_point(points.size());
    std::vector<int> counts;
    const std::vector<std::uint64_t> keys = cellKeys(points, inv, simd);
    for (std::size_t i = 0; i < points.size(); ++i) {
      int& s = index.slotAhead(keys, i);
      if (s < 0) {
        s = static_cast<int>(cells.size());
        cells.push_back(cellOf(points[i], inv));
        counts.push_back(0);
      }
      cell_of_point[i] = s;
      ++counts[static_cast<std::size_t>(s)];
    }
    start.assign(cells.size() + 1, 0);
    for (std::size_t c = 0; c < cells.size(); ++c) start[c + 1] = start[c] + counts[c];
    order.resize(points.size());
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < points.size(); ++i) {
      order[static_cast<std::size_t>(fill[static_cast<std::size_t>(cell_of_point[i])]++)] = static_cast<int>(i);
    }
  }
};

}  // namespace mobmap::perception::detail
