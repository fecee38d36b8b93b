#pragma once
// Vector kernels of the hot loops (internal). Each does exactly the floating-point
// operations of its portable counterpart, in the same order, so results are
// bit-identical; callers choose through mobmap::perception::Simd.

#include <cstddef>
#include <cstdint>

#if (defined(__x86_64__) || defined(_M_X64)) && (defined(__GNUC__) || defined(__clang__))
#define MOBMAP_X86_KERNELS 1
#else
#define MOBMAP_X86_KERNELS 0
#endif

namespace mobmap::perception::detail {

/// rankSmallest takes at most this many keys. A key is a k-nearest candidate as one
/// 64-bit number: the squared distance's bit pattern (monotone for non-negative
/// floats) above the point index, so keys order by (distance, index) and are distinct.
inline constexpr std::size_t kRankMaxKeys = 64;

/// The inverse iteration's convergence test (kernels/local_plane.hpp), a step of under 1e-5:
/// the largest double s with sqrt(s) < 1e-5, two units in the last place below the
/// rounded 1e-5 * 1e-5. Square roots are correctly rounded and monotone, so for s >= 0
/// "s <= this" is exactly "sqrt(s) < 1e-5", without the square root the next step
/// would wait for. (Found by stepping nextafter from 1e-5 * 1e-5; the normals are
/// bit-identical to those of the square-root test.)
inline constexpr double kStepUnder1e5Squared = 0x1.b7cdfd9d7bdbap-34;

#if MOBMAP_X86_KERNELS
/// The local-plane kernels' last step, for a group of eight: for each lane l < lanes
/// whose bit is set in `done`, copies its normal (out_n[axis][l]), curvature and, if
/// `projected` is not null, projected point to point first + l of the output arrays.
inline void storeDoneLanes(unsigned done, int lanes, std::size_t first, const float out_n[3][8],
                           const float out_c[8], const float out_p[3][8], float* normals, float* curvature,
                           float* projected) {
  for (int l = 0; l < lanes; ++l) {
    if (!(done >> l & 1u)) continue;
    const std::size_t i = first + static_cast<std::size_t>(l);
    for (int a = 0; a < 3; ++a) normals[3 * i + static_cast<std::size_t>(a)] = out_n[a][l];
    curvature[i] = out_c[l];
    if (projected) {
      for (int a = 0; a < 3; ++a) projected[3 * i + static_cast<std::size_t>(a)] = out_p[a][l];
    }
  }
}

namespace avx512 {

/// Block of candidate points as structure of arrays, padded with NaN coordinates (and
/// index -1) to a multiple of 16; `n` is the padded length.
/// Writes the squared distance of every block point to (px, py, pz) into d2 (computed
/// as dx*dx + dy*dy + dz*dz, left to right) and, for q < 4, the number of block points
/// with d2 <= limit[q] into count[q] (NaN padding is never counted).
void distancesAndCounts(const float* x, const float* y, const float* z, std::size_t n, float px, float py, float pz,
                        const float limit[4], float* d2, int count[4]);

/// Appends to `keys` the keys of the block points with d2 <= limit whose index is not
/// `self`, in block order; returns how many. `keys` needs room for n entries.
std::size_t compactKeys(const float* d2, const int* index, std::size_t n, int self, float limit, std::uint64_t* keys);

/// The min(k, m) smallest of m <= kRankMaxKeys distinct keys, ascending, unpacked into
/// squared distances and indices. Each key's rank is the number of smaller keys;
/// `keys` needs room for m rounded up to a multiple of 8 (the tail is overwritten).
std::size_t rankSmallest(std::uint64_t* keys, std::size_t m, std::size_t k, float* sq_dist, int* index);

/// The OffsetSums of points first .. first + lanes - 1 (lanes <= 8) over their first
/// counts[i] neighbours (indices[i * k ..]), into sums[q * 8 + lane] (fields in
/// declaration order), as sumOffsets computes them: one vector holds a point's nine
/// sums, so each neighbour is one subtract, one multiply and one add in the same order
/// as the scalar loop; the eight points' chains are interleaved. `n_points` is the
/// number of points (x, y, z triples) in `points`, so that no load reads past the last.
void offsetSums8(const float* points, std::size_t n_points, const int* indices, std::size_t k, const int* counts,
                 std::size_t first, int lanes, float sums[9 * 8]);

/// The packed cell keys (spatial_hash.hpp's cellKey of floorToInt(coordinate *
/// inv_cell) per axis) of the first points of `xyz` (x, y, z per point), 16 at a time;
/// returns how many it did (n rounded down to a multiple of 16), the rest is the
/// caller's. Same bits as the scalar code: one product per coordinate, rounded down
/// exactly, then the same integer operations.
std::size_t cellKeys(const float* xyz, std::size_t n, float inv_cell, std::uint64_t* keys);

/// Local planes of the points first .. first + lanes - 1 (lanes <= 16), as
/// estimateNormals computes them with the arithmetic of local_plane.hpp, in two groups
/// of eight (group g: points first + 8 g ..), from their OffsetSums (sums[72 g + q * 8 +
/// lane], fields in declaration order: sx, sy, sz, xx, xy, xz, yy, yz, zz) and
/// neighbour counts. `points` is x, y, z per point; `near` (the same) is null for the
/// closed-form solver, whose lanes this leaves to the caller. For each lane done,
/// writes normal (x, y, z, turned towards `viewpoint`), curvature and, if `projected`
/// is not null, the projected point. Returns the mask of lanes done (group g at bits
/// 8 g .. 8 g + 7); for the others with at least 2 neighbours, moments[72 g + q * 8 +
/// lane] holds the LocalMoments fields in declaration order (mx, my, mz, xx, xy, xz,
/// yy, yz, zz) for the exact solver. Lanes with under 2 neighbours count as done and
/// are not written: the caller has set them (zero normal, curvature 1, projected =
/// point). The two groups' inverse iterations run side by side, each hiding the other's
/// waits on the square root and the division. Gathering the neighbours is left to
/// scalar code: on AMD cores a gather fetches about one element per cycle, no faster
/// than the scalar loads it replaces.
unsigned localPlanes16(const float* points, const float sums[2 * 9 * 8], const int* counts, std::size_t first,
                       int lanes, const float* near, const float viewpoint[3], float* normals, float* curvature,
                       float* projected, double moments[2 * 9 * 8]);
/// The inliers of the plane a x + b y + c z + d = 0 (plane = a, b, c, d) among m
/// points given as coordinate arrays: |(a x + (b y + c z)) + d| not above `dist` and,
/// if nx is not null, |a nx + (b ny + c nz)| not below `cos_normal` (NaN passes both,
/// as in ransacPlane's portable test). Returns their number; if `bits` is not null,
/// sets bit j % 64 of bits[j / 64] for each inlier j and clears the others (all
/// (m + 63) / 64 words are written). Sixteen points per vector.
std::size_t planeInliers(const float* x, const float* y, const float* z, const float* nx, const float* ny,
                         const float* nz, std::size_t m, const float plane[4], float dist, float cos_normal,
                         std::uint64_t* bits);

}  // namespace avx512

/// The same functions, with the same contracts and results, in AVX2 (kernels/avx2.cpp):
/// eight floats or four 64-bit keys per vector, masks as vectors. rankSmallest ranks
/// the keys' distance bits as signed 32-bit integers, eight per vector, and the whole
/// keys as signed 64-bit ones, four per vector, when two distances are equal (both
/// order as the unsigned keys do: a squared distance's sign bit is 0).
namespace avx2 {

void distancesAndCounts(const float* x, const float* y, const float* z, std::size_t n, float px, float py, float pz,
                        const float limit[4], float* d2, int count[4]);
std::size_t compactKeys(const float* d2, const int* index, std::size_t n, int self, float limit, std::uint64_t* keys);
std::size_t rankSmallest(std::uint64_t* keys, std::size_t m, std::size_t k, float* sq_dist, int* index);
/// As avx512::cellKeys, 8 points at a time.
std::size_t cellKeys(const float* xyz, std::size_t n, float inv_cell, std::uint64_t* keys);
/// As avx512::offsetSums8.
void offsetSums8(const float* points, std::size_t n_points, const int* indices, std::size_t k, const int* counts,
                 std::size_t first, int lanes, float sums[9 * 8]);
/// As avx512::localPlanes16 with one group of eight (lanes <= 8).
unsigned localPlanes8(const float* points, const float sums[9 * 8], const int* counts, std::size_t first, int lanes,
                      const float* near, const float viewpoint[3], float* normals, float* curvature, float* projected,
                      double moments[9 * 8]);
/// As avx512::planeInliers, eight points per vector.
std::size_t planeInliers(const float* x, const float* y, const float* z, const float* nx, const float* ny,
                         const float* nz, std::size_t m, const float plane[4], float dist, float cos_normal,
                         std::uint64_t* bits);

}  // namespace avx2
#endif

}  // namespace mobmap::perception::detail
