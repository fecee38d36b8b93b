// AVX-512 versions of the hot loops. Compiled for every x86-64 build and only called
// after simdSupported(Simd::kAvx512) said yes: each function carries its own target
// attribute, so the rest of the library stays baseline x86-64.
#include "kernels/kernels.hpp"

#if MOBMAP_X86_KERNELS

// GCC 12's avx512fintrin.h fills the merge operand of unmasked intrinsics with a
// deliberately uninitialised value, which -Wmaybe-uninitialized reports once they are
// inlined here (GCC bug 105593, fixed in GCC 13): a false positive in the compiler's
// own header.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
#endif
#include <immintrin.h>

#include <algorithm>
#include <cstring>

#define MOBMAP_TARGET_AVX512 __attribute__((target("avx512f,avx512bw,avx512dq,avx512vl,popcnt")))

namespace mobmap::perception::detail::avx512 {
namespace {

MOBMAP_TARGET_AVX512 inline int popcount16(__mmask16 m) { return __builtin_popcount(static_cast<unsigned>(m)); }

// Ranks of NV * 8 keys by counting, for each, the keys below it: one broadcast and NV
// compares per key, all ranks accumulating in registers. Keys at rank < out are
// scattered to their place in `sorted`.
template <int NV>
MOBMAP_TARGET_AVX512 inline void rankInto(const std::uint64_t* keys, std::size_t m, std::size_t out,
                                          std::uint64_t* sorted) {
  __m512i key[NV], rank[NV];
  for (int v = 0; v < NV; ++v) {
    key[v] = _mm512_loadu_si512(keys + 8 * v);
    rank[v] = _mm512_setzero_si512();
  }
  const __m512i one = _mm512_set1_epi64(1);
  for (std::size_t j = 0; j < m; ++j) {
    const __m512i b = _mm512_set1_epi64(static_cast<long long>(keys[j]));
    for (int v = 0; v < NV; ++v) rank[v] = _mm512_mask_add_epi64(rank[v], _mm512_cmplt_epu64_mask(b, key[v]), rank[v], one);
  }
  const __m512i limit = _mm512_set1_epi64(static_cast<long long>(out));
  for (int v = 0; v < NV; ++v) {
    _mm512_mask_i64scatter_epi64(sorted, _mm512_cmplt_epu64_mask(rank[v], limit), rank[v], key[v], 8);
  }
}

}  // namespace

MOBMAP_TARGET_AVX512 void offsetSums8(const float* points, std::size_t n_points, const int* indices, std::size_t k,
                                      const int* counts, std::size_t first, int lanes, float sums[9 * 8]) {
  // v = (dx, dy, dz, 1) in each 128-bit block, loaded as one broadcast (a load, not a
  // shuffle); one permute spreads dx, dy, dz and 1 over the blocks, so the products are
  // dx*dx dy*dx dz*dx 1*dx | dx*dy dy*dy dz*dy 1*dy | dx*dz dy*dz dz*dz 1*dz | dx dy dz 1:
  // every sum (x * 1 is x, and x * y is y * x, exactly) for one permute per neighbour
  // where two were needed to line the operands up.
  const __m512i spread = _mm512_setr_epi32(0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3);
  const __m512 ones = _mm512_set1_ps(1.f);
  constexpr __mmask16 kOffsets = 0x7777;  // dx, dy, dz in every block, 1 in its last lane
  __m512 acc[8];
  __m512 centre[8];
  int c[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int most = 0;
  for (int l = 0; l < 8; ++l) {
    acc[l] = _mm512_setzero_ps();
    centre[l] = _mm512_setzero_ps();
    if (l >= lanes) continue;
    const std::size_t i = first + static_cast<std::size_t>(l);
    centre[l] = _mm512_broadcast_f32x4(_mm_maskz_loadu_ps(0x7, points + 3 * i));
    c[l] = counts[i];
    most = std::max(most, c[l]);
  }
  for (int j = 0; j < most; ++j) {
    for (int l = 0; l < 8; ++l) {
      if (j >= c[l]) continue;
      const std::size_t i = first + static_cast<std::size_t>(l);
      const auto nb = static_cast<std::size_t>(indices[i * k + static_cast<std::size_t>(j)]);
      // x, y, z and the next point's x (masked off below); the last point's three
      // coordinates alone, so that no load reads past the array.
      const __m128 xyz = nb + 1 < n_points ? _mm_loadu_ps(points + 3 * nb) : _mm_maskz_loadu_ps(0x7, points + 3 * nb);
      const __m512 v = _mm512_mask_sub_ps(ones, kOffsets, _mm512_broadcast_f32x4(xyz), centre[l]);
      acc[l] = _mm512_add_ps(acc[l], _mm512_mul_ps(v, _mm512_permutexvar_ps(spread, v)));
    }
  }
  // sx sy sz xx xy xz yy yz zz from their lanes.
  constexpr int kLane[9] = {12, 13, 14, 0, 1, 2, 5, 6, 10};
  for (int l = 0; l < lanes; ++l) {
    alignas(64) float out[16];
    _mm512_store_ps(out, acc[l]);
    for (int q = 0; q < 9; ++q) sums[8 * q + l] = out[kLane[q]];
  }
}

MOBMAP_TARGET_AVX512 void distancesAndCounts(const float* x, const float* y, const float* z, std::size_t n, float px,
                                             float py, float pz, const float limit[4], float* d2, int count[4]) {
  const __m512 vx = _mm512_set1_ps(px), vy = _mm512_set1_ps(py), vz = _mm512_set1_ps(pz);
  const __m512 l0 = _mm512_set1_ps(limit[0]), l1 = _mm512_set1_ps(limit[1]);
  const __m512 l2 = _mm512_set1_ps(limit[2]), l3 = _mm512_set1_ps(limit[3]);
  int c0 = 0, c1 = 0, c2 = 0, c3 = 0;
  for (std::size_t j = 0; j < n; j += 16) {
    const __m512 dx = _mm512_sub_ps(_mm512_loadu_ps(x + j), vx);
    const __m512 dy = _mm512_sub_ps(_mm512_loadu_ps(y + j), vy);
    const __m512 dz = _mm512_sub_ps(_mm512_loadu_ps(z + j), vz);
    const __m512 d = _mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(dx, dx), _mm512_mul_ps(dy, dy)), _mm512_mul_ps(dz, dz));
    _mm512_storeu_ps(d2 + j, d);
    // Ordered compares: NaN padding is never within a limit.
    c0 += popcount16(_mm512_cmp_ps_mask(d, l0, _CMP_LE_OQ));
    c1 += popcount16(_mm512_cmp_ps_mask(d, l1, _CMP_LE_OQ));
    c2 += popcount16(_mm512_cmp_ps_mask(d, l2, _CMP_LE_OQ));
    c3 += popcount16(_mm512_cmp_ps_mask(d, l3, _CMP_LE_OQ));
  }
  // One 16-byte store, not four: the caller reads the counts as one vector, and a load
  // that spans several pending stores cannot take its data from them (it waits until
  // every earlier store, the distances' among them, has reached the cache).
  _mm_storeu_si128(reinterpret_cast<__m128i*>(count), _mm_setr_epi32(c0, c1, c2, c3));
}

MOBMAP_TARGET_AVX512 std::size_t compactKeys(const float* d2, const int* index, std::size_t n, int self, float limit,
                                             std::uint64_t* keys) {
  const __m512 lim = _mm512_set1_ps(limit);
  const __m512i vself = _mm512_set1_epi32(self);
  std::size_t out = 0;
  for (std::size_t j = 0; j < n; j += 16) {
    const __m512i d = _mm512_castps_si512(_mm512_loadu_ps(d2 + j));
    const __m512i id = _mm512_loadu_si512(index + j);
    const __mmask16 take =
        _mm512_cmp_ps_mask(_mm512_castsi512_ps(d), lim, _CMP_LE_OQ) & _mm512_cmpneq_epi32_mask(id, vself);
    if (!take) continue;
    // (d2 bits << 32) | index, as two vectors of eight 64-bit keys.
    const __m512i lo = _mm512_or_si512(_mm512_slli_epi64(_mm512_cvtepu32_epi64(_mm512_castsi512_si256(d)), 32),
                                       _mm512_cvtepu32_epi64(_mm512_castsi512_si256(id)));
    const __m512i hi = _mm512_or_si512(_mm512_slli_epi64(_mm512_cvtepu32_epi64(_mm512_extracti64x4_epi64(d, 1)), 32),
                                       _mm512_cvtepu32_epi64(_mm512_extracti64x4_epi64(id, 1)));
    const auto take_lo = static_cast<__mmask8>(take & 0xff), take_hi = static_cast<__mmask8>(take >> 8);
    // Compressed in a register and stored whole (the lanes past the kept keys are
    // overwritten by the next store or ignored), not with a compressing store. With the
    // counts' single store above, buildKnnGraph ran 4 % faster on an Intel Sapphire
    // Rapids (samples had piled up on the first load after each kernel returned);
    // either change alone only moved the wait to the next load.
    _mm512_storeu_si512(keys + out, _mm512_maskz_compress_epi64(take_lo, lo));
    out += static_cast<std::size_t>(__builtin_popcount(take_lo));
    _mm512_storeu_si512(keys + out, _mm512_maskz_compress_epi64(take_hi, hi));
    out += static_cast<std::size_t>(__builtin_popcount(take_hi));
  }
  return out;
}

MOBMAP_TARGET_AVX512 std::size_t rankSmallest(std::uint64_t* keys, std::size_t m, std::size_t k, float* sq_dist,
                                              int* index) {
  const std::size_t vectors = (m + 7) / 8;
  for (std::size_t j = m; j < vectors * 8; ++j) keys[j] = ~0ULL;  // above every real key, never ranked in
  alignas(64) std::uint64_t sorted[kRankMaxKeys];
  const std::size_t out = std::min(k, m);
  switch (vectors) {
    case 0: return 0;
    case 1: rankInto<1>(keys, m, out, sorted); break;
    case 2: rankInto<2>(keys, m, out, sorted); break;
    case 3: rankInto<3>(keys, m, out, sorted); break;
    case 4: rankInto<4>(keys, m, out, sorted); break;
    case 5: rankInto<5>(keys, m, out, sorted); break;
    case 6: rankInto<6>(keys, m, out, sorted); break;
    case 7: rankInto<7>(keys, m, out, sorted); break;
    default: rankInto<8>(keys, m, out, sorted); break;
  }
  std::size_t j = 0;
  for (; j + 8 <= out; j += 8) {
    const __m512i v = _mm512_load_si512(sorted + j);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(index + j), _mm512_cvtepi64_epi32(v));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(sq_dist + j), _mm512_cvtepi64_epi32(_mm512_srli_epi64(v, 32)));
  }
  for (; j < out; ++j) {
    const auto bits = static_cast<std::uint32_t>(sorted[j] >> 32);
    std::memcpy(sq_dist + j, &bits, sizeof bits);
    index[j] = static_cast<int>(static_cast<std::uint32_t>(sorted[j]));
  }
  return out;
}

namespace {

// (a d + b e) + c f, lane by lane.
MOBMAP_TARGET_AVX512 inline __m512d dot3(__m512d a, __m512d b, __m512d c, __m512d d, __m512d e, __m512d f) {
  return _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(a, d), _mm512_mul_pd(b, e)), _mm512_mul_pd(c, f));
}

// Local planes of H groups of eight points (localPlanes16: H = 2). Every lane does the
// same arithmetic whatever H; the groups only share the loop of the inverse iteration,
// whose steps are a chain of a square root and a division each: two independent
// chains keep the divider busy while either waits.
template <int H>
MOBMAP_TARGET_AVX512 inline unsigned localPlanesGroups(const float* points, const float* sums, const int* counts,
                                                       std::size_t first, int lanes, const float* near,
                                                       const float viewpoint[3], float* normals, float* curvature,
                                                       float* projected, double* moments) {
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256i p3 = _mm256_mullo_epi32(lane, _mm256_set1_epi32(3));
  __mmask8 live[H], planar[H], done[H], active[H];
  __m256 px[H], py[H], pz[H];
  __m512d mx[H], my[H], mz[H], cxx[H], cxy[H], cxz[H], cyy[H], cyz[H], czz[H];
  __m512d nx[H], ny[H], nz[H], curv[H];
  for (int h = 0; h < H; ++h) {
    const int in_group = std::clamp(lanes - 8 * h, 0, 8);
    live[h] = static_cast<__mmask8>((1u << in_group) - 1u);
    const std::size_t at = first + 8 * static_cast<std::size_t>(h);
    const float* sum = sums + 72 * h;
    const __m256i count = _mm256_maskz_loadu_epi32(live[h], counts + at);
    // The points themselves (x, y, z at 3 i, 3 i + 1, 3 i + 2).
    const float* base = points + 3 * at;
    px[h] = _mm256_mmask_i32gather_ps(_mm256_setzero_ps(), live[h], p3, base, 4);
    py[h] = _mm256_mmask_i32gather_ps(_mm256_setzero_ps(), live[h], p3, base + 1, 4);
    pz[h] = _mm256_mmask_i32gather_ps(_mm256_setzero_ps(), live[h], p3, base + 2, 4);
    const __m256 sx = _mm256_loadu_ps(sum), sy = _mm256_loadu_ps(sum + 8), sz = _mm256_loadu_ps(sum + 16);
    const __m256 xx = _mm256_loadu_ps(sum + 24), xy = _mm256_loadu_ps(sum + 32), xz = _mm256_loadu_ps(sum + 40);
    const __m256 yy = _mm256_loadu_ps(sum + 48), yz = _mm256_loadu_ps(sum + 56), zz = _mm256_loadu_ps(sum + 64);
    // Moments in double (momentsOf).
    planar[h] = _mm256_mask_cmpge_epi32_mask(live[h], count, _mm256_set1_epi32(2));
    const __m512d inv_m = _mm512_div_pd(_mm512_set1_pd(1.0), _mm512_add_pd(_mm512_cvtepi32_pd(count), _mm512_set1_pd(1.0)));
    mx[h] = _mm512_mul_pd(_mm512_cvtps_pd(sx), inv_m), my[h] = _mm512_mul_pd(_mm512_cvtps_pd(sy), inv_m);
    mz[h] = _mm512_mul_pd(_mm512_cvtps_pd(sz), inv_m);
    cxx[h] = _mm512_sub_pd(_mm512_mul_pd(_mm512_cvtps_pd(xx), inv_m), _mm512_mul_pd(mx[h], mx[h]));
    cxy[h] = _mm512_sub_pd(_mm512_mul_pd(_mm512_cvtps_pd(xy), inv_m), _mm512_mul_pd(mx[h], my[h]));
    cxz[h] = _mm512_sub_pd(_mm512_mul_pd(_mm512_cvtps_pd(xz), inv_m), _mm512_mul_pd(mx[h], mz[h]));
    cyy[h] = _mm512_sub_pd(_mm512_mul_pd(_mm512_cvtps_pd(yy), inv_m), _mm512_mul_pd(my[h], my[h]));
    cyz[h] = _mm512_sub_pd(_mm512_mul_pd(_mm512_cvtps_pd(yz), inv_m), _mm512_mul_pd(my[h], mz[h]));
    czz[h] = _mm512_sub_pd(_mm512_mul_pd(_mm512_cvtps_pd(zz), inv_m), _mm512_mul_pd(mz[h], mz[h]));
    done[h] = 0;
    active[h] = 0;
    nx[h] = _mm512_setzero_pd(), ny[h] = nx[h], nz[h] = nx[h], curv[h] = _mm512_set1_pd(1.0);
  }

  // Inverse iteration from `near` (smallestEigenvectorNear), lane by lane in step.
  if (near) {
    const __m512d inf = _mm512_set1_pd(__builtin_inf());
    __m512d b00[H], b11[H], b22[H], b01[H], b02[H], b12[H], floor[H], x0[H], x1[H], x2[H];
    for (int h = 0; h < H; ++h) {
      const float* start = near + 3 * (first + 8 * static_cast<std::size_t>(h));
      const __m512d x0s = _mm512_cvtps_pd(_mm256_mmask_i32gather_ps(_mm256_setzero_ps(), planar[h], p3, start, 4));
      const __m512d x1s = _mm512_cvtps_pd(_mm256_mmask_i32gather_ps(_mm256_setzero_ps(), planar[h], p3, start + 1, 4));
      const __m512d x2s = _mm512_cvtps_pd(_mm256_mmask_i32gather_ps(_mm256_setzero_ps(), planar[h], p3, start + 2, 4));
      const __m512d start2 = dot3(x0s, x1s, x2s, x0s, x1s, x2s);
      active[h] = _mm512_mask_cmp_pd_mask(planar[h], start2, _mm512_set1_pd(0.25), _CMP_NLT_UQ);
      // adj(C), squared twice (iterationMatrix).
      b00[h] = _mm512_sub_pd(_mm512_mul_pd(cyy[h], czz[h]), _mm512_mul_pd(cyz[h], cyz[h]));
      b11[h] = _mm512_sub_pd(_mm512_mul_pd(cxx[h], czz[h]), _mm512_mul_pd(cxz[h], cxz[h]));
      b22[h] = _mm512_sub_pd(_mm512_mul_pd(cxx[h], cyy[h]), _mm512_mul_pd(cxy[h], cxy[h]));
      b01[h] = _mm512_sub_pd(_mm512_mul_pd(cxz[h], cyz[h]), _mm512_mul_pd(cxy[h], czz[h]));
      b02[h] = _mm512_sub_pd(_mm512_mul_pd(cxy[h], cyz[h]), _mm512_mul_pd(cxz[h], cyy[h]));
      b12[h] = _mm512_sub_pd(_mm512_mul_pd(cxy[h], cxz[h]), _mm512_mul_pd(cxx[h], cyz[h]));
      for (int square = 0; square < 2; ++square) {
        const __m512d j00 = b00[h], j11 = b11[h], j22 = b22[h], j01 = b01[h], j02 = b02[h], j12 = b12[h];
        b00[h] = dot3(j00, j01, j02, j00, j01, j02);
        b11[h] = dot3(j01, j11, j12, j01, j11, j12);
        b22[h] = dot3(j02, j12, j22, j02, j12, j22);
        b01[h] = dot3(j00, j01, j02, j01, j11, j12);
        b02[h] = dot3(j00, j01, j02, j02, j12, j22);
        b12[h] = dot3(j01, j11, j12, j02, j12, j22);
      }
      const __m512d scale = _mm512_max_pd(_mm512_max_pd(_mm512_max_pd(_mm512_abs_pd(b00[h]), _mm512_abs_pd(b11[h])),
                                                        _mm512_max_pd(_mm512_abs_pd(b22[h]), _mm512_abs_pd(b01[h]))),
                                          _mm512_max_pd(_mm512_abs_pd(b02[h]), _mm512_abs_pd(b12[h])));
      floor[h] = _mm512_mul_pd(_mm512_set1_pd(1e-30), scale);
      x0[h] = x0s, x1[h] = x1s, x2[h] = x2s;
    }
    const auto anyActive = [&]() {
      unsigned any = 0;
      for (int h = 0; h < H; ++h) any |= active[h];
      return any != 0;
    };
    for (int step = 0; step < 8 && anyActive(); ++step) {
      for (int h = 0; h < H; ++h) {
        if (!active[h]) continue;
        const __m512d y0 = dot3(b00[h], b01[h], b02[h], x0[h], x1[h], x2[h]);
        const __m512d y1 = dot3(b01[h], b11[h], b12[h], x0[h], x1[h], x2[h]);
        const __m512d y2 = _mm512_add_pd(_mm512_mul_pd(b02[h], x0[h]), _mm512_add_pd(_mm512_mul_pd(b12[h], x1[h]), _mm512_mul_pd(b22[h], x2[h])));
        const __m512d norm = _mm512_sqrt_pd(dot3(y0, y1, y2, y0, y1, y2));
        // !(norm > floor) || !isfinite(norm): such lanes go to the exact solver.
        active[h] = _mm512_mask_cmp_pd_mask(active[h], norm, floor[h], _CMP_GT_OQ) & _mm512_cmp_pd_mask(norm, inf, _CMP_LT_OQ);
        const __m512d inv = _mm512_div_pd(_mm512_set1_pd(1.0), norm);
        const __m512d n0 = _mm512_mul_pd(y0, inv), n1 = _mm512_mul_pd(y1, inv), n2 = _mm512_mul_pd(y2, inv);
        const __m512d d0 = _mm512_sub_pd(n0, x0[h]), d1 = _mm512_sub_pd(n1, x1[h]), d2 = _mm512_sub_pd(n2, x2[h]);
        const __m512d moved2 = dot3(d0, d1, d2, d0, d1, d2);
        x0[h] = _mm512_mask_mov_pd(x0[h], active[h], n0), x1[h] = _mm512_mask_mov_pd(x1[h], active[h], n1);
        x2[h] = _mm512_mask_mov_pd(x2[h], active[h], n2);
        const __mmask8 converged = _mm512_mask_cmp_pd_mask(active[h], moved2, _mm512_set1_pd(kStepUnder1e5Squared), _CMP_LE_OQ);
        if (converged) {
          const __m512d total = _mm512_add_pd(cxx[h], _mm512_add_pd(cyy[h], czz[h]));
          const __m512d cx0 = dot3(cxx[h], cxy[h], cxz[h], x0[h], x1[h], x2[h]);
          const __m512d cx1 = dot3(cxy[h], cyy[h], cyz[h], x0[h], x1[h], x2[h]);
          const __m512d cx2 = _mm512_add_pd(_mm512_mul_pd(cxz[h], x0[h]), _mm512_add_pd(_mm512_mul_pd(cyz[h], x1[h]), _mm512_mul_pd(czz[h], x2[h])));
          const __m512d rayleigh = dot3(x0[h], x1[h], x2[h], cx0, cx1, cx2);
          // std::max(0.0, v): 0 unless 0 < v (so a NaN gives 0), as vmaxpd(v, 0) does.
          const __m512d lambda0 = _mm512_max_pd(rayleigh, _mm512_setzero_pd());
          const __mmask8 plane = _mm512_mask_cmp_pd_mask(converged, total, _mm512_setzero_pd(), _CMP_GT_OQ) &
                                 _mm512_cmp_pd_mask(lambda0, _mm512_mul_pd(_mm512_set1_pd(0.25), total), _CMP_NGT_UQ);
          nx[h] = _mm512_mask_mov_pd(nx[h], plane, x0[h]), ny[h] = _mm512_mask_mov_pd(ny[h], plane, x1[h]);
          nz[h] = _mm512_mask_mov_pd(nz[h], plane, x2[h]);
          curv[h] = _mm512_mask_mov_pd(curv[h], plane, _mm512_div_pd(lambda0, total));
          done[h] |= plane;
          active[h] &= static_cast<__mmask8>(~converged);
        }
      }
    }
  }

  unsigned result = 0;
  for (int h = 0; h < H; ++h) {
    // Lanes with under 2 neighbours keep what the caller set (zero normal, curvature 1,
    // the point itself).
    const auto few = static_cast<__mmask8>(live[h] & ~planar[h]);
    alignas(32) float out_n[3][8], out_c[8], out_p[3][8];
    if (done[h]) {
      // orientedNormal: turned towards the viewpoint, then normalised, in single precision.
      const __m512d vx = _mm512_cvtps_pd(_mm256_sub_ps(_mm256_set1_ps(viewpoint[0]), px[h]));
      const __m512d vy = _mm512_cvtps_pd(_mm256_sub_ps(_mm256_set1_ps(viewpoint[1]), py[h]));
      const __m512d vz = _mm512_cvtps_pd(_mm256_sub_ps(_mm256_set1_ps(viewpoint[2]), pz[h]));
      const __m512d facing = dot3(nx[h], ny[h], nz[h], vx, vy, vz);
      const __mmask8 away = _mm512_cmp_pd_mask(facing, _mm512_setzero_pd(), _CMP_LT_OQ);
      const __m512d sign = _mm512_mask_mov_pd(_mm512_set1_pd(1.0), away, _mm512_set1_pd(-1.0));
      const __m512d ox = _mm512_mul_pd(nx[h], sign), oy = _mm512_mul_pd(ny[h], sign), oz = _mm512_mul_pd(nz[h], sign);
      const __m512d len = _mm512_sqrt_pd(dot3(ox, oy, oz, ox, oy, oz));
      _mm256_store_ps(out_n[0], _mm512_cvtpd_ps(_mm512_div_pd(ox, len)));
      _mm256_store_ps(out_n[1], _mm512_cvtpd_ps(_mm512_div_pd(oy, len)));
      _mm256_store_ps(out_n[2], _mm512_cvtpd_ps(_mm512_div_pd(oz, len)));
      _mm256_store_ps(out_c, _mm512_cvtpd_ps(curv[h]));
      // projectedPoint, with the unturned normal.
      const __m512d t = dot3(nx[h], ny[h], nz[h], mx[h], my[h], mz[h]);
      _mm256_store_ps(out_p[0], _mm512_cvtpd_ps(_mm512_add_pd(_mm512_cvtps_pd(px[h]), _mm512_mul_pd(nx[h], t))));
      _mm256_store_ps(out_p[1], _mm512_cvtpd_ps(_mm512_add_pd(_mm512_cvtps_pd(py[h]), _mm512_mul_pd(ny[h], t))));
      _mm256_store_ps(out_p[2], _mm512_cvtpd_ps(_mm512_add_pd(_mm512_cvtps_pd(pz[h]), _mm512_mul_pd(nz[h], t))));
    }
    const int in_group = std::clamp(lanes - 8 * h, 0, 8);
    storeDoneLanes(done[h], in_group, first + 8 * static_cast<std::size_t>(h), out_n, out_c, out_p, normals, curvature,
                   projected);
    const __m512d fields[9] = {mx[h], my[h], mz[h], cxx[h], cxy[h], cxz[h], cyy[h], cyz[h], czz[h]};
    for (int q = 0; q < 9; ++q) _mm512_storeu_pd(moments + 72 * h + 8 * q, fields[q]);
    result |= static_cast<unsigned>(done[h] | few) << (8 * h);
  }
  return result;
}

}  // namespace

MOBMAP_TARGET_AVX512 unsigned localPlanes16(const float* points, const float sums[2 * 9 * 8], const int* counts,
                                            std::size_t first, int lanes, const float* near, const float viewpoint[3],
                                            float* normals, float* curvature, float* projected,
                                            double moments[2 * 9 * 8]) {
  return localPlanesGroups<2>(points, sums, counts, first, lanes, near, viewpoint, normals, curvature, projected,
                              moments);
}

MOBMAP_TARGET_AVX512 std::size_t cellKeys(const float* xyz, std::size_t n, float inv_cell, std::uint64_t* keys) {
  // Coordinate `axis` of point q is float 3 q + axis of the 48 in a, b, c: the two-source
  // permute takes those below 32 from a and b, a second permute the rest from c.
  const __m512i stride3 = _mm512_setr_epi32(0, 3, 6, 9, 12, 15, 18, 21, 24, 27, 30, 33, 36, 39, 42, 45);
  const __m512 inv = _mm512_set1_ps(inv_cell);
  const __m512i offset = _mm512_set1_epi64(1 << 20);
  std::size_t i = 0;
  for (; i + 16 <= n; i += 16) {
    const float* p = xyz + 3 * i;
    const __m512 a = _mm512_loadu_ps(p), b = _mm512_loadu_ps(p + 16), c = _mm512_loadu_ps(p + 32);
    __m512i lo[3], hi[3];
    for (int axis = 0; axis < 3; ++axis) {
      const __m512i at = _mm512_add_epi32(stride3, _mm512_set1_epi32(axis));
      const __mmask16 in_c = _mm512_cmpge_epi32_mask(at, _mm512_set1_epi32(32));
      const __m512 v = _mm512_mask_permutexvar_ps(_mm512_permutex2var_ps(a, at, b), in_c,
                                                  _mm512_sub_epi32(at, _mm512_set1_epi32(32)), c);
      // floor(v * inv) as an integer: the conversion itself rounds down, exactly.
      const __m512i cell = _mm512_cvt_roundps_epi32(_mm512_mul_ps(v, inv), _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
      lo[axis] = _mm512_add_epi64(_mm512_cvtepi32_epi64(_mm512_castsi512_si256(cell)), offset);
      hi[axis] = _mm512_add_epi64(_mm512_cvtepi32_epi64(_mm512_extracti64x4_epi64(cell, 1)), offset);
    }
    _mm512_storeu_si512(keys + i, _mm512_or_si512(_mm512_or_si512(_mm512_slli_epi64(lo[0], 42), _mm512_slli_epi64(lo[1], 21)), lo[2]));
    _mm512_storeu_si512(keys + i + 8, _mm512_or_si512(_mm512_or_si512(_mm512_slli_epi64(hi[0], 42), _mm512_slli_epi64(hi[1], 21)), hi[2]));
  }
  return i;
}

MOBMAP_TARGET_AVX512 std::size_t planeInliers(const float* x, const float* y, const float* z, const float* nx,
                                              const float* ny, const float* nz, std::size_t m, const float plane[4],
                                              float dist, float cos_normal, std::uint64_t* bits) {
  const __m512 a = _mm512_set1_ps(plane[0]), b = _mm512_set1_ps(plane[1]), c = _mm512_set1_ps(plane[2]);
  const __m512 d = _mm512_set1_ps(plane[3]), limit = _mm512_set1_ps(dist), cosine = _mm512_set1_ps(cos_normal);
  std::size_t total = 0;
  for (std::size_t w = 0; 64 * w < m; ++w) {
    std::uint64_t word = 0;
    for (std::size_t q = 0; q < 4; ++q) {
      const std::size_t j = 64 * w + 16 * q;
      if (j >= m) break;
      const auto live = static_cast<__mmask16>(m - j >= 16 ? 0xFFFFu : (1u << (m - j)) - 1u);
      // |(a x + (b y + c z)) + d| not above the distance: not greater, or NaN.
      const __m512 t = _mm512_add_ps(
          _mm512_add_ps(_mm512_mul_ps(a, _mm512_maskz_loadu_ps(live, x + j)),
                        _mm512_add_ps(_mm512_mul_ps(b, _mm512_maskz_loadu_ps(live, y + j)),
                                      _mm512_mul_ps(c, _mm512_maskz_loadu_ps(live, z + j)))),
          d);
      __mmask16 in = _mm512_mask_cmp_ps_mask(live, _mm512_abs_ps(t), limit, _CMP_NGT_UQ);
      if (nx) {
        // |a nx + (b ny + c nz)| not below the cosine: not less, or NaN.
        const __m512 u = _mm512_add_ps(_mm512_mul_ps(a, _mm512_maskz_loadu_ps(live, nx + j)),
                                       _mm512_add_ps(_mm512_mul_ps(b, _mm512_maskz_loadu_ps(live, ny + j)),
                                                     _mm512_mul_ps(c, _mm512_maskz_loadu_ps(live, nz + j))));
        in = _mm512_mask_cmp_ps_mask(in, _mm512_abs_ps(u), cosine, _CMP_NLT_UQ);
      }
      word |= static_cast<std::uint64_t>(in) << (16 * q);
    }
    total += static_cast<std::size_t>(__builtin_popcountll(word));
    if (bits) bits[w] = word;
  }
  return total;
}

}  // namespace mobmap::perception::detail::avx512

#endif  // MOBMAP_X86_KERNELS
