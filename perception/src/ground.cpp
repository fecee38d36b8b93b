// Paper step 5: the RANSAC ground plane (eq. 6) and least-squares planes.

#include "mobmap/perception/ground.hpp"

#include "graph_walk.hpp"
#include "kernels/kernels.hpp"
#include "kernels/simd.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace mobmap::perception {

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

double imageUpTiltDeg(const Eigen::Vector4f& plane) {
  const double towards_camera = plane(3) < 0 ? -1.0 : 1.0;
  const double c = -towards_camera * plane(1) / std::max(static_cast<double>(plane.head<3>().norm()), 1e-12);
  return std::acos(std::clamp(c, -1.0, 1.0)) * 180.0 / M_PI;
}

}  // namespace mobmap::perception
