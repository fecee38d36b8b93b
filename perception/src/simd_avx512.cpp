// AVX-512 versions of the hot loops. Compiled for every x86-64 build and only called
// after simdSupported(Simd::kAvx512) said yes: each function carries its own target
// attribute, so the rest of the library stays baseline x86-64.
#include "simd_kernels.hpp"

#if MOBMAP_AVX512_KERNELS

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
  count[0] = c0, count[1] = c1, count[2] = c2, count[3] = c3;
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
    _mm512_mask_compressstoreu_epi64(keys + out, take_lo, lo);
    out += static_cast<std::size_t>(__builtin_popcount(take_lo));
    _mm512_mask_compressstoreu_epi64(keys + out, take_hi, hi);
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

}  // namespace mobmap::perception::detail::avx512

#endif  // MOBMAP_AVX512_KERNELS
