#include "mobmap/perception/stages.hpp"

#include "kernels/local_plane.hpp"
#include "kernels/kernels.hpp"
#include "kernels/spatial_hash.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <limits>
#include <stdexcept>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace mobmap::perception {
namespace {

// Calls f(neighbour index) for the graph neighbours of point i closer than
// sqrt(max_d2). Rows are sorted by distance (neighbours.hpp), so the scan stops at the
// first one beyond.
template <typename F>
void forNeighboursWithin(const KnnGraph& g, std::size_t i, float max_d2, F&& f) {
  const std::size_t base = i * static_cast<std::size_t>(g.k);
  for (int j = 0; j < g.count[i]; ++j) {
    const std::size_t e = base + static_cast<std::size_t>(j);
    if (g.sq_dist[e] > max_d2) break;
    f(static_cast<std::size_t>(g.indices[e]));
  }
}

// Asks for the graph row of points[pos], if the list reaches that far, ahead of the
// scan that will read it: breadth-first searches and orphan lists jump between rows in
// ways the hardware prefetcher cannot predict.
inline void prefetchRow(const KnnGraph& g, const std::vector<int>& points, std::size_t pos) {
  if (pos >= points.size()) return;
  const std::size_t base = static_cast<std::size_t>(points[pos]) * static_cast<std::size_t>(g.k);
  __builtin_prefetch(g.sq_dist.data() + base);
  __builtin_prefetch(g.indices.data() + base);
}

// Sum of the outer products d * d^T of a sequence of vectors: its six distinct entries,
// each summed in the order of the sequence, so the matrix is the one summing the full
// products gives, to the bit, for 2/3 of the work.
struct OuterSum {
  double xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0;
  void add(const Eigen::Vector3d& d) {
    xx += d.x() * d.x();
    xy += d.x() * d.y();
    xz += d.x() * d.z();
    yy += d.y() * d.y();
    yz += d.y() * d.z();
    zz += d.z() * d.z();
  }
  [[nodiscard]] Eigen::Matrix3d matrix() const {
    Eigen::Matrix3d m;
    m << xx, xy, xz, xy, yy, yz, xz, yz, zz;
    return m;
  }
};

}  // namespace

std::vector<Eigen::Vector3f> voxelReduce(const std::vector<Eigen::Vector3f>& points, float voxel_m,
                                         std::vector<int>* voxel_of_point) {
  if (!(voxel_m > 0.f)) throw std::invalid_argument("voxelReduce: voxel size must be > 0");
  const Simd simd = activeSimd();
  const float inv = 1.f / voxel_m;
  const std::size_t n = points.size();
  // The table lives on in this thread from frame to frame (~4 MB for a VGA frame), so
  // that it need not be cleared each time (reset() only starts a new fill).
  thread_local detail::CellHash index(0);
  index.reset(n / 4 + 16);
  std::vector<Eigen::Vector3d> sums;  // double: sums of many points stay exact enough
  std::vector<int> counts;
  if (voxel_of_point) voxel_of_point->resize(n);
  // Keys first, so that each lookup can prefetch a later one's slot (reduction stage
  // 5.9 -> 3.9 ms per real frame).
  const std::vector<std::uint64_t> keys = detail::cellKeys(points, inv, simd);
  // A run of equal keys (neighbouring pixels of an image in one voxel: ~270k points
  // make ~130k runs on a Kinect frame) shares one lookup, and its points are added in
  // order, as one at a time would add them, with the sum in registers instead of a
  // store and a load per point.
  std::size_t i = 0;
  while (i < n) {
    const std::uint64_t key = keys[i];
    int& slot = index.slotAhead(keys, i);
    if (slot < 0) {
      slot = static_cast<int>(sums.size());
      sums.emplace_back(Eigen::Vector3d::Zero());
      counts.push_back(0);
    }
    const int v = slot;
    const auto vs = static_cast<std::size_t>(v);
    Eigen::Vector3d acc = sums[vs];
    std::size_t j = i;
    do {
      acc += points[j].cast<double>();
      if (voxel_of_point) (*voxel_of_point)[j] = v;
      ++j;
    } while (j < n && keys[j] == key);
    sums[vs] = acc;
    counts[vs] += static_cast<int>(j - i);
    i = j;
  }
  std::vector<Eigen::Vector3f> out(sums.size());
  for (std::size_t v = 0; v < sums.size(); ++v) out[v] = (sums[v] / counts[v]).cast<float>();
  return out;
}

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

namespace detail {

void smallestEigenvectorExact(const LocalMoments& c, double normal[3], float& curvature) {
  Eigen::Matrix3d cov;
  cov << c.xx, c.xy, c.xz, c.xy, c.yy, c.yz, c.xz, c.yz, c.zz;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(cov);
  for (int r = 0; r < 3; ++r) normal[r] = es.eigenvectors()(r, 0);
  const double total = es.eigenvalues().sum();
  curvature = total > 0 ? static_cast<float>(std::max(0.0, es.eigenvalues()(0)) / total) : 0.f;
}

}  // namespace detail

namespace {

// The offset sums of point i over its first c graph neighbours.
detail::OffsetSums rowOffsets(const std::vector<Eigen::Vector3f>& points, const KnnGraph& g, std::size_t i, int c) {
  return detail::sumOffsets(points.data(), i, &g.indices[i * static_cast<std::size_t>(g.k)], c);
}

}  // namespace

void estimateNormals(const std::vector<Eigen::Vector3f>& points, const KnnGraph& g, const Eigen::Vector3f& viewpoint,
                     std::vector<Eigen::Vector3f>& normals, std::vector<float>& curvature,
                     std::vector<Eigen::Vector3f>* projected, const std::vector<Eigen::Vector3f>* near) {
  const std::size_t n = points.size();
  if (near && near->size() != n) throw std::invalid_argument("estimateNormals: `near` size differs from points");
  if (g.count.size() != n) throw std::invalid_argument("estimateNormals: graph and points sizes differ");
  const Simd simd = activeSimd();
  normals.assign(n, Eigen::Vector3f::Zero());
  curvature.assign(n, 1.f);
  if (projected) *projected = points;
#if MOBMAP_X86_KERNELS
  if (simd == Simd::kAvx512 || simd == Simd::kAvx2) {
    // Eight points at a time; the lanes the kernel leaves (the closed-form solver) are
    // finished here with the same arithmetic as the portable loop below.
    static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float), "points are read as x, y, z triples");
    // (Cast, not ->data(): an empty vector's data() may be null.)
    const auto* xyz = reinterpret_cast<const float*>(points.data());
    const auto* start = near ? reinterpret_cast<const float*>(near->data()) : nullptr;
    auto* proj = projected ? reinterpret_cast<float*>(projected->data()) : nullptr;
    auto* normal_xyz = reinterpret_cast<float*>(normals.data());
    const auto k = static_cast<std::size_t>(g.k);
    // Sixteen at a time with AVX-512 (two groups of eight whose eigenvector iterations
    // overlap), eight with AVX2.
    double moments[2 * 9 * 8] = {};
    float sums[2 * 9 * 8] = {};
    const std::size_t group = simd == Simd::kAvx512 ? 16 : 8;
    for (std::size_t first = 0; first < n; first += group) {
      const int lanes = static_cast<int>(std::min(group, n - first));
      unsigned done = 0;
      if (simd == Simd::kAvx512) {
        detail::avx512::offsetSums8(xyz, n, g.indices.data(), k, g.count.data(), first, std::min(lanes, 8), sums);
        if (lanes > 8) {
          detail::avx512::offsetSums8(xyz, n, g.indices.data(), k, g.count.data(), first + 8, lanes - 8, sums + 72);
        }
        done = detail::avx512::localPlanes16(xyz, sums, g.count.data(), first, lanes, start, viewpoint.data(),
                                             normal_xyz, curvature.data(), proj, moments);
      } else {
        detail::avx2::offsetSums8(xyz, n, g.indices.data(), k, g.count.data(), first, lanes, sums);
        done = detail::avx2::localPlanes8(xyz, sums, g.count.data(), first, lanes, start, viewpoint.data(),
                                          normal_xyz, curvature.data(), proj, moments);
      }
      for (int l = 0; l < lanes; ++l) {
        if (done >> l & 1u) continue;
        const std::size_t i = first + static_cast<std::size_t>(l);
        detail::LocalMoments m;
        double* fields[9] = {&m.mx, &m.my, &m.mz, &m.xx, &m.xy, &m.xz, &m.yy, &m.yz, &m.zz};
        for (int q = 0; q < 9; ++q) *fields[q] = moments[72 * (l / 8) + 8 * q + l % 8];
        double normal[3];
        detail::smallestEigenvectorExact(m, normal, curvature[i]);
        normals[i] = detail::orientedNormal(normal, points[i], viewpoint);
        if (projected) (*projected)[i] = detail::projectedPoint(normal, m, points[i]);
      }
    }
    return;
  }
#endif
  for (std::size_t i = 0; i < n; ++i) {
    const int c = g.count[i];
    if (c < 2) continue;  // with the point itself, 3 points make a plane
    const detail::LocalMoments m = detail::momentsOf(rowOffsets(points, g, i, c), c);
    double normal[3];
    bool done = false;
    if (near) {
      const double start[3] = {(*near)[i].x(), (*near)[i].y(), (*near)[i].z()};
      done = detail::smallestEigenvectorNear(m, start, normal, curvature[i]);
    }
    if (!done) detail::smallestEigenvectorExact(m, normal, curvature[i]);
    normals[i] = detail::orientedNormal(normal, points[i], viewpoint);
    if (projected) (*projected)[i] = detail::projectedPoint(normal, m, points[i]);
  }
}

void projectOntoLocalPlanes(const std::vector<Eigen::Vector3f>& points, const KnnGraph& g, int max_neighbours,
                            const std::vector<int>& which, std::vector<Eigen::Vector3f>& projected) {
  if (projected.size() != points.size() || g.count.size() != points.size()) {
    throw std::invalid_argument("projectOntoLocalPlanes: graph, points and output sizes differ");
  }
  for (int idx : which) {
    const auto i = static_cast<std::size_t>(idx);
    const int c = std::min(g.count[i], max_neighbours);
    if (c < 2) continue;
    const detail::LocalMoments m = detail::momentsOf(rowOffsets(points, g, i, c), c);
    double normal[3];
    float unused = 0.f;
    detail::smallestEigenvectorExact(m, normal, unused);
    projected[i] = detail::projectedPoint(normal, m, points[i]);
  }
}

namespace {

// std::lround(x) cast to 8 bits for x in [0, 255] (and NaN), inline: the library call
// was ~0.4 % of a `mobmap build`. x - trunc(x) is exact there; checked equal to lround
// on every float from 0 to 255.
inline std::uint8_t roundColour(float x) {
  if (!(x >= 0.f)) return 0;  // NaN: lround's LONG_MIN, whose low byte is 0
  const int t = static_cast<int>(x);
  return static_cast<std::uint8_t>(t + (x - static_cast<float>(t) >= 0.5f));
}

}  // namespace

std::vector<std::array<std::uint8_t, 3>> normalColours(const std::vector<Eigen::Vector3f>& normals) {
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  Eigen::Vector3f hi = -lo;
  for (const auto& nrm : normals) {
    if (nrm.isZero()) continue;
    lo = lo.cwiseMin(nrm);
    hi = hi.cwiseMax(nrm);
  }
  std::vector<std::array<std::uint8_t, 3>> out(normals.size(), {0, 0, 0});
  for (std::size_t i = 0; i < normals.size(); ++i) {
    if (normals[i].isZero()) continue;
    for (int c = 0; c < 3; ++c) {
      const float range = hi(c) - lo(c);
      const float t = range > 1e-6f ? (normals[i](c) - lo(c)) / range : 0.5f;  // eq. 5
      out[i][static_cast<std::size_t>(c)] = roundColour(255.f * std::clamp(t, 0.f, 1.f));
    }
  }
  return out;
}

Eigen::Vector3f rgbToYCrCb(const std::array<std::uint8_t, 3>& rgb) {
  const float r = rgb[0], g = rgb[1], b = rgb[2];
  const float y = 0.299f * r + 0.587f * g + 0.114f * b;
  return {y, 128.f + 0.713f * (r - y), 128.f + 0.564f * (b - y)};
}

Eigen::Vector4f leastSquaresPlane(const std::vector<Eigen::Vector3f>& points, const std::vector<int>& idx, double* rms) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int i : idx) mean += points[static_cast<std::size_t>(i)].cast<double>();
  mean /= static_cast<double>(std::max<std::size_t>(1, idx.size()));
  OuterSum cov;
  for (int i : idx) cov.add(points[static_cast<std::size_t>(i)].cast<double>() - mean);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(cov.matrix() / static_cast<double>(std::max<std::size_t>(1, idx.size())));
  const Eigen::Vector3d n = es.eigenvectors().col(0).normalized();
  if (rms) *rms = std::sqrt(std::max(0.0, es.eigenvalues()(0)));
  Eigen::Vector4f plane;
  plane << n.cast<float>(), static_cast<float>(-n.dot(mean));
  return plane;
}

namespace {

// Candidates of a RANSAC search with their coordinates (and normals) side by side, so
// that judging a plane is one pass over arrays, 16 or 8 points per vector with
// AVX-512 or AVX2 (the portable loop is vectorised by the compiler, four per vector).
// A point is an inlier of n.x + d = 0 exactly as before: |(n.p) + d| not above the
// distance (n.p summed as Eigen's dot does, x + (y + z)) and, with normals, |n.normal|
// not below the cosine (as a float: below the smallest float >= the double cosine is
// below it).
class InlierTest {
 public:
  InlierTest(const std::vector<Eigen::Vector3f>& points, const std::vector<int>& ids,
             const std::vector<Eigen::Vector3f>* normals, float dist, double cos_normal, Simd simd)
      : ids_(ids), normals_(normals != nullptr), simd_(simd), dist_(dist) {
    const std::size_t m = ids.size();
    x_.resize(m), y_.resize(m), z_.resize(m);
    for (std::size_t j = 0; j < m; ++j) {
      const Eigen::Vector3f& p = points[static_cast<std::size_t>(ids[j])];
      x_[j] = p.x(), y_[j] = p.y(), z_[j] = p.z();
    }
    if (normals_) {
      nx_.resize(m), ny_.resize(m), nz_.resize(m);
      for (std::size_t j = 0; j < m; ++j) {
        const Eigen::Vector3f& q = (*normals)[static_cast<std::size_t>(ids[j])];
        nx_[j] = q.x(), ny_[j] = q.y(), nz_[j] = q.z();
      }
      cos_ = static_cast<float>(cos_normal);
      if (static_cast<double>(cos_) < cos_normal) cos_ = std::nextafter(cos_, std::numeric_limits<float>::infinity());
    }
  }
  [[nodiscard]] std::size_t count(const Eigen::Vector4f& pl) const {
#if MOBMAP_X86_KERNELS
    if (simd_ != Simd::kPortable) return vectorInliers(pl, nullptr);
#endif
    std::size_t n = 0;
    if (normals_) {
      for (std::size_t j = 0; j < x_.size(); ++j) n += static_cast<std::size_t>(near(pl, j) & facing(pl, j));
    } else {
      for (std::size_t j = 0; j < x_.size(); ++j) n += static_cast<std::size_t>(near(pl, j));
    }
    return n;
  }
  // The inliers' ids, in candidate order.
  void collect(const Eigen::Vector4f& pl, std::vector<int>& out) const {
    out.clear();
#if MOBMAP_X86_KERNELS
    if (simd_ != Simd::kPortable) {
      bits_.resize((x_.size() + 63) / 64);
      out.reserve(vectorInliers(pl, bits_.data()));
      for (std::size_t w = 0; w < bits_.size(); ++w) {
        for (std::uint64_t word = bits_[w]; word != 0; word &= word - 1) {
          out.push_back(ids_[64 * w + static_cast<std::size_t>(__builtin_ctzll(word))]);
        }
      }
      return;
    }
#endif
    for (std::size_t j = 0; j < x_.size(); ++j) {
      if (near(pl, j) && (!normals_ || facing(pl, j))) out.push_back(ids_[j]);
    }
  }

 private:
#if MOBMAP_X86_KERNELS
  // The same rule in the vector kernels (kernels/kernels.hpp).
  std::size_t vectorInliers(const Eigen::Vector4f& pl, std::uint64_t* bits) const {
    const float plane[4] = {pl(0), pl(1), pl(2), pl(3)};
    const float* nx = normals_ ? nx_.data() : nullptr;
    const auto kernel = simd_ == Simd::kAvx512 ? detail::avx512::planeInliers : detail::avx2::planeInliers;
    return kernel(x_.data(), y_.data(), z_.data(), nx, ny_.data(), nz_.data(), x_.size(), plane, dist_, cos_, bits);
  }
#endif
  // The two halves of the rule, the one place they are written (the portable loops).
  [[nodiscard]] bool near(const Eigen::Vector4f& pl, std::size_t j) const {
    return !(std::abs(pl(0) * x_[j] + (pl(1) * y_[j] + pl(2) * z_[j]) + pl(3)) > dist_);
  }
  [[nodiscard]] bool facing(const Eigen::Vector4f& pl, std::size_t j) const {
    return !(std::abs(pl(0) * nx_[j] + (pl(1) * ny_[j] + pl(2) * nz_[j])) < cos_);
  }

  const std::vector<int>& ids_;
  bool normals_;
  Simd simd_;
  float dist_, cos_ = 0.f;
  std::vector<float> x_, y_, z_, nx_, ny_, nz_;
  mutable std::vector<std::uint64_t> bits_;  // collect's inlier bits
};

}  // namespace

std::optional<PlaneFit> ransacPlane(const std::vector<Eigen::Vector3f>& points, const std::vector<int>& cand,
                                    const RansacOptions& o, std::mt19937& rng) {
  const Simd simd = activeSimd();
  if (cand.size() < 3) return std::nullopt;
  const double cos_tilt = std::cos(o.max_tilt_deg * M_PI / 180.0);
  const double cos_normal = std::cos(o.normal_tolerance_deg * M_PI / 180.0);
  const float dist = static_cast<float>(o.distance_m);
  std::uniform_int_distribution<std::size_t> pick(0, cand.size() - 1);
  std::size_t best_count = 0;
  Eigen::Vector4f best = Eigen::Vector4f::Zero();
  double needed = static_cast<double>(o.max_iterations);
  int it = 0;
  // Hypotheses are scored on a random subset (partial Fisher-Yates shuffle).
  std::vector<int> subset;
  const bool sampled = o.score_sample > 0 && cand.size() > o.score_sample;
  if (sampled) {
    subset = cand;
    for (std::size_t i = 0; i < o.score_sample; ++i) {
      std::uniform_int_distribution<std::size_t> rest(i, subset.size() - 1);
      std::swap(subset[i], subset[rest(rng)]);
    }
    subset.resize(o.score_sample);
  }
  const std::vector<int>& scoring = sampled ? subset : cand;
  constexpr std::size_t kFinalists = 8;
  std::vector<std::pair<std::size_t, Eigen::Vector4f>> finalists;
  const InlierTest on_scoring(points, scoring, o.point_normals, dist, cos_normal, simd);
  std::optional<InlierTest> on_all;  // the candidates, when they are not the scoring set
  if (sampled) on_all.emplace(points, cand, o.point_normals, dist, cos_normal, simd);
  const InlierTest& all = sampled ? *on_all : on_scoring;
  auto countInliers = [&](const Eigen::Vector4f& pl, std::vector<int>* out) {
    if (!out) return on_scoring.count(pl);
    all.collect(pl, *out);
    return out->size();
  };
  for (; it < o.max_iterations && it < needed; ++it) {
    const Eigen::Vector3f a = points[static_cast<std::size_t>(cand[pick(rng)])];
    const Eigen::Vector3f b = points[static_cast<std::size_t>(cand[pick(rng)])];
    const Eigen::Vector3f c = points[static_cast<std::size_t>(cand[pick(rng)])];
    Eigen::Vector3f n = (b - a).cross(c - a);
    const float len = n.norm();
    if (len < 1e-9f) continue;  // degenerate sample
    n /= len;
    if (o.required_normal && std::abs(n.dot(*o.required_normal)) < cos_tilt) continue;
    if (o.required_normal && o.origin_on_normal_side && (n.dot(*o.required_normal) < 0 ? n.dot(a) : -n.dot(a)) <= 0) continue;
    const Eigen::Vector4f pl(n.x(), n.y(), n.z(), -n.dot(a));
    const std::size_t count = countInliers(pl, nullptr);
    if (sampled && count > 0) {
      // Keep the best few by subset score; the full count decides among them, so
      // sampling noise cannot pick a plane that only looks best on the subset.
      finalists.emplace_back(count, pl);
      std::sort(finalists.begin(), finalists.end(),
                [](const auto& x, const auto& y) { return x.first > y.first; });
      if (finalists.size() > kFinalists) finalists.pop_back();
    }
    if (count > best_count) {
      best_count = count;
      best = pl;
      // Eq. 6 with the outlier ratio e = 1 - w updated from the best set so far.
      const double w = static_cast<double>(count) / static_cast<double>(scoring.size());
      const double denom = std::log(std::max(1e-12, 1.0 - w * w * w));
      needed = denom < 0 ? std::log(1.0 - o.probability) / denom : 0.0;
    }
  }
  if (best_count == 0) return std::nullopt;
  PlaneFit fit;
  fit.iterations = it;
  if (sampled) {
    std::size_t best_full = 0;
    for (const auto& f : finalists) {
      const std::size_t full = all.count(f.second);
      if (full > best_full) {
        best_full = full;
        best = f.second;
      }
    }
  }
  countInliers(best, &fit.inliers);
  if (fit.inliers.size() < 3) return std::nullopt;
  // Least-squares refits on the inliers, each followed by the inlier set of the new
  // plane, while that set does not shrink (at most a few rounds). One refit leaves
  // the slab chosen by the 3-point hypothesis, and with it part of the hypothesis'
  // tilt; iterating moves the band onto the surface's own mean plane, so the result
  // no longer depends on which sample happened to win.
  for (int round = 0; round < 5; ++round) {
    Eigen::Vector4f refined = leastSquaresPlane(points, fit.inliers);
    if (refined.head<3>().dot(best.head<3>()) < 0) refined = -refined;
    if (o.required_normal && std::abs(refined.head<3>().dot(*o.required_normal)) < cos_tilt) break;
    std::vector<int> again;
    if (countInliers(refined, &again) < fit.inliers.size()) break;
    const bool same = again == fit.inliers;
    best = refined;
    fit.inliers = std::move(again);
    if (same) break;
  }
  fit.plane = best;
  return fit;
}

std::vector<int> growRegions(const std::vector<Eigen::Vector3f>& points,
                             const std::vector<std::array<std::uint8_t, 3>>& colours, const KnnGraph& g,
                             const std::vector<bool>& eligible, double colour_threshold, double max_distance_m,
                             int min_points, int* regions, const std::vector<Eigen::Vector3f>* normals,
                             double max_deviation_deg) {
  const std::size_t n = points.size();
  if (normals && normals->size() != n) throw std::invalid_argument("growRegions: normals size differs from points");
  const bool gate = normals && max_deviation_deg < 180.0;
  const float min_cos = static_cast<float>(std::cos(max_deviation_deg * M_PI / 180.0));
  std::vector<Eigen::Vector3f> ycc(n);
  for (std::size_t i = 0; i < n; ++i) ycc[i] = rgbToYCrCb(colours[i]);
  const float max_d2 = static_cast<float>(max_distance_m * max_distance_m);
  const float thr2 = static_cast<float>(colour_threshold * colour_threshold);
  // -1: not yet reached, -2: in a region below min_points, -3: not eligible. One test
  // of the label then rejects a neighbour.
  std::vector<int> label(n);
  for (std::size_t i = 0; i < n; ++i) label[i] = eligible[i] ? -1 : -3;
  // The queue ends up holding the region's members, in the order they were reached.
  std::vector<int> queue;
  int next = 0;
  for (std::size_t seed = 0; seed < n; ++seed) {
    if (label[seed] != -1) continue;
    queue.clear();
    queue.push_back(static_cast<int>(seed));
    label[seed] = next;
    Eigen::Vector3f normal_sum = Eigen::Vector3f::Zero();
    Eigen::Vector3f mean_dir = Eigen::Vector3f::Zero();
    for (std::size_t head = 0; head < queue.size(); ++head) {
      const int i = queue[head];
      prefetchRow(g, queue, head + 6);
      if (gate) {
        normal_sum += (*normals)[static_cast<std::size_t>(i)];
        mean_dir = normal_sum.normalized();
      }
      forNeighboursWithin(g, static_cast<std::size_t>(i), max_d2, [&](std::size_t nb) {
        if (label[nb] != -1) return;
        if ((ycc[static_cast<std::size_t>(i)] - ycc[nb]).squaredNorm() > thr2) return;
        if (gate && (*normals)[nb].dot(mean_dir) < min_cos) return;
        label[nb] = next;
        queue.push_back(static_cast<int>(nb));
      });
    }
    if (static_cast<int>(queue.size()) < min_points) {
      for (int i : queue) label[static_cast<std::size_t>(i)] = -2;  // visited, too small
    } else {
      ++next;
    }
  }
  for (auto& l : label) l = l < 0 ? -1 : l;
  if (regions) *regions = next;
  return label;
}

namespace {

// First and second moments of a point set, for its PCA.
struct PointMoments {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  OuterSum outer;
  std::size_t n = 0;
  void add(const Eigen::Vector3f& p) {
    const Eigen::Vector3d q = p.cast<double>();
    sum += q;
    outer.add(q);
    ++n;
  }
  // Eigenvalues ascending, eigenvectors in columns (col(0): the plane normal).
  [[nodiscard]] Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen() const {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    const Eigen::Vector3d mean = sum / static_cast<double>(std::max<std::size_t>(n, 1));
    es.computeDirect(outer.matrix() / static_cast<double>(std::max<std::size_t>(n, 1)) - mean * mean.transpose());
    return es;
  }
  // Extent across the set's main direction: the width of a uniform strip is sqrt(12)
  // times its standard deviation.
  [[nodiscard]] static double width(const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>& es) {
    return std::sqrt(12.0 * std::max(0.0, es.eigenvalues()(1)));
  }
  [[nodiscard]] double width() const { return width(eigen()); }
};

}  // namespace

std::vector<int> mergeFragments(const std::vector<Eigen::Vector3f>& points, const std::vector<Eigen::Vector3f>& normals,
                                const KnnGraph& g, double max_neighbour_distance_m, const std::vector<int>& labels,
                                int min_segment_points, int fragment_max_points, double fragment_max_width_m,
                                int min_fragments, int min_points, double min_width_m, double min_spread_deg,
                                const std::optional<Eigen::Vector3f>& up, double max_slope_deg, int* regions,
                                std::vector<bool>* rough, const std::vector<bool>* ground) {
  const double cos_max_slope = std::cos(max_slope_deg * M_PI / 180.0);
  const std::size_t n = points.size();
  if (labels.size() != n || normals.size() != n || g.count.size() != n || (ground && ground->size() != n)) {
    throw std::invalid_argument("mergeFragments: points, normals, graph, labels and ground mask sizes differ");
  }
  int n_in = 0;
  for (int l : labels) n_in = std::max(n_in, l + 1);
  std::vector<int> size(static_cast<std::size_t>(n_in), 0);
  for (int l : labels) {
    if (l >= 0) ++size[static_cast<std::size_t>(l)];
  }
  // A fragment is a small region, or a narrow one: where fragments of the same
  // orientation touch at their corners (a row of pyramid faces) they grow into a long
  // zigzag strip a few centimetres wide.
  std::vector<bool> fragment(static_cast<std::size_t>(n_in), false);
  {
    std::vector<PointMoments> moments(static_cast<std::size_t>(n_in));
    for (std::size_t i = 0; i < n; ++i) {
      if (labels[i] >= 0) moments[static_cast<std::size_t>(labels[i])].add(points[i]);
    }
    for (std::size_t r = 0; r < fragment.size(); ++r) {
      fragment[r] = size[r] < fragment_max_points || moments[r].width() < fragment_max_width_m;
    }
  }
  auto is_fragment = [&](std::size_t i) { return labels[i] >= 0 && fragment[static_cast<std::size_t>(labels[i])]; };
  // Groups of connected fragment points (-1: not in a group).
  std::vector<int> group(n, -1);
  std::vector<bool> group_kept;
  {
    const float max_d2 = static_cast<float>(max_neighbour_distance_m * max_neighbour_distance_m);
    std::vector<int> queue;
    std::vector<int> seen_stamp(static_cast<std::size_t>(n_in), -1);
    std::vector<int> bridge_stamp(ground ? n : 0, -1);
    for (std::size_t seed = 0; seed < n; ++seed) {
      if (group[seed] >= 0 || !is_fragment(seed)) continue;
      const int id = static_cast<int>(group_kept.size());
      queue.assign(1, static_cast<int>(seed));
      group[seed] = id;
      int fragments = 0;
      for (std::size_t head = 0; head < queue.size(); ++head) {
        const auto i = static_cast<std::size_t>(queue[head]);
        prefetchRow(g, queue, head + 6);
        int& stamp = seen_stamp[static_cast<std::size_t>(labels[i])];
        if (stamp != id) {
          stamp = id;
          ++fragments;
        }
        auto take = [&](std::size_t nb) {
          if (group[nb] >= 0 || !is_fragment(nb)) return;
          group[nb] = id;
          queue.push_back(static_cast<int>(nb));
        };
        forNeighboursWithin(g, i, max_d2, [&](std::size_t nb) {
          take(nb);
          // Across one ground point to the fragments on its other side.
          if (ground && (*ground)[nb] && bridge_stamp[nb] != id) {
            bridge_stamp[nb] = id;
            forNeighboursWithin(g, nb, max_d2, take);
          }
        });
      }
      bool keep = fragments >= min_fragments && static_cast<int>(queue.size()) >= min_points;
      if (keep) {
        // Areal, not a strip: fragments along a crease (a stair's nose, a box edge)
        // also form groups, long and a few centimetres wide. The width of a uniform
        // strip is sqrt(12) times its standard deviation across.
        PointMoments m;
        for (int i : queue) m.add(points[static_cast<std::size_t>(i)]);
        const auto es = m.eigen();
        keep = PointMoments::width(es) >= min_width_m;
        // Walking surfaces only: a steep group is a staircase or a wall at a range
        // where noise fragments it, not rough ground.
        const Eigen::Vector3d plane_normal = es.eigenvectors().col(0);
        if (keep && up) keep = std::abs(plane_normal.dot(up->cast<double>().normalized())) >= cos_max_slope;
        // Rough: the point normals turn away from the group's plane. Fragments of a
        // smooth surface that noise broke up (a far floor, a gentle ramp) lean only a
        // few degrees off it.
        if (keep) {
          double spread = 0.0;
          for (int i : queue) {
            const double c = std::abs(normals[static_cast<std::size_t>(i)].cast<double>().dot(plane_normal));
            spread += std::acos(std::min(1.0, c));
          }
          keep = spread / static_cast<double>(queue.size()) * 180.0 / M_PI >= min_spread_deg;
        }
      }
      group_kept.push_back(keep);
    }
  }
  // Final labels, numbered in order of first point: kept groups, then regions that are
  // large enough on their own.
  std::vector<int> out(n, -1);
  std::vector<int> region_id(static_cast<std::size_t>(n_in), -1), group_id(group_kept.size(), -1);
  int next = 0;
  std::vector<bool> flags;
  for (std::size_t i = 0; i < n; ++i) {
    if (labels[i] < 0) continue;
    if (group[i] >= 0 && group_kept[static_cast<std::size_t>(group[i])]) {
      int& id = group_id[static_cast<std::size_t>(group[i])];
      if (id < 0) {
        id = next++;
        flags.push_back(true);
      }
      out[i] = id;
    } else if (size[static_cast<std::size_t>(labels[i])] >= min_segment_points) {
      int& id = region_id[static_cast<std::size_t>(labels[i])];
      if (id < 0) {
        id = next++;
        flags.push_back(false);
      }
      out[i] = id;
    }
  }
  if (regions) *regions = next;
  if (rough) *rough = std::move(flags);
  return out;
}

std::size_t absorbGroundIntoRough(const KnnGraph& g, double max_neighbour_distance_m,
                                  const std::vector<bool>& region_is_rough, double min_fraction, int passes,
                                  std::vector<int>& labels, std::vector<bool>& ground) {
  const std::size_t n = labels.size();
  if (ground.size() != n || g.count.size() != n) {
    throw std::invalid_argument("absorbGroundIntoRough: graph, labels and ground mask sizes differ");
  }
  const float max_d2 = static_cast<float>(max_neighbour_distance_m * max_neighbour_distance_m);
  std::size_t moved = 0;
  std::vector<std::pair<std::size_t, int>> moves;
  for (int pass = 0; pass < passes; ++pass) {
    moves.clear();
    for (std::size_t i = 0; i < n; ++i) {
      if (!ground[i]) continue;
      // Votes for rough regions as a whole (a valley between two pieces of one rough
      // surface has both around it); the point joins the one most of them belong to.
      int near = 0, votes = 0;
      std::array<std::pair<int, int>, 4> tally{};  // (region, count), the first few seen
      int kinds = 0;
      forNeighboursWithin(g, i, max_d2, [&](std::size_t nb) {
        ++near;
        const int l = labels[nb];
        if (l < 0 || static_cast<std::size_t>(l) >= region_is_rough.size() || !region_is_rough[static_cast<std::size_t>(l)]) return;
        ++votes;
        int t = 0;
        while (t < kinds && tally[static_cast<std::size_t>(t)].first != l) ++t;
        if (t == kinds && kinds < static_cast<int>(tally.size())) tally[static_cast<std::size_t>(kinds++)] = {l, 0};
        if (t < kinds) ++tally[static_cast<std::size_t>(t)].second;
      });
      if (kinds > 0 && votes > min_fraction * near) {
        const auto best = std::max_element(tally.begin(), tally.begin() + kinds,
                                           [](const auto& a, const auto& b) { return a.second < b.second; });
        moves.emplace_back(i, best->first);
      }
    }
    if (moves.empty()) break;
    for (const auto& [i, region] : moves) {
      ground[i] = false;
      labels[i] = region;
    }
    moved += moves.size();
  }
  return moved;
}

int joinTouchingRoughRegions(const KnnGraph& g, double max_neighbour_distance_m, std::vector<bool>& region_is_rough,
                             std::vector<int>& labels, int* regions) {
  const std::size_t n = labels.size();
  if (g.count.size() != n || !regions || static_cast<std::size_t>(*regions) != region_is_rough.size()) {
    throw std::invalid_argument("joinTouchingRoughRegions: graph, labels and region counts differ");
  }
  std::vector<int> parent(region_is_rough.size());
  for (std::size_t r = 0; r < parent.size(); ++r) parent[r] = static_cast<int>(r);
  const auto root = [&](int r) {
    while (parent[static_cast<std::size_t>(r)] != r) r = parent[static_cast<std::size_t>(r)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(r)])];
    return r;
  };
  const auto rough = [&](int l) { return l >= 0 && region_is_rough[static_cast<std::size_t>(l)]; };
  const float max_d2 = static_cast<float>(max_neighbour_distance_m * max_neighbour_distance_m);
  int joins = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!rough(labels[i])) continue;
    forNeighboursWithin(g, i, max_d2, [&](std::size_t nb) {
      if (!rough(labels[nb])) return;
      const int a = root(labels[i]), b = root(labels[nb]);
      if (a == b) return;
      parent[static_cast<std::size_t>(std::max(a, b))] = std::min(a, b);
      ++joins;
    });
  }
  if (joins == 0) return 0;
  // Renumber: surviving regions keep their order.
  std::vector<int> new_id(parent.size(), -1);
  std::vector<bool> new_rough;
  for (std::size_t r = 0; r < parent.size(); ++r) {
    if (root(static_cast<int>(r)) != static_cast<int>(r)) continue;
    new_id[r] = static_cast<int>(new_rough.size());
    new_rough.push_back(region_is_rough[r]);
  }
  for (auto& l : labels) {
    if (l >= 0) l = new_id[static_cast<std::size_t>(root(l))];
  }
  region_is_rough.swap(new_rough);
  *regions = static_cast<int>(region_is_rough.size());
  return joins;
}

std::size_t reclaimGroundPoints(const std::vector<Eigen::Vector3f>& points, const KnnGraph& g,
                                double max_neighbour_distance_m, const Eigen::Vector4f& ground_plane,
                                const std::vector<Eigen::Vector4f>& region_planes, double min_angle_deg,
                                double max_angle_deg, double max_plane_distance_m, std::vector<int>& labels,
                                std::vector<bool>& ground, const std::vector<Eigen::Vector3f>* normals,
                                const std::vector<bool>* no_footprint) {
  const std::size_t n = points.size();
  if (labels.size() != n || ground.size() != n || g.count.size() != n) {
    throw std::invalid_argument("reclaimGroundPoints: points, graph, labels and ground mask sizes differ");
  }
  if (no_footprint && no_footprint->size() != region_planes.size()) {
    throw std::invalid_argument("reclaimGroundPoints: no_footprint and region_planes sizes differ");
  }
  const Eigen::Vector3f gn = ground_plane.head<3>().normalized();
  const float gd = ground_plane(3) / ground_plane.head<3>().norm();
  const double cos_min = std::cos(min_angle_deg * M_PI / 180.0);
  const double cos_max = std::cos(max_angle_deg * M_PI / 180.0);
  std::vector<bool> tilted(region_planes.size(), false);
  std::vector<Eigen::Vector4f> unit(region_planes.size());
  for (std::size_t r = 0; r < region_planes.size(); ++r) {
    const float len = region_planes[r].head<3>().norm();
    if (!(len > 0.f)) continue;
    unit[r] = region_planes[r] / len;
    const double c = std::abs(static_cast<double>(unit[r].head<3>().dot(gn)));
    tilted[r] = c < cos_min && c >= cos_max - 1e-9;
  }
  const float max_d2 = static_cast<float>(max_neighbour_distance_m * max_neighbour_distance_m);
  const float max_plane = static_cast<float>(max_plane_distance_m);
  std::vector<int> queue;
  for (std::size_t i = 0; i < n; ++i) {
    const int r = labels[i];
    if (r >= 0 && static_cast<std::size_t>(r) < tilted.size() && tilted[static_cast<std::size_t>(r)]) {
      queue.push_back(static_cast<int>(i));
    }
  }
  // Each tilted region's footprint on the ground: the side of the line where its plane
  // meets the ground plane on which the region rises, and its extent along that line.
  // Near the line the two planes are closer than the noise, so distances and normals
  // cannot tell the ramp's foot from the floor; the footprint can (the floor cannot lie
  // under the ramp), and it measures positions along the ground, which noise barely moves.
  struct Footprint {
    Eigen::Vector3f along = Eigen::Vector3f::Zero();  // direction of the line
    float rise_sign = 0.f;                             // sign of the region plane's value on the ramp side (0: unknown)
    float lo = std::numeric_limits<float>::max(), hi = std::numeric_limits<float>::lowest();
  };
  // Where the region's plane is this far above the ground plane: its fitted plane is off
  // by a few millimetres at its foot (a tilt error over half a metre of ramp), and
  // nearer the line that error alone would put floor points under the region.
  constexpr float kFootprintClearance = 0.007f;
  std::vector<Footprint> foot(region_planes.size());
  std::vector<double> height_sum(region_planes.size(), 0.0);  // region points' signed distance to the ground plane
  for (int idx : queue) {
    const auto i = static_cast<std::size_t>(idx);
    const auto r = static_cast<std::size_t>(labels[i]);
    Footprint& f = foot[r];
    if (f.along.isZero()) f.along = gn.cross(unit[r].head<3>()).normalized();
    const float a = f.along.dot(points[i]);
    f.lo = std::min(f.lo, a);
    f.hi = std::max(f.hi, a);
    height_sum[r] += gn.dot(points[i]) + gd;
  }
  for (std::size_t r = 0; r < region_planes.size(); ++r) {
    // A point p of the region at signed height h over the ground plane has its foot
    // p - h gn on the ground, where the region's plane has the value -h (nr . gn): the
    // sign of that value marks the side the region stands over (either orientation of
    // either plane).
    const double side = -height_sum[r] * static_cast<double>(unit[r].head<3>().dot(gn));
    const bool planar = !(no_footprint && (*no_footprint)[r]);
    foot[r].rise_sign = !planar ? 0.f : side > 0 ? 1.f : side < 0 ? -1.f : 0.f;
  }
  // +1: under the region (beyond the line by the clearance, between its sides); -1: in
  // front of the line by the clearance (the region's plane lies below the floor there);
  // 0: near the line or beside the region, where the distances and normals decide.
  const auto footprintSide = [&](std::size_t r, const Eigen::Vector3f& q) {
    const Footprint& f = foot[r];
    if (f.rise_sign == 0.f) return 0;
    const Eigen::Vector3f on_ground = q - (gn.dot(q) + gd) * gn;
    const float rise = f.rise_sign * (unit[r].head<3>().dot(on_ground) + unit[r](3));
    if (rise < -kFootprintClearance) return -1;
    // Half a centimetre of slack: the line's direction comes from the fitted plane, and a
    // tenth of a degree off it moves a corner of the ramp by about a millimetre.
    const float a = f.along.dot(q);
    return rise > kFootprintClearance && a >= f.lo - 0.005f && a <= f.hi + 0.005f ? 1 : 0;
  };
  std::size_t moved = 0;
  for (std::size_t head = 0; head < queue.size(); ++head) {
    const auto i = static_cast<std::size_t>(queue[head]);
    const auto r = static_cast<std::size_t>(labels[i]);
    const Eigen::Vector4f& pl = unit[r];
    forNeighboursWithin(g, i, max_d2, [&](std::size_t nb) {
      if (!ground[nb]) return;
      const Eigen::Vector3f& q = points[nb];
      const float to_region = std::abs(pl.head<3>().dot(q) + pl(3));
      const float to_ground = std::abs(gn.dot(q) + gd);
      if (to_region > max_plane) return;
      const int side = footprintSide(r, q);
      if (side < 0) return;
      if (side == 0) {
        if (to_region >= to_ground) return;
        if (normals && !(*normals)[nb].isZero() &&
            std::abs((*normals)[nb].dot(pl.head<3>())) <= std::abs((*normals)[nb].dot(gn))) {
          return;  // its normal says floor
        }
      }
      ground[nb] = false;
      labels[nb] = static_cast<int>(r);
      queue.push_back(static_cast<int>(nb));
      ++moved;
    });
  }
  return moved;
}

std::size_t adoptUnsegmentedPoints(const std::vector<Eigen::Vector3f>& points, const std::vector<Eigen::Vector3f>& normals,
                                   const KnnGraph& g, double max_neighbour_distance_m,
                                   const std::vector<Eigen::Vector4f>& region_planes,
                                   const std::vector<bool>& region_excluded, double max_plane_distance_m,
                                   double max_angle_deg, std::vector<int>& labels, const std::vector<bool>& ground) {
  const std::size_t n = points.size();
  if (labels.size() != n || ground.size() != n || normals.size() != n || g.count.size() != n) {
    throw std::invalid_argument("adoptUnsegmentedPoints: points, normals, graph, labels and ground mask sizes differ");
  }
  std::vector<Eigen::Vector4f> unit(region_planes.size(), Eigen::Vector4f::Zero());
  std::vector<bool> open(region_planes.size(), false);
  for (std::size_t r = 0; r < region_planes.size(); ++r) {
    const float len = region_planes[r].head<3>().norm();
    if (!(len > 0.f) || !region_planes[r].allFinite()) continue;
    unit[r] = region_planes[r] / len;
    open[r] = !(r < region_excluded.size() && region_excluded[r]);
  }
  const float max_d2 = static_cast<float>(max_neighbour_distance_m * max_neighbour_distance_m);
  const float max_plane = static_cast<float>(max_plane_distance_m);
  const float min_cos = static_cast<float>(std::cos(max_angle_deg * M_PI / 180.0));
  std::vector<int> orphans;
  for (std::size_t i = 0; i < n; ++i) {
    if (labels[i] < 0 && !ground[i] && !normals[i].isZero()) orphans.push_back(static_cast<int>(i));
  }
  // For each point, the orphans that have it as a neighbour (CSR): only those can
  // change their mind when it joins a region.
  std::vector<int> watch_start(n + 1, 0), watchers;
  for (std::size_t s = 0; s < orphans.size(); ++s) {
    prefetchRow(g, orphans, s + 8);
    forNeighboursWithin(g, static_cast<std::size_t>(orphans[s]), max_d2,
                        [&](std::size_t nb) { ++watch_start[nb + 1]; });
  }
  for (std::size_t i = 0; i < n; ++i) watch_start[i + 1] += watch_start[i];
  watchers.resize(static_cast<std::size_t>(watch_start[n]));
  {
    std::vector<int> fill(watch_start.begin(), watch_start.end() - 1);
    for (int o : orphans) {
      forNeighboursWithin(g, static_cast<std::size_t>(o), max_d2,
                          [&](std::size_t nb) { watchers[static_cast<std::size_t>(fill[nb]++)] = o; });
    }
  }
  // Rounds: each round, every orphan next to a region it fits joins the closest such
  // region (by distance to the plane), decided on the labels of the round before, so
  // the result does not depend on the order points are visited in. After the first
  // round only orphans next to a point that joined in the last round are looked at.
  std::size_t adopted = 0;
  std::vector<std::pair<int, int>> joins;
  std::vector<int> stamp(n, -1);
  for (int round = 0; !orphans.empty(); ++round) {
    joins.clear();
    for (std::size_t s = 0; s < orphans.size(); ++s) {
      prefetchRow(g, orphans, s + 8);
      const int o = orphans[s];
      const auto j = static_cast<std::size_t>(o);
      const Eigen::Vector3f& q = points[j];
      int best = -1;
      float best_d = max_plane;
      forNeighboursWithin(g, j, max_d2, [&](std::size_t nb) {
        const int r = labels[nb];
        if (r < 0 || static_cast<std::size_t>(r) >= open.size() || !open[static_cast<std::size_t>(r)]) return;
        const Eigen::Vector4f& pl = unit[static_cast<std::size_t>(r)];
        const float d = std::abs(pl.head<3>().dot(q) + pl(3));
        if (d > best_d || (d == best_d && best >= 0 && r >= best)) return;
        if (std::abs(pl.head<3>().dot(normals[j])) < min_cos) return;
        best = r;
        best_d = d;
      });
      if (best >= 0) joins.emplace_back(o, best);
    }
    if (joins.empty()) break;
    for (const auto& [o, r] : joins) labels[static_cast<std::size_t>(o)] = r;
    adopted += joins.size();
    orphans.clear();
    for (const auto& jr : joins) {
      const auto a = static_cast<std::size_t>(jr.first);
      for (int w = watch_start[a]; w < watch_start[a + 1]; ++w) {
        const int o = watchers[static_cast<std::size_t>(w)];
        if (labels[static_cast<std::size_t>(o)] >= 0 || stamp[static_cast<std::size_t>(o)] == round) continue;
        stamp[static_cast<std::size_t>(o)] = round;
        orphans.push_back(o);
      }
    }
  }
  return adopted;
}

}  // namespace mobmap::perception
