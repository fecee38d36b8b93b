#pragma once
// Open-addressing hash from packed integer cell coordinates to a value (internal).

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

inline Eigen::Vector3i cellOf(const Eigen::Vector3f& p, float inv_cell) {
  return {static_cast<int>(std::floor(p.x() * inv_cell)), static_cast<int>(std::floor(p.y() * inv_cell)),
          static_cast<int>(std::floor(p.z() * inv_cell))};
}

/// The packed cell keys of the points, in order: computed before a scan of lookups so
/// that CellHash::slotAhead can ask for a slot before it is needed.
inline std::vector<std::uint64_t> cellKeys(const std::vector<Eigen::Vector3f>& points, float inv_cell) {
  std::vector<std::uint64_t> keys(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3i c = cellOf(points[i], inv_cell);
    keys[i] = cellKey(c.x(), c.y(), c.z());
  }
  return keys;
}

/// key -> int32 value; capacity a power of two, linear probing.
class CellHash {
 public:
  explicit CellHash(std::size_t expected) {
    std::size_t cap = 16;
    while (cap < expected * 2) cap <<= 1;
    keys_.assign(cap, kEmpty);
    values_.assign(cap, -1);
    mask_ = cap - 1;
  }
  /// Returns a reference to the value slot of `key`, inserting -1 if absent. The
  /// reference is valid until the next insertion (the table doubles at half load).
  int& slot(std::uint64_t key) {
    if (2 * (size_ + 1) > keys_.size()) grow();
    std::size_t i = hash(key) & mask_;
    while (keys_[i] != kEmpty && keys_[i] != key) i = (i + 1) & mask_;
    if (keys_[i] == kEmpty) {
      keys_[i] = key;
      ++size_;
    }
    return values_[i];
  }
  /// slot(keys[i]) in a scan over `keys`, having first asked for the cache lines of
  /// keys[i + kAhead]'s slot: the first lookup of every key misses the cache otherwise
  /// (the table is a few MB and keys land at random places in it).
  int& slotAhead(const std::vector<std::uint64_t>& keys, std::size_t i) {
    constexpr std::size_t kAhead = 32;
    if (i + kAhead < keys.size()) {
      const std::size_t ahead = hash(keys[i + kAhead]) & mask_;
      __builtin_prefetch(keys_.data() + ahead);
      __builtin_prefetch(values_.data() + ahead);
    }
    return slot(keys[i]);
  }
  [[nodiscard]] int find(std::uint64_t key) const {
    std::size_t i = hash(key) & mask_;
    while (keys_[i] != kEmpty) {
      if (keys_[i] == key) return values_[i];
      i = (i + 1) & mask_;
    }
    return -1;
  }

 private:
  static constexpr std::uint64_t kEmpty = ~0ULL;
  void grow() {
    std::vector<std::uint64_t> old_keys(keys_.size() * 2, kEmpty);
    std::vector<int> old_values(values_.size() * 2, -1);
    old_keys.swap(keys_);
    old_values.swap(values_);
    mask_ = keys_.size() - 1;
    for (std::size_t j = 0; j < old_keys.size(); ++j) {
      if (old_keys[j] == kEmpty) continue;
      std::size_t i = hash(old_keys[j]) & mask_;
      while (keys_[i] != kEmpty) i = (i + 1) & mask_;
      keys_[i] = old_keys[j];
      values_[i] = old_values[j];
    }
  }
  std::size_t size_ = 0;
  static std::size_t hash(std::uint64_t k) {
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdULL;
    k ^= k >> 33;
    return static_cast<std::size_t>(k);
  }
  std::vector<std::uint64_t> keys_;
  std::vector<int> values_;
  std::size_t mask_ = 0;
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

  CellBuckets(const std::vector<Eigen::Vector3f>& points, float cell_m) : index(points.size() / 2 + 16) {
    const float inv = 1.f / cell_m;
    std::vector<int> cell_of_point(points.size());
    std::vector<int> counts;
    const std::vector<std::uint64_t> keys = cellKeys(points, inv);
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
