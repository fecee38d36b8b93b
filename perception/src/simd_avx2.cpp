// AVX2 versions of the hot loops, for the x86-64 CPUs without AVX-512 (most desktop and
// laptop parts, and AMD before Zen 4). Like simd_avx512.cpp: compiled for every x86-64
// build, each function with its own target attribute, and only called after
// simdSupported(Simd::kAvx2) said yes. Every result equals the portable loops' to the
// last bit (same operations in the same order; the library is built with
// -ffp-contract=off).
#include "simd_kernels.hpp"

#if MOBMAP_X86_KERNELS

#include <immintrin.h>

#include <algorithm>
#include <array>
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

// Field q of the four lanes from `off` of the sums (sums[q * 8 + lane]), in double.
MOBMAP_TARGET_AVX2 inline __m256d sumField(const float sums[9 * 8], int q, int off) {
  return _mm256_cvtps_pd(_mm_loadu_ps(sums + 8 * q + off));
}

// A lane mask as a vector: all ones in the 64-bit lanes whose bit is set.
MOBMAP_TARGET_AVX2 inline __m256d maskOf(unsigned bits) {
  return _mm256_castsi256_pd(
      _mm256_setr_epi64x(bits & 1u ? -1 : 0, bits & 2u ? -1 : 0, bits & 4u ? -1 : 0, bits & 8u ? -1 : 0));
}

MOBMAP_TARGET_AVX2 inline __m256i compressLanes(unsigned mask) {
  return _mm256_load_si256(reinterpret_cast<const __m256i*>(kCompress.lanes[mask]));
}

// localPlanes8 for the lanes first .. first + lanes - 1 (lanes <= 4) of a group of
// eight starting at group_first; `half` (0 or 1) says which four of the group's lanes
// these are, for the sums and moments layout. Returns the done-or-few mask of these
// lanes (bit l for lane first + l).
MOBMAP_TARGET_AVX2 unsigned localPlanes4(const float* points, const float sums[9 * 8], const int* counts,
                                         std::size_t first, int lanes, int half, const float* near,
                                         const float viewpoint[3], float* normals, float* curvature,
                                         float* projected, double moments[9 * 8]) {
  const int off = 4 * half;
  alignas(16) float px_a[4] = {0, 0, 0, 0}, py_a[4] = {0, 0, 0, 0}, pz_a[4] = {0, 0, 0, 0};
  alignas(16) float nx_a[4] = {0, 0, 0, 0}, ny_a[4] = {0, 0, 0, 0}, nz_a[4] = {0, 0, 0, 0};
  alignas(16) std::int32_t count_a[4] = {0, 0, 0, 0};
  unsigned live = 0, planar_bits = 0;
  for (int l = 0; l < lanes; ++l) {
    const std::size_t i = first + static_cast<std::size_t>(l);
    px_a[l] = points[3 * i], py_a[l] = points[3 * i + 1], pz_a[l] = points[3 * i + 2];
    count_a[l] = counts[i];
    live |= 1u << l;
    if (counts[i] >= 2) {
      planar_bits |= 1u << l;
      if (near) nx_a[l] = near[3 * i], ny_a[l] = near[3 * i + 1], nz_a[l] = near[3 * i + 2];
    }
  }
  const __m128 px = _mm_load_ps(px_a), py = _mm_load_ps(py_a), pz = _mm_load_ps(pz_a);
  const __m256d planar = maskOf(planar_bits);

  // Moments in double (momentsOf).
  const __m256d m = _mm256_add_pd(_mm256_cvtepi32_pd(_mm_load_si128(reinterpret_cast<const __m128i*>(count_a))),
                                  _mm256_set1_pd(1.0));
  const __m256d mx = _mm256_div_pd(sumField(sums, 0, off), m), my = _mm256_div_pd(sumField(sums, 1, off), m), mz = _mm256_div_pd(sumField(sums, 2, off), m);
  const __m256d cxx = _mm256_sub_pd(_mm256_div_pd(sumField(sums, 3, off), m), _mm256_mul_pd(mx, mx));
  const __m256d cxy = _mm256_sub_pd(_mm256_div_pd(sumField(sums, 4, off), m), _mm256_mul_pd(mx, my));
  const __m256d cxz = _mm256_sub_pd(_mm256_div_pd(sumField(sums, 5, off), m), _mm256_mul_pd(mx, mz));
  const __m256d cyy = _mm256_sub_pd(_mm256_div_pd(sumField(sums, 6, off), m), _mm256_mul_pd(my, my));
  const __m256d cyz = _mm256_sub_pd(_mm256_div_pd(sumField(sums, 7, off), m), _mm256_mul_pd(my, mz));
  const __m256d czz = _mm256_sub_pd(_mm256_div_pd(sumField(sums, 8, off), m), _mm256_mul_pd(mz, mz));

  // Inverse iteration from `near` (smallestEigenvectorNear), the four lanes in step.
  __m256d done = _mm256_setzero_pd();
  __m256d nx = _mm256_setzero_pd(), ny = nx, nz = nx, curv = _mm256_set1_pd(1.0);
  if (near) {
    const __m256d x0s = _mm256_cvtps_pd(_mm_load_ps(nx_a)), x1s = _mm256_cvtps_pd(_mm_load_ps(ny_a));
    const __m256d x2s = _mm256_cvtps_pd(_mm_load_ps(nz_a));
    const __m256d start2 =
        _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(x0s, x0s), _mm256_mul_pd(x1s, x1s)), _mm256_mul_pd(x2s, x2s));
    __m256d active = _mm256_and_pd(planar, _mm256_cmp_pd(start2, _mm256_set1_pd(0.25), _CMP_NLT_UQ));
    const __m256d a00 = _mm256_sub_pd(_mm256_mul_pd(cyy, czz), _mm256_mul_pd(cyz, cyz));
    const __m256d a11 = _mm256_sub_pd(_mm256_mul_pd(cxx, czz), _mm256_mul_pd(cxz, cxz));
    const __m256d a22 = _mm256_sub_pd(_mm256_mul_pd(cxx, cyy), _mm256_mul_pd(cxy, cxy));
    const __m256d a01 = _mm256_sub_pd(_mm256_mul_pd(cxz, cyz), _mm256_mul_pd(cxy, czz));
    const __m256d a02 = _mm256_sub_pd(_mm256_mul_pd(cxy, cyz), _mm256_mul_pd(cxz, cyy));
    const __m256d a12 = _mm256_sub_pd(_mm256_mul_pd(cxy, cxz), _mm256_mul_pd(cxx, cyz));
    const __m256d scale = _mm256_max_pd(_mm256_max_pd(_mm256_max_pd(absPd(a00), absPd(a11)),
                                                      _mm256_max_pd(absPd(a22), absPd(a01))),
                                        _mm256_max_pd(absPd(a02), absPd(a12)));
    const __m256d floor = _mm256_mul_pd(_mm256_set1_pd(1e-30), scale);
    const __m256d inf = _mm256_set1_pd(std::numeric_limits<double>::infinity());
    __m256d x0 = x0s, x1 = x1s, x2 = x2s;
    for (int step = 0; step < 8 && _mm256_movemask_pd(active); ++step) {
      const __m256d y0 =
          _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(a00, x0), _mm256_mul_pd(a01, x1)), _mm256_mul_pd(a02, x2));
      const __m256d y1 =
          _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(a01, x0), _mm256_mul_pd(a11, x1)), _mm256_mul_pd(a12, x2));
      const __m256d y2 =
          _mm256_add_pd(_mm256_mul_pd(a02, x0), _mm256_add_pd(_mm256_mul_pd(a12, x1), _mm256_mul_pd(a22, x2)));
      const __m256d norm = _mm256_sqrt_pd(
          _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(y0, y0), _mm256_mul_pd(y1, y1)), _mm256_mul_pd(y2, y2)));
      // !(norm > floor) || !isfinite(norm): such lanes go to the exact solver.
      active = _mm256_and_pd(active, _mm256_and_pd(_mm256_cmp_pd(norm, floor, _CMP_GT_OQ),
                                                   _mm256_cmp_pd(norm, inf, _CMP_LT_OQ)));
      const __m256d n0 = _mm256_div_pd(y0, norm), n1 = _mm256_div_pd(y1, norm), n2 = _mm256_div_pd(y2, norm);
      const __m256d d0 = _mm256_sub_pd(n0, x0), d1 = _mm256_sub_pd(n1, x1), d2 = _mm256_sub_pd(n2, x2);
      const __m256d moved = _mm256_sqrt_pd(
          _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(d0, d0), _mm256_mul_pd(d1, d1)), _mm256_mul_pd(d2, d2)));
      x0 = _mm256_blendv_pd(x0, n0, active), x1 = _mm256_blendv_pd(x1, n1, active);
      x2 = _mm256_blendv_pd(x2, n2, active);
      const __m256d converged = _mm256_and_pd(active, _mm256_cmp_pd(moved, _mm256_set1_pd(1e-5), _CMP_LT_OQ));
      if (_mm256_movemask_pd(converged)) {
        const __m256d total = _mm256_add_pd(cxx, _mm256_add_pd(cyy, czz));
        const __m256d cx0 =
            _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(cxx, x0), _mm256_mul_pd(cxy, x1)), _mm256_mul_pd(cxz, x2));
        const __m256d cx1 =
            _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(cxy, x0), _mm256_mul_pd(cyy, x1)), _mm256_mul_pd(cyz, x2));
        const __m256d cx2 =
            _mm256_add_pd(_mm256_mul_pd(cxz, x0), _mm256_add_pd(_mm256_mul_pd(cyz, x1), _mm256_mul_pd(czz, x2)));
        const __m256d rayleigh =
            _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(x0, cx0), _mm256_mul_pd(x1, cx1)), _mm256_mul_pd(x2, cx2));
        // std::max(0.0, v): 0 unless 0 < v (so a NaN gives 0), as vmaxpd(v, 0) does.
        const __m256d lambda0 = _mm256_max_pd(rayleigh, _mm256_setzero_pd());
        const __m256d plane = _mm256_and_pd(
            converged, _mm256_and_pd(_mm256_cmp_pd(total, _mm256_setzero_pd(), _CMP_GT_OQ),
                                     _mm256_cmp_pd(lambda0, _mm256_mul_pd(_mm256_set1_pd(0.25), total), _CMP_NGT_UQ)));
        nx = _mm256_blendv_pd(nx, x0, plane), ny = _mm256_blendv_pd(ny, x1, plane);
        nz = _mm256_blendv_pd(nz, x2, plane);
        curv = _mm256_blendv_pd(curv, _mm256_div_pd(lambda0, total), plane);
        done = _mm256_or_pd(done, plane);
        active = _mm256_andnot_pd(converged, active);
      }
    }
  }

  const auto done_bits = static_cast<unsigned>(_mm256_movemask_pd(done));
  if (done_bits) {
    // orientedNormal: turned towards the viewpoint, then normalised, in single precision.
    const __m256d vx = _mm256_cvtps_pd(_mm_sub_ps(_mm_set1_ps(viewpoint[0]), px));
    const __m256d vy = _mm256_cvtps_pd(_mm_sub_ps(_mm_set1_ps(viewpoint[1]), py));
    const __m256d vz = _mm256_cvtps_pd(_mm_sub_ps(_mm_set1_ps(viewpoint[2]), pz));
    const __m256d facing =
        _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(nx, vx), _mm256_mul_pd(ny, vy)), _mm256_mul_pd(nz, vz));
    const __m256d sign = _mm256_blendv_pd(_mm256_set1_pd(1.0), _mm256_set1_pd(-1.0),
                                          _mm256_cmp_pd(facing, _mm256_setzero_pd(), _CMP_LT_OQ));
    const __m256d ox = _mm256_mul_pd(nx, sign), oy = _mm256_mul_pd(ny, sign), oz = _mm256_mul_pd(nz, sign);
    const __m256d len = _mm256_sqrt_pd(
        _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(ox, ox), _mm256_mul_pd(oy, oy)), _mm256_mul_pd(oz, oz)));
    alignas(16) float out_n[3][4], out_c[4], out_p[3][4];
    _mm_store_ps(out_n[0], _mm256_cvtpd_ps(_mm256_div_pd(ox, len)));
    _mm_store_ps(out_n[1], _mm256_cvtpd_ps(_mm256_div_pd(oy, len)));
    _mm_store_ps(out_n[2], _mm256_cvtpd_ps(_mm256_div_pd(oz, len)));
    _mm_store_ps(out_c, _mm256_cvtpd_ps(curv));
    // projectedPoint, with the unturned normal.
    const __m256d t = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(nx, mx), _mm256_mul_pd(ny, my)), _mm256_mul_pd(nz, mz));
    _mm_store_ps(out_p[0], _mm256_cvtpd_ps(_mm256_add_pd(_mm256_cvtps_pd(px), _mm256_mul_pd(nx, t))));
    _mm_store_ps(out_p[1], _mm256_cvtpd_ps(_mm256_add_pd(_mm256_cvtps_pd(py), _mm256_mul_pd(ny, t))));
    _mm_store_ps(out_p[2], _mm256_cvtpd_ps(_mm256_add_pd(_mm256_cvtps_pd(pz), _mm256_mul_pd(nz, t))));
    for (int l = 0; l < lanes; ++l) {
      if (!(done_bits >> l & 1u)) continue;
      const std::size_t i = first + static_cast<std::size_t>(l);
      for (int a = 0; a < 3; ++a) normals[3 * i + static_cast<std::size_t>(a)] = out_n[a][l];
      curvature[i] = out_c[l];
      if (projected) {
        for (int a = 0; a < 3; ++a) projected[3 * i + static_cast<std::size_t>(a)] = out_p[a][l];
      }
    }
  }
  const __m256d fields[9] = {mx, my, mz, cxx, cxy, cxz, cyy, cyz, czz};
  for (int q = 0; q < 9; ++q) _mm256_storeu_pd(moments + 8 * q + off, fields[q]);
  // Lanes with under 2 neighbours keep what the caller set: they count as done.
  return (done_bits | (live & ~planar_bits)) & live;
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
    if (!take) continue;
    // (d2 bits << 32) | index, as two vectors of four 64-bit keys; each is compressed
    // through the table and stored whole (at most 3 slots past the kept keys, which
    // stay below j + 8 <= n).
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
  const std::size_t vectors = (m + 3) / 4;
  // Above every real key (whose top bit is 0), never ranked in.
  for (std::size_t j = m; j < vectors * 4; ++j) keys[j] = static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());
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
    for (std::size_t j = 0; j < m; ++j) {
      if (static_cast<std::size_t>(dist_rank[j]) < out) sorted[dist_rank[j]] = keys[j];
    }
  } else {
    // Equal distances (in about a fifth of the searches on real frames: voxel
    // centroids often repeat a distance): rank the whole keys, four per vector. A
    // scalar pass ordering only the tied keys by index was slower (28.3 against 26.2
    // ms of denoising per frame).
    alignas(32) std::int64_t ranks[kRankMaxKeys];
    for (std::size_t v = 0; v < vectors; v += 4) {
      switch (std::min<std::size_t>(4, vectors - v)) {
        case 1: rankChunk<1>(keys + 4 * v, keys, m, ranks + 4 * v); break;
        case 2: rankChunk<2>(keys + 4 * v, keys, m, ranks + 4 * v); break;
        case 3: rankChunk<3>(keys + 4 * v, keys, m, ranks + 4 * v); break;
        default: rankChunk<4>(keys + 4 * v, keys, m, ranks + 4 * v); break;
      }
    }
    for (std::size_t j = 0; j < m; ++j) {
      if (static_cast<std::size_t>(ranks[j]) < out) sorted[ranks[j]] = keys[j];
    }
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
  __m128 linear[8], centre[8];
  __m256 products[8];
  int c[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int most = 0;
  for (int l = 0; l < 8; ++l) {
    linear[l] = _mm_setzero_ps();
    products[l] = _mm256_setzero_ps();
    centre[l] = _mm_setzero_ps();
    if (l >= lanes) continue;
    const std::size_t i = first + static_cast<std::size_t>(l);
    centre[l] = loadPoint(points, i, n_points);
    c[l] = counts[i];
    most = std::max(most, c[l]);
  }
  for (int j = 0; j < most; ++j) {
    for (int l = 0; l < 8; ++l) {
      if (j >= c[l]) continue;
      const std::size_t i = first + static_cast<std::size_t>(l);
      const auto nb = static_cast<std::size_t>(indices[i * k + static_cast<std::size_t>(j)]);
      const __m128 d = _mm_sub_ps(loadPoint(points, nb, n_points), centre[l]);
      linear[l] = _mm_add_ps(linear[l], d);
      const __m256 wide = _mm256_castps128_ps256(d);
      products[l] = _mm256_add_ps(products[l], _mm256_mul_ps(_mm256_permutevar8x32_ps(wide, lhs_idx),
                                                             _mm256_permutevar8x32_ps(wide, rhs_idx)));
    }
  }
  for (int l = 0; l < lanes; ++l) {
    alignas(32) float lin[4], prod[8];
    _mm_store_ps(lin, linear[l]);
    _mm256_store_ps(prod, products[l]);
    for (int q = 0; q < 3; ++q) sums[8 * q + l] = lin[q];
    for (int q = 0; q < 6; ++q) sums[8 * (q + 3) + l] = prod[q];
  }
}

MOBMAP_TARGET_AVX2 unsigned localPlanes8(const float* points, const float sums[9 * 8], const int* counts,
                                         std::size_t first, int lanes, const float* near, const float viewpoint[3],
                                         float* normals, float* curvature, float* projected, double moments[9 * 8]) {
  unsigned done = localPlanes4(points, sums, counts, first, std::min(lanes, 4), 0, near, viewpoint, normals, curvature,
                               projected, moments);
  if (lanes > 4) {
    done |= localPlanes4(points, sums, counts, first + 4, lanes - 4, 1, near, viewpoint, normals, curvature, projected,
                         moments)
            << 4;
  }
  return done;
}

}  // namespace mobmap::perception::detail::avx2

#endif  // MOBMAP_X86_KERNELS
