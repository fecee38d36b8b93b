// AVX2 versions of the hot loops, for the x86-64 CPUs without AVX-512 (most desktop and
// laptop parts, and AMD before Zen 4). Like kernels/avx512.cpp: compiled for every x86-64
// build, each function with its own target attribute, and only called after
// simdSupported(Simd::kAvx2) said yes. Every result equals the portable loops' to the
// last bit (same operations in the same order; the library is built with
// -ffp-contract=off).
#include "kernels/kernels.hpp"

#if MOBMAP_X86_KERNELS

#include <immintrin.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>

#define MOBMAP_TARGET_AVX2 __attribute__((target("avx2,popcnt")))

namespace mobmap::perception::detail::avx2 {
namespace {

// For each 4-bit mask, the 32-bit lane permutation that moves the selected 64-bit
// lanes, in order, to the front of a vector of four (AVX2 has no compress).
struct CompressTable {
  alignas(32) std::int32_t lanes[16][8];
};
constexpr CompressTable makeCompressTable() {
  CompressTable t{};
  for (int mask = 0; mask < 16; ++mask) {
    int out = 0;
    for (int lane = 0; lane < 4; ++lane) {
      if (!(mask >> lane & 1)) continue;
      t.lanes[mask][2 * out] = 2 * lane;
      t.lanes[mask][2 * out + 1] = 2 * lane + 1;
      ++out;
    }
    for (; out < 4; ++out) t.lanes[mask][2 * out] = t.lanes[mask][2 * out + 1] = 0;
  }
  return t;
}
constexpr CompressTable kCompress = makeCompressTable();

MOBMAP_TARGET_AVX2 inline int popcount(unsigned m) { return __builtin_popcount(m); }

// Sum of the eight 32-bit lanes.
MOBMAP_TARGET_AVX2 inline int laneSum(__m256i v) {
  __m128i s = _mm_add_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
  s = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0x4E));
  s = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0xB1));
  return _mm_cvtsi128_si32(s);
}

// Ranks of NV * 4 keys (keys[0 .. NV * 4)) among the m keys `all`: the number of keys
// below each, accumulated as vectors by subtracting the all-ones compare results.
template <int NV>
MOBMAP_TARGET_AVX2 inline void rankChunk(const std::uint64_t* chunk, const std::uint64_t* all, std::size_t m,
                                         std::int64_t* ranks) {
  __m256i key[NV], rank[NV];
  for (int v = 0; v < NV; ++v) {
    key[v] = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(chunk + 4 * v));
    rank[v] = _mm256_setzero_si256();
  }
  for (std::size_t j = 0; j < m; ++j) {
    const __m256i b = _mm256_set1_epi64x(static_cast<long long>(all[j]));
    for (int v = 0; v < NV; ++v) rank[v] = _mm256_sub_epi64(rank[v], _mm256_cmpgt_epi64(key[v], b));
  }
  for (int v = 0; v < NV; ++v) _mm256_storeu_si256(reinterpret_cast<__m256i*>(ranks + 4 * v), rank[v]);
}

// Ranks by distance alone of NV * 8 keys' distance bits (chunk[0 .. NV * 8)) among the
// m distance bits `all`: the number of strictly smaller distances, eight per vector
// (the bits of non-negative floats order as signed integers do).
template <int NV>
MOBMAP_TARGET_AVX2 inline void rankChunkByDistance(const std::int32_t* chunk, const std::int32_t* all,
                                                   std::size_t m, std::int32_t* ranks) {
  __m256i key[NV], rank[NV];
  for (int v = 0; v < NV; ++v) {
    key[v] = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(chunk + 8 * v));
    rank[v] = _mm256_setzero_si256();
  }
  for (std::size_t j = 0; j < m; ++j) {
    const __m256i b = _mm256_set1_epi32(all[j]);
    for (int v = 0; v < NV; ++v) rank[v] = _mm256_sub_epi32(rank[v], _mm256_cmpgt_epi32(key[v], b));
  }
  for (int v = 0; v < NV; ++v) _mm256_storeu_si256(reinterpret_cast<__m256i*>(ranks + 8 * v), rank[v]);
}

// x, y, z of point i as the low three lanes (the fourth is not used by the callers);
// the last point is loaded under a mask so that nothing past the array is read.
MOBMAP_TARGET_AVX2 inline __m128 loadPoint(const float* points, std::size_t i, std::size_t n_points) {
  if (i + 1 < n_points) return _mm_loadu_ps(points + 3 * i);
  return _mm_maskload_ps(points + 3 * i, _mm_setr_epi32(-1, -1, -1, 0));
}

MOBMAP_TARGET_AVX2 inline __m256d absPd(__m256d v) { return _mm256_andnot_pd(_mm256_set1_pd(-0.0), v); }

// A lane mask as a vector: all ones in the 64-bit lanes whose bit is set.
MOBMAP_TARGET_AVX2 inline __m256d maskOf(unsigned bits) {
  return _mm256_castsi256_pd(
      _mm256_setr_epi64x(bits & 1u ? -1 : 0, bits & 2u ? -1 : 0, bits & 4u ? -1 : 0, bits & 8u ? -1 : 0));
}

MOBMAP_TARGET_AVX2 inline __m256i compressLanes(unsigned mask) {
  return _mm256_load_si256(reinterpret_cast<const __m256i*>(kCompress.lanes[mask]));
}

// Two vectors of four doubles: lanes 0-3 and 4-7 of a group of eight. The plane
// kernel works on both halves in every step, so two independent chains of divisions
// and square roots are in flight (one half at a time waits on their latency).
struct Pair {
  __m256d h[2];
};

#define MOBMAP_PAIR_OP(name, expr)                                       \
  MOBMAP_TARGET_AVX2 inline Pair name(const Pair& a, const Pair& b) {    \
    return {{expr(a.h[0], b.h[0]), expr(a.h[1], b.h[1])}};              \
  }
MOBMAP_PAIR_OP(add, _mm256_add_pd)
MOBMAP_PAIR_OP(sub, _mm256_sub_pd)
MOBMAP_PAIR_OP(mul, _mm256_mul_pd)
MOBMAP_PAIR_OP(div, _mm256_div_pd)
MOBMAP_PAIR_OP(max, _mm256_max_pd)
MOBMAP_PAIR_OP(bitAnd, _mm256_and_pd)
MOBMAP_PAIR_OP(bitOr, _mm256_or_pd)
MOBMAP_PAIR_OP(bitAndNot, _mm256_andnot_pd)  // ~a & b
#undef MOBMAP_PAIR_OP

MOBMAP_TARGET_AVX2 inline Pair splat(double v) { return {{_mm256_set1_pd(v), _mm256_set1_pd(v)}}; }
MOBMAP_TARGET_AVX2 inline Pair sqrt(const Pair& a) { return {{_mm256_sqrt_pd(a.h[0]), _mm256_sqrt_pd(a.h[1])}}; }
MOBMAP_TARGET_AVX2 inline Pair abs(const Pair& a) { return {{absPd(a.h[0]), absPd(a.h[1])}}; }
// b where the mask is set, a elsewhere.
MOBMAP_TARGET_AVX2 inline Pair select(const Pair& a, const Pair& b, const Pair& mask) {
  return {{_mm256_blendv_pd(a.h[0], b.h[0], mask.h[0]), _mm256_blendv_pd(a.h[1], b.h[1], mask.h[1])}};
}
template <int kPredicate>
MOBMAP_TARGET_AVX2 inline Pair compare(const Pair& a, const Pair& b) {
  return {{_mm256_cmp_pd(a.h[0], b.h[0], kPredicate), _mm256_cmp_pd(a.h[1], b.h[1], kPredicate)}};
}
MOBMAP_TARGET_AVX2 inline unsigned bitsOf(const Pair& mask) {
  return static_cast<unsigned>(_mm256_movemask_pd(mask.h[0])) |
         static_cast<unsigned>(_mm256_movemask_pd(mask.h[1])) << 4;
}
MOBMAP_TARGET_AVX2 inline Pair maskOf8(unsigned bits) { return {{maskOf(bits & 15u), maskOf(bits >> 4)}}; }
// Eight floats as doubles.
MOBMAP_TARGET_AVX2 inline Pair widen(const float* v) {
  return {{_mm256_cvtps_pd(_mm_loadu_ps(v)), _mm256_cvtps_pd(_mm_loadu_ps(v + 4))}};
}
MOBMAP_TARGET_AVX2 inline void narrow(const Pair& a, float* out) {
  _mm_storeu_ps(out, _mm256_cvtpd_ps(a.h[0]));
  _mm_storeu_ps(out + 4, _mm256_cvtpd_ps(a.h[1]));
}

}  // namespace

MOBMAP_TARGET_AVX2 void distancesAndCounts(const float* x, const float* y, const float* z, std::size_t n, float px,
                                           float py, float pz, const float limit[4], float* d2, int count[4]) {
  const __m256 vx = _mm256_set1_ps(px), vy = _mm256_set1_ps(py), vz = _mm256_set1_ps(pz);
  const __m256 l0 = _mm256_set1_ps(limit[0]), l1 = _mm256_set1_ps(limit[1]);
  const __m256 l2 = _mm256_set1_ps(limit[2]), l3 = _mm256_set1_ps(limit[3]);
  // Each compare gives -1 in the lanes within its limit; subtracting counts them.
  __m256i c0 = _mm256_setzero_si256(), c1 = c0, c2 = c0, c3 = c0;
  for (std::size_t j = 0; j < n; j += 8) {
    const __m256 dx = _mm256_sub_ps(_mm256_loadu_ps(x + j), vx);
    const __m256 dy = _mm256_sub_ps(_mm256_loadu_ps(y + j), vy);
    const __m256 dz = _mm256_sub_ps(_mm256_loadu_ps(z + j), vz);
    const __m256 d = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy)), _mm256_mul_ps(dz, dz));
    _mm256_storeu_ps(d2 + j, d);
    // Ordered compares: NaN padding is never within a limit.
    c0 = _mm256_sub_epi32(c0, _mm256_castps_si256(_mm256_cmp_ps(d, l0, _CMP_LE_OQ)));
    c1 = _mm256_sub_epi32(c1, _mm256_castps_si256(_mm256_cmp_ps(d, l1, _CMP_LE_OQ)));
    c2 = _mm256_sub_epi32(c2, _mm256_castps_si256(_mm256_cmp_ps(d, l2, _CMP_LE_OQ)));
    c3 = _mm256_sub_epi32(c3, _mm256_castps_si256(_mm256_cmp_ps(d, l3, _CMP_LE_OQ)));
  }
  count[0] = laneSum(c0), count[1] = laneSum(c1), count[2] = laneSum(c2), count[3] = laneSum(c3);
}

MOBMAP_TARGET_AVX2 std::size_t compactKeys(const float* d2, const int* index, std::size_t n, int self, float limit,
                                           std::uint64_t* keys) {
  const __m256 lim = _mm256_set1_ps(limit);
  const __m256i vself = _mm256_set1_epi32(self);
  std::size_t out = 0;
  for (std::size_t j = 0; j < n; j += 8) {
    const __m256 d = _mm256_loadu_ps(d2 + j);
    const __m256i id = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(index + j));
    const __m256 within = _mm256_cmp_ps(d, lim, _CMP_LE_OQ);
    const __m256 is_self = _mm256_castsi256_ps(_mm256_cmpeq_epi32(id, vself));
    const auto take = static_cast<unsigned>(_mm256_movemask_ps(_mm256_andnot_ps(is_self, within)));
    // (d2 bits << 32) | index, as two vectors of four 64-bit keys; each is compressed
    // through the table and stored whole (at most 3 slots past the kept keys, which
    // stay below j + 8 <= n), even when it keeps none: skipping empty groups was a
    // branch that mispredicted (denoising 23.4 -> 21.2 ms per frame without it).
    const __m256i bits = _mm256_castps_si256(d);
    const __m256i lo = _mm256_or_si256(_mm256_slli_epi64(_mm256_cvtepu32_epi64(_mm256_castsi256_si128(bits)), 32),
                                       _mm256_cvtepu32_epi64(_mm256_castsi256_si128(id)));
    const __m256i hi = _mm256_or_si256(_mm256_slli_epi64(_mm256_cvtepu32_epi64(_mm256_extracti128_si256(bits, 1)), 32),
                                       _mm256_cvtepu32_epi64(_mm256_extracti128_si256(id, 1)));
    const unsigned take_lo = take & 15u, take_hi = take >> 4;
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(keys + out), _mm256_permutevar8x32_epi32(lo, compressLanes(take_lo)));
    out += static_cast<std::size_t>(popcount(take_lo));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(keys + out), _mm256_permutevar8x32_epi32(hi, compressLanes(take_hi)));
    out += static_cast<std::size_t>(popcount(take_hi));
  }
  return out;
}

MOBMAP_TARGET_AVX2 std::size_t rankSmallest(std::uint64_t* keys, std::size_t m, std::size_t k, float* sq_dist,
                                            int* index) {
  const std::size_t out = std::min(k, m);
  alignas(32) std::uint64_t sorted[kRankMaxKeys];
  // First by distance alone, eight 32-bit distances per vector: when no two distances
  // are equal, those ranks are the keys' ranks, and they are 0 .. m - 1 exactly when
  // their sum is m (m - 1) / 2 (a tie gives each key after the first of its group a
  // smaller rank). Four vectors of distances and their ranks stay in registers.
  alignas(32) std::int32_t dist[kRankMaxKeys + 8], dist_rank[kRankMaxKeys + 8];
  for (std::size_t j = 0; j < m; ++j) dist[j] = static_cast<std::int32_t>(keys[j] >> 32);
  const std::size_t dist_vectors = (m + 7) / 8;
  for (std::size_t j = m; j < dist_vectors * 8; ++j) dist[j] = std::numeric_limits<std::int32_t>::max();
  for (std::size_t v = 0; v < dist_vectors; v += 4) {
    switch (std::min<std::size_t>(4, dist_vectors - v)) {
      case 1: rankChunkByDistance<1>(dist + 8 * v, dist, m, dist_rank + 8 * v); break;
      case 2: rankChunkByDistance<2>(dist + 8 * v, dist, m, dist_rank + 8 * v); break;
      case 3: rankChunkByDistance<3>(dist + 8 * v, dist, m, dist_rank + 8 * v); break;
      default: rankChunkByDistance<4>(dist + 8 * v, dist, m, dist_rank + 8 * v); break;
    }
  }
  std::size_t rank_sum = 0;
  for (std::size_t j = 0; j < m; ++j) rank_sum += static_cast<std::size_t>(dist_rank[j]);
  if (rank_sum == m * (m - 1) / 2) {
    // The ranks are 0 .. m - 1, each once: every key is stored, without a branch on
    // whether it is among the first `out` (which mispredicted often).
    for (std::size_t j = 0; j < m; ++j) sorted[dist_rank[j]] = keys[j];
  } else {
    // Equal distances (in about a fifth of the searches on real frames: voxel
    // centroids often repeat a distance): rank the whole keys, four per vector. A
    // scalar pass ordering only the tied keys by index was slower (28.3 against 26.2
    // ms of denoising per frame).
    const std::size_t vectors = (m + 3) / 4;
    // Above every real key (whose top bit is 0), never ranked in.
    for (std::size_t j = m; j < vectors * 4; ++j) keys[j] = static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());
    alignas(32) std::int64_t ranks[kRankMaxKeys];
    for (std::size_t v = 0; v < vectors; v += 4) {
      switch (std::min<std::size_t>(4, vectors - v)) {
        case 1: rankChunk<1>(keys + 4 * v, keys, m, ranks + 4 * v); break;
        case 2: rankChunk<2>(keys + 4 * v, keys, m, ranks + 4 * v); break;
        case 3: rankChunk<3>(keys + 4 * v, keys, m, ranks + 4 * v); break;
        default: rankChunk<4>(keys + 4 * v, keys, m, ranks + 4 * v); break;
      }
    }
    for (std::size_t j = 0; j < m; ++j) sorted[ranks[j]] = keys[j];
  }
  // Unpacked four at a time: the low halves (indices) to the low 128 bits, the high
  // halves (distance bits) to the high 128 bits.
  const __m256i split = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
  std::size_t j = 0;
  for (; j + 4 <= out; j += 4) {
    const __m256i v = _mm256_permutevar8x32_epi32(_mm256_load_si256(reinterpret_cast<const __m256i*>(sorted + j)), split);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(index + j), _mm256_castsi256_si128(v));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(sq_dist + j), _mm256_extracti128_si256(v, 1));
  }
  for (; j < out; ++j) {
    const auto bits = static_cast<std::uint32_t>(sorted[j] >> 32);
    std::memcpy(sq_dist + j, &bits, sizeof bits);
    index[j] = static_cast<int>(static_cast<std::uint32_t>(sorted[j]));
  }
  return out;
}

MOBMAP_TARGET_AVX2 void offsetSums8(const float* points, std::size_t n_points, const int* indices, std::size_t k,
                                    const int* counts, std::size_t first, int lanes, float sums[9 * 8]) {
  // d = (dx, dy, dz, -) in the low lanes. The linear sums add d itself (dx * 1 is dx
  // exactly); the products lhs * rhs are dx*dx dx*dy dx*dz dy*dy dy*dz dz*dz.
  const __m256i lhs_idx = _mm256_setr_epi32(0, 0, 0, 1, 1, 2, 3, 3);
  const __m256i rhs_idx = _mm256_setr_epi32(0, 1, 2, 1, 2, 2, 3, 3);
  // Four points' chains at a time: their sums and centres fill 12 of the 16 vector
  // registers (eight at a time spilled the sums to the stack).
  for (int group = 0; group < lanes; group += 4) {
    __m128 linear[4], centre[4];
    __m256 products[4];
    int c[4] = {0, 0, 0, 0};
    int most = 0;
    for (int l = 0; l < 4; ++l) {
      linear[l] = _mm_setzero_ps();
      products[l] = _mm256_setzero_ps();
      centre[l] = _mm_setzero_ps();
      if (group + l >= lanes) continue;
      const std::size_t i = first + static_cast<std::size_t>(group + l);
      centre[l] = loadPoint(points, i, n_points);
      c[l] = counts[i];
      most = std::max(most, c[l]);
    }
    for (int j = 0; j < most; ++j) {
      for (int l = 0; l < 4; ++l) {
        if (j >= c[l]) continue;
        const std::size_t i = first + static_cast<std::size_t>(group + l);
        const auto nb = static_cast<std::size_t>(indices[i * k + static_cast<std::size_t>(j)]);
        const __m128 d = _mm_sub_ps(loadPoint(points, nb, n_points), centre[l]);
        linear[l] = _mm_add_ps(linear[l], d);
        const __m256 wide = _mm256_castps128_ps256(d);
        products[l] = _mm256_add_ps(products[l], _mm256_mul_ps(_mm256_permutevar8x32_ps(wide, lhs_idx),
                                                               _mm256_permutevar8x32_ps(wide, rhs_idx)));
      }
    }
    for (int l = 0; l < 4 && group + l < lanes; ++l) {
      alignas(32) float lin[4], prod[8];
      _mm_store_ps(lin, linear[l]);
      _mm256_store_ps(prod, products[l]);
      for (int q = 0; q < 3; ++q) sums[8 * q + group + l] = lin[q];
      for (int q = 0; q < 6; ++q) sums[8 * (q + 3) + group + l] = prod[q];
    }
  }
}

MOBMAP_TARGET_AVX2 unsigned localPlanes8(const float* points, const float sums[9 * 8], const int* counts,
                                         std::size_t first, int lanes, const float* near, const float viewpoint[3],
                                         float* normals, float* curvature, float* projected, double moments[9 * 8]) {
  float px_a[8] = {}, py_a[8] = {}, pz_a[8] = {}, sx_a[8] = {}, sy_a[8] = {}, sz_a[8] = {};
  alignas(16) std::int32_t count_a[8] = {};
  unsigned live = 0, planar_bits = 0;
  for (int l = 0; l < lanes; ++l) {
    const std::size_t i = first + static_cast<std::size_t>(l);
    px_a[l] = points[3 * i], py_a[l] = points[3 * i + 1], pz_a[l] = points[3 * i + 2];
    count_a[l] = counts[i];
    live |= 1u << l;
    if (counts[i] >= 2) {
      planar_bits |= 1u << l;
      if (near) sx_a[l] = near[3 * i], sy_a[l] = near[3 * i + 1], sz_a[l] = near[3 * i + 2];
    }
  }
  const Pair planar = maskOf8(planar_bits);

  // Moments in double (momentsOf).
  const Pair inv_m = div(splat(1.0), add(Pair{{_mm256_cvtepi32_pd(_mm_load_si128(reinterpret_cast<const __m128i*>(count_a))),
                                                _mm256_cvtepi32_pd(_mm_load_si128(reinterpret_cast<const __m128i*>(count_a + 4)))}},
                                          splat(1.0)));
  const Pair mx = mul(widen(sums), inv_m), my = mul(widen(sums + 8), inv_m), mz = mul(widen(sums + 16), inv_m);
  const Pair cxx = sub(mul(widen(sums + 24), inv_m), mul(mx, mx));
  const Pair cxy = sub(mul(widen(sums + 32), inv_m), mul(mx, my));
  const Pair cxz = sub(mul(widen(sums + 40), inv_m), mul(mx, mz));
  const Pair cyy = sub(mul(widen(sums + 48), inv_m), mul(my, my));
  const Pair cyz = sub(mul(widen(sums + 56), inv_m), mul(my, mz));
  const Pair czz = sub(mul(widen(sums + 64), inv_m), mul(mz, mz));

  // Inverse iteration from `near` (smallestEigenvectorNear), the eight lanes in step.
  const Pair zero = splat(0.0);
  Pair done = zero, nx = zero, ny = zero, nz = zero, curv = splat(1.0);
  if (near) {
    const Pair x0s = widen(sx_a), x1s = widen(sy_a), x2s = widen(sz_a);
    const Pair start2 = add(add(mul(x0s, x0s), mul(x1s, x1s)), mul(x2s, x2s));
    Pair active = bitAnd(planar, compare<_CMP_NLT_UQ>(start2, splat(0.25)));
    // adj(C), squared twice (iterationMatrix).
    Pair b00 = sub(mul(cyy, czz), mul(cyz, cyz));
    Pair b11 = sub(mul(cxx, czz), mul(cxz, cxz));
    Pair b22 = sub(mul(cxx, cyy), mul(cxy, cxy));
    Pair b01 = sub(mul(cxz, cyz), mul(cxy, czz));
    Pair b02 = sub(mul(cxy, cyz), mul(cxz, cyy));
    Pair b12 = sub(mul(cxy, cxz), mul(cxx, cyz));
    for (int square = 0; square < 2; ++square) {
      const Pair j00 = b00, j11 = b11, j22 = b22, j01 = b01, j02 = b02, j12 = b12;
      b00 = add(add(mul(j00, j00), mul(j01, j01)), mul(j02, j02));
      b11 = add(add(mul(j01, j01), mul(j11, j11)), mul(j12, j12));
      b22 = add(add(mul(j02, j02), mul(j12, j12)), mul(j22, j22));
      b01 = add(add(mul(j00, j01), mul(j01, j11)), mul(j02, j12));
      b02 = add(add(mul(j00, j02), mul(j01, j12)), mul(j02, j22));
      b12 = add(add(mul(j01, j02), mul(j11, j12)), mul(j12, j22));
    }
    const Pair scale = max(max(max(abs(b00), abs(b11)), max(abs(b22), abs(b01))), max(abs(b02), abs(b12)));
    const Pair floor = mul(splat(1e-30), scale);
    const Pair inf = splat(std::numeric_limits<double>::infinity());
    Pair x0 = x0s, x1 = x1s, x2 = x2s;
    for (int step = 0; step < 8 && bitsOf(active); ++step) {
      const Pair y0 = add(add(mul(b00, x0), mul(b01, x1)), mul(b02, x2));
      const Pair y1 = add(add(mul(b01, x0), mul(b11, x1)), mul(b12, x2));
      const Pair y2 = add(mul(b02, x0), add(mul(b12, x1), mul(b22, x2)));
      const Pair norm = sqrt(add(add(mul(y0, y0), mul(y1, y1)), mul(y2, y2)));
      // !(norm > floor) || !isfinite(norm): such lanes go to the exact solver.
      active = bitAnd(active, bitAnd(compare<_CMP_GT_OQ>(norm, floor), compare<_CMP_LT_OQ>(norm, inf)));
      const Pair inv = div(splat(1.0), norm);
      const Pair n0 = mul(y0, inv), n1 = mul(y1, inv), n2 = mul(y2, inv);
      const Pair d0 = sub(n0, x0), d1 = sub(n1, x1), d2 = sub(n2, x2);
      const Pair moved2 = add(add(mul(d0, d0), mul(d1, d1)), mul(d2, d2));
      x0 = select(x0, n0, active), x1 = select(x1, n1, active), x2 = select(x2, n2, active);
      const Pair converged = bitAnd(active, compare<_CMP_LE_OQ>(moved2, splat(kStepUnder1e5Squared)));
      if (bitsOf(converged)) {
        const Pair total = add(cxx, add(cyy, czz));
        const Pair cx0 = add(add(mul(cxx, x0), mul(cxy, x1)), mul(cxz, x2));
        const Pair cx1 = add(add(mul(cxy, x0), mul(cyy, x1)), mul(cyz, x2));
        const Pair cx2 = add(mul(cxz, x0), add(mul(cyz, x1), mul(czz, x2)));
        const Pair rayleigh = add(add(mul(x0, cx0), mul(x1, cx1)), mul(x2, cx2));
        // std::max(0.0, v): 0 unless 0 < v (so a NaN gives 0), as vmaxpd(v, 0) does.
        const Pair lambda0 = max(rayleigh, zero);
        const Pair plane = bitAnd(converged, bitAnd(compare<_CMP_GT_OQ>(total, zero),
                                                    compare<_CMP_NGT_UQ>(lambda0, mul(splat(0.25), total))));
        nx = select(nx, x0, plane), ny = select(ny, x1, plane), nz = select(nz, x2, plane);
        curv = select(curv, div(lambda0, total), plane);
        done = bitOr(done, plane);
        active = bitAndNot(converged, active);
      }
    }
  }

  const unsigned done_bits = bitsOf(done);
  if (done_bits) {
    // orientedNormal: turned towards the viewpoint (the difference in single
    // precision), then normalised.
    float vx_a[8], vy_a[8], vz_a[8];
    for (int l = 0; l < 8; ++l) {
      vx_a[l] = viewpoint[0] - px_a[l], vy_a[l] = viewpoint[1] - py_a[l], vz_a[l] = viewpoint[2] - pz_a[l];
    }
    const Pair facing = add(add(mul(nx, widen(vx_a)), mul(ny, widen(vy_a))), mul(nz, widen(vz_a)));
    const Pair sign = select(splat(1.0), splat(-1.0), compare<_CMP_LT_OQ>(facing, zero));
    const Pair ox = mul(nx, sign), oy = mul(ny, sign), oz = mul(nz, sign);
    const Pair len = sqrt(add(add(mul(ox, ox), mul(oy, oy)), mul(oz, oz)));
    float out_n[3][8], out_c[8], out_p[3][8];
    narrow(div(ox, len), out_n[0]);
    narrow(div(oy, len), out_n[1]);
    narrow(div(oz, len), out_n[2]);
    narrow(curv, out_c);
    // projectedPoint, with the unturned normal.
    const Pair t = add(add(mul(nx, mx), mul(ny, my)), mul(nz, mz));
    narrow(add(widen(px_a), mul(nx, t)), out_p[0]);
    narrow(add(widen(py_a), mul(ny, t)), out_p[1]);
    narrow(add(widen(pz_a), mul(nz, t)), out_p[2]);
    storeDoneLanes(done_bits, lanes, first, out_n, out_c, out_p, normals, curvature, projected);
  }
  const Pair fields[9] = {mx, my, mz, cxx, cxy, cxz, cyy, cyz, czz};
  for (int q = 0; q < 9; ++q) {
    _mm256_storeu_pd(moments + 8 * q, fields[q].h[0]);
    _mm256_storeu_pd(moments + 8 * q + 4, fields[q].h[1]);
  }
  // Lanes with under 2 neighbours keep what the caller set: they count as done.
  return (done_bits | (live & ~planar_bits)) & live;
}

MOBMAP_TARGET_AVX2 std::size_t cellKeys(const float* xyz, std::size_t n, float inv_cell, std::uint64_t* keys) {
  const __m256 inv = _mm256_set1_ps(inv_cell);
  const __m256i offset = _mm256_set1_epi64x(1 << 20);
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const float* p = xyz + 3 * i;
    // Points 0-3 in the low halves, 4-7 in the high ones: x0 y0 z0 x1 | y1 z1 x2 y2 |
    // z2 x3 y3 z3 (and the same for 4-7), shuffled into x, y and z of the 8 points in
    // the order 0 1 2 3 | 4 5 6 7.
    const __m256 m0 = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(p)), _mm_loadu_ps(p + 12), 1);
    const __m256 m1 = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(p + 4)), _mm_loadu_ps(p + 16), 1);
    const __m256 m2 = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(p + 8)), _mm_loadu_ps(p + 20), 1);
    const __m256 x2y2x3y3 = _mm256_shuffle_ps(m1, m2, _MM_SHUFFLE(2, 1, 3, 2));  // x2 y2 x3 y3
    const __m256 y0z0y1z1 = _mm256_shuffle_ps(m0, m1, _MM_SHUFFLE(1, 0, 2, 1));  // y0 z0 y1 z1
    const __m256 x = _mm256_shuffle_ps(m0, x2y2x3y3, _MM_SHUFFLE(2, 0, 3, 0));
    const __m256 y = _mm256_shuffle_ps(y0z0y1z1, x2y2x3y3, _MM_SHUFFLE(3, 1, 2, 0));
    const __m256 z = _mm256_shuffle_ps(y0z0y1z1, m2, _MM_SHUFFLE(3, 0, 3, 1));
    const __m256 axes[3] = {x, y, z};
    __m256i lo[3], hi[3];
    for (int axis = 0; axis < 3; ++axis) {
      // floor(v * inv), exact, then converted (an integer-valued float converts exactly).
      const __m256i cell = _mm256_cvttps_epi32(_mm256_floor_ps(_mm256_mul_ps(axes[axis], inv)));
      lo[axis] = _mm256_add_epi64(_mm256_cvtepi32_epi64(_mm256_castsi256_si128(cell)), offset);
      hi[axis] = _mm256_add_epi64(_mm256_cvtepi32_epi64(_mm256_extracti128_si256(cell, 1)), offset);
    }
    const __m256i k_lo = _mm256_or_si256(_mm256_or_si256(_mm256_slli_epi64(lo[0], 42), _mm256_slli_epi64(lo[1], 21)), lo[2]);
    const __m256i k_hi = _mm256_or_si256(_mm256_or_si256(_mm256_slli_epi64(hi[0], 42), _mm256_slli_epi64(hi[1], 21)), hi[2]);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(keys + i), k_lo);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(keys + i + 4), k_hi);
  }
  return i;
}

MOBMAP_TARGET_AVX2 std::size_t planeInliers(const float* x, const float* y, const float* z, const float* nx,
                                            const float* ny, const float* nz, std::size_t m, const float plane[4],
                                            float dist, float cos_normal, std::uint64_t* bits) {
  const __m256 a = _mm256_set1_ps(plane[0]), b = _mm256_set1_ps(plane[1]), c = _mm256_set1_ps(plane[2]);
  const __m256 d = _mm256_set1_ps(plane[3]), limit = _mm256_set1_ps(dist), cosine = _mm256_set1_ps(cos_normal);
  const __m256 magnitude = _mm256_castsi256_ps(_mm256_set1_epi32(0x7FFFFFFF));
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  std::size_t total = 0;
  for (std::size_t w = 0; 64 * w < m; ++w) {
    std::uint64_t word = 0;
    for (std::size_t q = 0; q < 8; ++q) {
      const std::size_t j = 64 * w + 8 * q;
      if (j >= m) break;
      const int left = static_cast<int>(std::min<std::size_t>(m - j, 8));
      const __m256i live = _mm256_cmpgt_epi32(_mm256_set1_epi32(left), lane);
      // |(a x + (b y + c z)) + d| not above the distance: not greater, or NaN.
      const __m256 t = _mm256_add_ps(
          _mm256_add_ps(_mm256_mul_ps(a, _mm256_maskload_ps(x + j, live)),
                        _mm256_add_ps(_mm256_mul_ps(b, _mm256_maskload_ps(y + j, live)),
                                      _mm256_mul_ps(c, _mm256_maskload_ps(z + j, live)))),
          d);
      __m256 in = _mm256_and_ps(_mm256_castsi256_ps(live), _mm256_cmp_ps(_mm256_and_ps(t, magnitude), limit, _CMP_NGT_UQ));
      if (nx) {
        // |a nx + (b ny + c nz)| not below the cosine: not less, or NaN.
        const __m256 u = _mm256_add_ps(_mm256_mul_ps(a, _mm256_maskload_ps(nx + j, live)),
                                       _mm256_add_ps(_mm256_mul_ps(b, _mm256_maskload_ps(ny + j, live)),
                                                     _mm256_mul_ps(c, _mm256_maskload_ps(nz + j, live))));
        in = _mm256_and_ps(in, _mm256_cmp_ps(_mm256_and_ps(u, magnitude), cosine, _CMP_NLT_UQ));
      }
      word |= static_cast<std::uint64_t>(static_cast<unsigned>(_mm256_movemask_ps(in))) << (8 * q);
    }
    total += static_cast<std::size_t>(__builtin_popcountll(word));
    if (bits) bits[w] = word;
  }
  return total;
}

}  // namespace mobmap::perception::detail::avx2

#endif  // MOBMAP_X86_KERNELS
