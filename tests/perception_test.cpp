// The per-frame pipeline, stage by stage against brute force and analytic oracles,
// and end to end on the synthetic corridor with exact ground truth.
#include "mobmap/perception/pipeline.hpp"
#include "mobmap/perception/stages.hpp"
#include "mobmap/sim/corridor_scene.hpp"
#include "kernels/simd.hpp"  // private: pins the instruction set

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <set>
#include <random>
#include <thread>

namespace mobmap::perception {
namespace {

constexpr double kDeg = M_PI / 180.0;

std::vector<Eigen::Vector3f> randomCloud(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.3f, 0.3f);
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < n; ++i) {
    // A noisy wavy sheet plus some scattered points: surface-like and irregular.
    const float x = u(rng), y = u(rng);
    pts.emplace_back(x, y, 0.05f * std::sin(10 * x) + 0.01f * u(rng) + (i % 17 == 0 ? u(rng) : 0.f));
  }
  return pts;
}

// Every instruction set this machine can run (the portable loops always); each must
// give the brute-force graph exactly.
std::vector<Simd> simdChoices() {
  std::vector<Simd> out{Simd::kPortable};
  for (Simd simd : {Simd::kAvx2, Simd::kAvx512}) {
    if (simdSupported(simd)) {
      out.push_back(simd);
    } else {
      std::printf("note: this CPU has no %s; its kernels are not tested here\n", toString(simd));
    }
  }
  return out;
}

void expectSameGraph(const KnnGraph& fast, const KnnGraph& ref, const std::string& what) {
  EXPECT_EQ(fast.count, ref.count) << what;
  EXPECT_EQ(fast.indices, ref.indices) << what;
  EXPECT_EQ(fast.sq_dist, ref.sq_dist) << what;
}

TEST(Neighbours, GridKnnEqualsBruteForce) {
  const auto pts = randomCloud(3000, 1);
  for (Simd simd : simdChoices()) {
    const ScopedSimd use(simd);
    for (int k : {1, 8, 30}) {
      expectSameGraph(buildKnnGraph(pts, k, 0.02f, 10.f), bruteForceKnnGraph(pts, k),
                      std::string(toString(simd)) + " k " + std::to_string(k));
    }
  }
}

TEST(Neighbours, SparseAndDenseRegionsTakeEveryBranchOfTheSearch) {
  // Clusters 2-6 cells apart (rows that need rings 2 and beyond), isolated points with
  // fewer than k neighbours even within the maximum radius, and a dense blob in which a
  // cell's guaranteed radius holds hundreds of candidates (the selection for more than
  // the 64 keys the vector ranking takes).
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  std::vector<Eigen::Vector3f> pts;
  for (int c = 0; c < 12; ++c) {
    const Eigen::Vector3f centre(0.09f * static_cast<float>(c), 0.07f * static_cast<float>(c % 3), 0.f);
    for (int i = 0; i < 6 + 3 * c; ++i) pts.push_back(centre + 0.015f * Eigen::Vector3f(u(rng), u(rng), u(rng)));
  }
  for (int i = 0; i < 5; ++i) pts.emplace_back(2.f + 0.5f * static_cast<float>(i), -1.f, 0.3f);
  for (int i = 0; i < 600; ++i) pts.push_back(Eigen::Vector3f(-0.5f, 0.f, 0.f) + 0.01f * Eigen::Vector3f(u(rng), u(rng), u(rng)));
  for (Simd simd : simdChoices()) {
    const ScopedSimd use(simd);
    for (int k : {4, 30}) {
      for (float max_radius : {0.25f, 1.f}) {
        const KnnGraph fast = buildKnnGraph(pts, k, 0.02f, max_radius);
        KnnGraph ref = bruteForceKnnGraph(pts, k);
        // The reference knows no radius: cut its rows at it.
        for (std::size_t i = 0; i < pts.size(); ++i) {
          int c = 0;
          while (c < ref.count[i] && ref.sq_dist[i * static_cast<std::size_t>(k) + static_cast<std::size_t>(c)] <= max_radius * max_radius) ++c;
          for (int j = c; j < ref.count[i]; ++j) {
            ref.indices[i * static_cast<std::size_t>(k) + static_cast<std::size_t>(j)] = -1;
            ref.sq_dist[i * static_cast<std::size_t>(k) + static_cast<std::size_t>(j)] = 0.f;
          }
          ref.count[i] = c;
        }
        expectSameGraph(fast, ref, std::string(toString(simd)) + " k " + std::to_string(k) + " radius " + std::to_string(max_radius));
        if (max_radius < 1.f) {
          EXPECT_LT(*std::min_element(fast.count.begin(), fast.count.end()), k);  // short rows exist
        }
      }
    }
  }
  for (Simd simd : {Simd::kAvx2, Simd::kAvx512}) {
    if (simdSupported(simd)) {
      const ScopedSimd use(simd);
      EXPECT_EQ(activeSimd(), simd);
    } else {
      EXPECT_THROW(ScopedSimd pin(simd), std::invalid_argument);
    }
  }
  // Unpinned, the kernels take the widest: AVX-512 where there is, else AVX2; a pin
  // ends with its scope.
  const Simd best = simdSupported(Simd::kAvx512) ? Simd::kAvx512
                    : simdSupported(Simd::kAvx2) ? Simd::kAvx2
                                                 : Simd::kPortable;
  EXPECT_EQ(activeSimd(), best);
  {
    const ScopedSimd portable(Simd::kPortable);
    EXPECT_EQ(activeSimd(), Simd::kPortable);
  }
  EXPECT_EQ(activeSimd(), best);
}

TEST(Neighbours, GridKnnEqualsBruteForceOnALatticeFullOfTies) {
  // Voxel centroids of a flat floor sit on a lattice: many neighbours share a distance
  // exactly, and the search's distance bands then hold runs of equal keys. Ties must
  // still resolve by index, as in the brute-force reference. Two lattices: a plane
  // (in the cell size the pipeline uses for k = 30) and a thin 3D slab.
  std::vector<Eigen::Vector3f> plane, slab;
  for (int i = 0; i < 45; ++i) {
    for (int j = 0; j < 45; ++j) plane.emplace_back(0.01f * i, 0.01f * j, 1.0f);
  }
  for (int i = 0; i < 16; ++i) {
    for (int j = 0; j < 16; ++j) {
      for (int l = 0; l < 4; ++l) slab.emplace_back(0.01f * i, 0.01f * j, 0.01f * l);
    }
  }
  for (Simd simd : simdChoices()) {
    const ScopedSimd use(simd);
    for (const auto* pts : {&plane, &slab}) {
      for (int k : {4, 16, 30}) {
        expectSameGraph(buildKnnGraph(*pts, k, 0.0375f, 0.2f), bruteForceKnnGraph(*pts, k),
                        std::string(toString(simd)) + " k " + std::to_string(k));
      }
    }
  }
}

TEST(Neighbours, GridKnnEqualsBruteForceWithPointsOnAndBesideCellFaces) {
  // The search trusts a radius of one cell plus each point's distance to its own cell's
  // faces. Points exactly on faces (margin 0), one float step either side of them, at
  // the middle of a cell (margin half a cell), and the same lattice 1 km away (where a
  // float step is ~0.06 mm and the cell arithmetic rounds the most).
  const float cell = 0.04f;
  std::vector<Eigen::Vector3f> pts;
  for (const float origin : {0.f, 1000.f}) {
    for (int i = 0; i < 24; ++i) {
      for (int j = 0; j < 24; ++j) {
        for (int l = 0; l < 3; ++l) {
          const Eigen::Vector3f p(origin + 0.01f * i, origin + 0.01f * j, origin + 0.02f * l);
          pts.push_back(p);
          if ((i + j + l) % 5 == 0) {
            pts.emplace_back(std::nextafter(p.x(), 1e9f), p.y(), std::nextafter(p.z(), -1e9f));
          } else if ((i + j + l) % 5 == 1) {
            pts.emplace_back(std::nextafter(p.x(), -1e9f), std::nextafter(p.y(), 1e9f), p.z());
          }
        }
      }
    }
  }
  for (Simd simd : simdChoices()) {
    const ScopedSimd use(simd);
    for (int k : {8, 30, 60}) {
      expectSameGraph(buildKnnGraph(pts, k, cell, 0.2f), bruteForceKnnGraph(pts, k),
                      std::string(toString(simd)) + " k " + std::to_string(k));
    }
  }
}

TEST(Neighbours, MaxRadiusDropsFarNeighbours) {
  std::vector<Eigen::Vector3f> pts = {{0, 0, 0}, {0.01f, 0, 0}, {1, 0, 0}};
  for (Simd simd : simdChoices()) {
    const ScopedSimd use(simd);
    const KnnGraph g = buildKnnGraph(pts, 2, 0.05f, 0.1f);
    EXPECT_EQ(g.count[0], 1) << toString(simd);
    EXPECT_EQ(g.indices[0], 1) << toString(simd);
    EXPECT_EQ(g.count[2], 0) << toString(simd);
  }
}

TEST(Neighbours, RestrictedGraphEqualsBruteForceOnTheKeptPoints) {
  const auto pts = randomCloud(3000, 5);
  const KnnGraph all = buildKnnGraph(pts, 30, 0.02f, 10.f);
  // Drop every 7th point and a dense blob, so some rows lose many neighbours.
  std::vector<bool> keep(pts.size(), true);
  std::vector<Eigen::Vector3f> kept;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    keep[i] = i % 7 != 0 && (pts[i].head<2>() - Eigen::Vector2f(0.1f, 0.1f)).norm() > 0.05f;
    if (keep[i]) kept.push_back(pts[i]);
  }
  for (Simd simd : simdChoices()) {
    const ScopedSimd use(simd);
    for (int k : {16, 30}) {
      std::size_t recomputed = 0;
      const KnnGraph fast = restrictKnnGraph(all, pts, keep, k, 0.02f, 10.f, &recomputed);
      const KnnGraph reference = bruteForceKnnGraph(kept, k);
      expectSameGraph(fast, reference, std::string(toString(simd)) + " k " + std::to_string(k));
      EXPECT_GT(recomputed, 0u) << "k " << k;  // the test exercises the search-again path
      EXPECT_LT(recomputed, kept.size()) << "k " << k;  // and the reuse path
      // The same graph built over the original in its own buffers (what the pipeline does).
      KnnGraph in_place = all;
      std::size_t recomputed_in_place = 0;
      restrictKnnGraphInPlace(in_place, pts, keep, k, 0.02f, 10.f, &recomputed_in_place);
      expectSameGraph(in_place, reference, std::string("in place ") + toString(simd) + " k " + std::to_string(k));
      EXPECT_EQ(in_place.indices.size(), kept.size() * static_cast<std::size_t>(k));
      EXPECT_EQ(recomputed_in_place, recomputed);
    }
  }
  EXPECT_THROW(restrictKnnGraph(all, pts, keep, 31, 0.02f, 10.f), std::invalid_argument);
  KnnGraph copy = all;
  EXPECT_THROW(restrictKnnGraphInPlace(copy, pts, keep, 31, 0.02f, 10.f), std::invalid_argument);
}

// The pipeline keeps its graph from frame to frame. A graph built into buffers
// that held another cloud's graph (more points, another k, rows full of stale
// entries) must equal a fresh one, padding of short rows included.
TEST(Neighbours, GraphsBuiltIntoReusedBuffersEqualFreshOnes) {
  auto pts = randomCloud(1500, 9);
  // Two points far from the rest: rows with one neighbour each. The mask removes the
  // first (index 1500), which leaves the second with none in the restricted graph.
  pts.emplace_back(50.f, 50.f, 50.f);
  pts.emplace_back(50.f, 50.f, 50.01f);
  std::vector<bool> keep(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) keep[i] = i % 5 != 0;
  for (Simd simd : simdChoices()) {
    const ScopedSimd use(simd);
    KnnGraph reused = buildKnnGraph(randomCloud(4000, 10), 40, 0.02f, 10.f);
    KnnGraph restricted_reused = reused;
    buildKnnGraph(pts, 30, 0.02f, 0.5f, reused);
    const KnnGraph fresh = buildKnnGraph(pts, 30, 0.02f, 0.5f);
    expectSameGraph(reused, fresh, toString(simd));
    EXPECT_EQ(fresh.count[pts.size() - 2], 1);
    EXPECT_EQ(fresh.indices[(pts.size() - 2) * 30 + 1], -1);
    EXPECT_EQ(fresh.sq_dist[(pts.size() - 2) * 30 + 1], 0.f);
    restrictKnnGraph(fresh, pts, keep, 20, 0.02f, 0.5f, restricted_reused, nullptr);
    expectSameGraph(restricted_reused, restrictKnnGraph(fresh, pts, keep, 20, 0.02f, 0.5f, nullptr),
                    toString(simd));
    EXPECT_THROW(restrictKnnGraph(reused, pts, keep, 20, 0.02f, 0.5f, reused, nullptr), std::invalid_argument);
  }
}

TEST(OutlierRemoval, FirstKOfALargerGraphEqualsTheSmallerGraph) {
  const auto pts = randomCloud(2000, 6);
  const auto a = statisticalOutlierMask(bruteForceKnnGraph(pts, 30), 1.0, 8);
  const auto b = statisticalOutlierMask(bruteForceKnnGraph(pts, 8), 1.0);
  EXPECT_EQ(a, b);
}

TEST(Camera, IntrinsicsFittedToAnOrganizedCloudAreTheOnesThatMadeIt) {
  PinholeIntrinsics k;
  k.width = 160, k.height = 120, k.fx = 150.5, k.fy = 149.0, k.cx = 79.25, k.cy = 61.5;
  std::vector<Eigen::Vector3f> cloud(static_cast<std::size_t>(k.width * k.height));
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const double z = 1.0 + 0.01 * ((u * 7 + v * 13) % 50);
      cloud[static_cast<std::size_t>(v * k.width + u)] =
          (u + v) % 11 == 0 ? Eigen::Vector3f(nan, nan, nan) : backProject(k, u, v, z).cast<float>();
    }
  }
  double rms = -1;
  const auto fit = fitIntrinsics(cloud, k.width, k.height, &rms);
  ASSERT_TRUE(fit);
  EXPECT_NEAR(fit->fx, k.fx, 1e-3);
  EXPECT_NEAR(fit->fy, k.fy, 1e-3);
  EXPECT_NEAR(fit->cx, k.cx, 1e-3);
  EXPECT_NEAR(fit->cy, k.cy, 1e-3);
  EXPECT_EQ(fit->width, k.width);
  EXPECT_LT(rms, 0.01);
  // Points that are not a pinhole image of their pixels: a large residual.
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1, 1);
  for (auto& p : cloud) p = Eigen::Vector3f(u(rng), u(rng), 2 + u(rng));
  const auto bad = fitIntrinsics(cloud, k.width, k.height, &rms);
  EXPECT_TRUE(!bad || rms > 10);
  std::vector<Eigen::Vector3f> empty(cloud.size(), Eigen::Vector3f(nan, nan, nan));
  EXPECT_FALSE(fitIntrinsics(empty, k.width, k.height));
  EXPECT_THROW(fitIntrinsics(empty, k.width + 1, k.height), std::invalid_argument);
}

TEST(VoxelReduce, CentroidsEqualBruteForceGrouping) {
  const auto pts = randomCloud(5000, 2);
  std::vector<int> voxel_of;
  const auto vox = voxelReduce(pts, 0.01f, &voxel_of);
  std::map<std::tuple<int, int, int>, std::pair<Eigen::Vector3d, int>> ref;
  for (const auto& p : pts) {
    // Same cell arithmetic as the implementation (x * (1 / size)), so boundary
    // points fall on the same side.
    const std::tuple<int, int, int> key{static_cast<int>(std::floor(p.x() * (1.f / 0.01f))),
                                        static_cast<int>(std::floor(p.y() * (1.f / 0.01f))),
                                        static_cast<int>(std::floor(p.z() * (1.f / 0.01f)))};
    auto it = ref.find(key);
    if (it == ref.end()) it = ref.emplace(key, std::make_pair(Eigen::Vector3d::Zero().eval(), 0)).first;
    auto& e = it->second;
    e.first += p.cast<double>();
    ++e.second;
  }
  ASSERT_EQ(vox.size(), ref.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const auto& p = pts[i];
    const auto& e = ref.at({static_cast<int>(std::floor(p.x() * (1.f / 0.01f))),
                            static_cast<int>(std::floor(p.y() * (1.f / 0.01f))),
                            static_cast<int>(std::floor(p.z() * (1.f / 0.01f)))});
    EXPECT_LT((vox[static_cast<std::size_t>(voxel_of[i])].cast<double>() - e.first / e.second).norm(), 1e-6);
  }
}

TEST(VoxelReduce, ImageOrderedRunsGiveTheCentroidsOfOnePointAtATime) {
  // Points as an image gives them: rows of pixels whose voxels come in runs of equal
  // keys, go back to a voxel seen a few points or a row before, straddle voxel faces
  // (coordinates exactly on them too) and lie on both sides of zero. Every kernel of
  // the voxel keys must give, bit for bit, what one point at a time gives: voxels
  // numbered by first occurrence, each the double sum of its points in input order.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> jitter(-0.004f, 0.004f);
  std::vector<Eigen::Vector3f> pts;
  for (int v = 0; v < 60; ++v) {
    for (int u = 0; u < 77; ++u) {  // 77 * 60 points: not a multiple of 8 or 16
      const float x = -0.2f + 0.0027f * static_cast<float>(u), y = -0.1f + 0.0031f * static_cast<float>(v);
      float z = 1.f + 0.3f * x + jitter(rng);  // depth noise: the key flips along z
      if ((u + v) % 23 == 0) z = 1.f;          // on a face
      if ((u * v) % 31 == 0) z = 0.01f * static_cast<float>(u % 5);
      pts.emplace_back(u % 19 == 0 ? 0.01f * static_cast<float>(v % 7 - 3) : x, y, z);
    }
  }
  const float size = 0.01f, inv = 1.f / size;
  std::map<std::tuple<int, int, int>, int> number;
  std::vector<Eigen::Vector3d> sums;
  std::vector<int> counts, ref_of;
  for (const auto& p : pts) {
    const std::tuple<int, int, int> key{static_cast<int>(std::floor(p.x() * inv)),
                                        static_cast<int>(std::floor(p.y() * inv)),
                                        static_cast<int>(std::floor(p.z() * inv))};
    auto it = number.find(key);
    if (it == number.end()) {
      it = number.emplace(key, static_cast<int>(sums.size())).first;
      sums.emplace_back(Eigen::Vector3d::Zero());
      counts.push_back(0);
    }
    sums[static_cast<std::size_t>(it->second)] += p.cast<double>();
    ++counts[static_cast<std::size_t>(it->second)];
    ref_of.push_back(it->second);
  }
  int repeats = 0;  // points whose voxel is that of the point before: the runs
  for (std::size_t i = 1; i < ref_of.size(); ++i) repeats += ref_of[i] == ref_of[i - 1];
  ASSERT_GT(repeats, 1000);
  ASSERT_LT(sums.size(), pts.size() - static_cast<std::size_t>(repeats));  // and voxels met again later
  // Each choice twice: the second call finds the table the first one filled (kept by
  // the thread), which must start empty again.
  for (Simd simd : simdChoices()) {
    const ScopedSimd use(simd);
    for (int call = 0; call < 2; ++call) {
      std::vector<int> voxel_of;
      const auto vox = voxelReduce(pts, size, &voxel_of);
      EXPECT_EQ(voxel_of, ref_of) << toString(simd) << " call " << call;
      ASSERT_EQ(vox.size(), sums.size()) << toString(simd) << " call " << call;
      for (std::size_t v = 0; v < vox.size(); ++v) {
        const Eigen::Vector3f want = (sums[v] / counts[v]).cast<float>();
        EXPECT_EQ(vox[v], want) << toString(simd) << " call " << call << " voxel " << v;
      }
    }
  }
}

TEST(OutlierRemoval, KeepsExactlyThePointsWithinAlphaSigma) {
  auto pts = randomCloud(2000, 3);
  const int k = 8;
  const KnnGraph g = bruteForceKnnGraph(pts, k);
  const auto keep = statisticalOutlierMask(g, 1.0);
  std::vector<double> d(pts.size());
  double mu = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    for (int j = 0; j < k; ++j) d[i] += std::sqrt(g.sq_dist[i * k + static_cast<std::size_t>(j)]) / k;
    mu += d[i] / static_cast<double>(pts.size());
  }
  double var = 0;
  for (double x : d) var += (x - mu) * (x - mu) / static_cast<double>(pts.size());
  int removed = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    EXPECT_EQ(keep[i], std::abs(d[i] - mu) <= std::sqrt(var) + 1e-9) << i;
    removed += !keep[i];
  }
  EXPECT_GT(removed, 0);
}

TEST(OutlierRemoval, MatchesAPlainPassForAnyRowLengthAndCount) {
  // The mask sums four rows at a time, four square roots per step: k not a multiple of
  // four, a graph wider than k, a point count not a multiple of four and rows short of
  // k neighbours must all give what one plain pass over the rows gives.
  // A jittered 1 cm lattice (mean neighbour distances close together) with every 50th
  // point lifted off it.
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> jitter(-0.001f, 0.001f);
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 2003; ++i) {
    pts.emplace_back(0.01f * static_cast<float>(i % 45) + jitter(rng), 0.01f * static_cast<float>(i / 45) + jitter(rng),
                     (i % 50 == 7 ? 0.03f : 0.f) + jitter(rng));
  }
  for (const auto& [graph_k, k] : std::vector<std::pair<int, int>>{{9, 7}, {16, 16}, {5, 3}, {12, 10}}) {
    KnnGraph g = bruteForceKnnGraph(pts, graph_k);
    for (std::size_t i = 5; i < pts.size(); i += 41) g.count[i] = k - 1;  // too few neighbours
    const auto keep = statisticalOutlierMask(g, 1.5, k);
    std::vector<double> mean(pts.size(), 0.0);
    double sum = 0, sum2 = 0;
    std::size_t m = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      if (g.count[i] < k) continue;
      double d = 0;
      for (int j = 0; j < k; ++j) d += std::sqrt(g.sq_dist[i * static_cast<std::size_t>(graph_k) + static_cast<std::size_t>(j)]);
      mean[i] = d / k;
      sum += mean[i];
      sum2 += mean[i] * mean[i];
      ++m;
    }
    const double mu = sum / static_cast<double>(m);
    const double sigma = std::sqrt(std::max(0.0, sum2 / static_cast<double>(m) - mu * mu));
    int removed = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      EXPECT_EQ(keep[i], g.count[i] >= k && std::abs(mean[i] - mu) <= 1.5 * sigma + 1e-12) << "k " << k << " point " << i;
      removed += !keep[i];
    }
    EXPECT_GT(removed, 49) << k;  // the short rows and some outliers
  }
}

TEST(Normals, SphereNormalsPointRadiallyTowardsTheViewpoint) {
  // Points on a sphere of radius 0.5 around (0, 0, 2), viewed from the origin.
  std::vector<Eigen::Vector3f> pts;
  const Eigen::Vector3f c(0, 0, 2);
  for (double th = 0.2; th < 1.2; th += 0.02) {
    for (double ph = 0; ph < 2 * M_PI; ph += 0.02 / std::sin(th)) {
      pts.push_back(c + 0.5f * Eigen::Vector3f(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), -std::cos(th)).cast<float>());
    }
  }
  const KnnGraph g = buildKnnGraph(pts, 12, 0.03f, 1.f);
  std::vector<Eigen::Vector3f> n;
  std::vector<float> curv;
  estimateNormals(pts, g, Eigen::Vector3f::Zero(), n, curv);
  double worst = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Eigen::Vector3f radial = (pts[i] - c).normalized();  // faces the viewpoint on this cap
    worst = std::max(worst, std::acos(std::min(1.0, static_cast<double>(n[i].dot(radial)))) / kDeg);
  }
  // Neighbourhood of ~2 cm on a 0.5 m sphere: the PCA normal is the radial direction
  // up to the sampling asymmetry at the cap's rim (a few degrees).
  EXPECT_LT(worst, 3.0);
}

TEST(Normals, PcaEqualsBruteForceEigenvector) {
  const auto pts = randomCloud(500, 4);
  const KnnGraph g = bruteForceKnnGraph(pts, 10);
  std::vector<Eigen::Vector3f> n;
  std::vector<float> curv;
  estimateNormals(pts, g, Eigen::Vector3f(0, 0, 5), n, curv);
  for (std::size_t i = 0; i < pts.size(); i += 7) {
    Eigen::MatrixXd a(11, 3);
    a.row(0) = pts[i].cast<double>().transpose();
    for (int j = 0; j < 10; ++j) a.row(j + 1) = pts[static_cast<std::size_t>(g.indices[i * 10 + static_cast<std::size_t>(j)])].cast<double>().transpose();
    const Eigen::MatrixXd centred = a.rowwise() - a.colwise().mean();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(centred.transpose() * centred / 11.0);
    Eigen::Vector3d ref = es.eigenvectors().col(0);
    if (ref.dot(Eigen::Vector3d(0, 0, 5) - pts[i].cast<double>()) < 0) ref = -ref;
    EXPECT_GT(ref.dot(n[i].cast<double>()), 0.9999) << i;
    EXPECT_NEAR(curv[i], es.eigenvalues()(0) / es.eigenvalues().sum(), 1e-4);
  }
}

// The smoothing passes' fast path (inverse iteration from a nearby normal) against the
// closed-form eigenvectors on the same neighbourhoods, started 10 degrees off.
TEST(Normals, InverseIterationFromANearbyNormalEqualsTheExactEigenvector) {
  const auto pts = randomCloud(3000, 9);
  const KnnGraph g = bruteForceKnnGraph(pts, 30);
  std::vector<Eigen::Vector3f> exact, fast, exact_proj, fast_proj;
  std::vector<float> exact_curv, fast_curv;
  estimateNormals(pts, g, Eigen::Vector3f(0, 0, 5), exact, exact_curv, &exact_proj);
  std::mt19937 rng(3);
  std::normal_distribution<float> gauss;
  std::vector<Eigen::Vector3f> near(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    // Tilt by 10 degrees about a random axis perpendicular to the normal.
    const Eigen::Vector3f axis = exact[i].cross(Eigen::Vector3f(gauss(rng), gauss(rng), gauss(rng))).normalized();
    near[i] = Eigen::AngleAxisf(static_cast<float>(10 * kDeg), axis) * exact[i];
  }
  estimateNormals(pts, g, Eigen::Vector3f(0, 0, 5), fast, fast_curv, &fast_proj, &near);
  std::vector<double> planar_angles;
  double worst_shift = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const double angle = std::acos(std::min(1.0, static_cast<double>(exact[i].dot(fast[i])))) / kDeg;
    if (exact_curv[i] < 0.05) planar_angles.push_back(angle);  // a well-defined plane
    EXPECT_LT(angle, 0.05) << i << " curvature " << exact_curv[i];
    EXPECT_NEAR(fast_curv[i], exact_curv[i], 1e-4) << i;
    worst_shift = std::max(worst_shift, static_cast<double>((fast_proj[i] - exact_proj[i]).norm()));
  }
  ASSERT_GT(planar_angles.size(), pts.size() / 2);
  EXPECT_LT(*std::max_element(planar_angles.begin(), planar_angles.end()), 0.05);
  EXPECT_LT(worst_shift, 1e-5);  // metres
  std::printf("[ info ] worst angle on planes %.2g deg, worst projection shift %.2g m\n",
              *std::max_element(planar_angles.begin(), planar_angles.end()), worst_shift);
}

// The pipeline's first normals pass starts the iteration from the direction to the
// camera. Surfaces seen nearly edge-on (a floor out to 6 m below a camera 1.2 m up, a
// wall along the optical axis) start almost orthogonal to their normal: the result must
// still be the closed-form eigenvector, through more steps or the fallback.
TEST(Normals, InverseIterationFromTheViewDirectionEqualsTheExactEigenvector) {
  std::mt19937 rng(17);
  std::normal_distribution<float> noise(0.f, 0.002f);
  std::vector<Eigen::Vector3f> pts;
  for (float z = 0.6f; z < 6.f; z += 0.04f) {
    for (float x = -0.3f; x < 0.3f; x += 0.04f) pts.emplace_back(x, 1.2f + noise(rng), z);  // floor
    for (float y = -0.3f; y < 0.3f; y += 0.04f) pts.emplace_back(0.8f + noise(rng), y, z);  // wall
  }
  const KnnGraph g = bruteForceKnnGraph(pts, 20);
  std::vector<Eigen::Vector3f> exact, fast, exact_proj, fast_proj, towards(pts.size());
  std::vector<float> exact_curv, fast_curv;
  for (std::size_t i = 0; i < pts.size(); ++i) towards[i] = -pts[i].normalized();
  estimateNormals(pts, g, Eigen::Vector3f::Zero(), exact, exact_curv, &exact_proj);
  estimateNormals(pts, g, Eigen::Vector3f::Zero(), fast, fast_curv, &fast_proj, &towards);
  double worst_angle = 0, worst_shift = 0, most_orthogonal = 1;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    worst_angle = std::max(worst_angle, std::acos(std::min(1.0, static_cast<double>(exact[i].dot(fast[i])))) / kDeg);
    worst_shift = std::max(worst_shift, static_cast<double>((fast_proj[i] - exact_proj[i]).norm()));
    most_orthogonal = std::min(most_orthogonal, std::abs(static_cast<double>(exact[i].dot(towards[i]))));
    EXPECT_NEAR(fast_curv[i], exact_curv[i], 1e-4) << i;
  }
  EXPECT_LT(most_orthogonal, 0.15);  // the scene does hold near edge-on views
  EXPECT_LT(worst_angle, 0.05);
  EXPECT_LT(worst_shift, 1e-5);  // metres
  std::printf("[ info ] start as little as cos %.3f from the normal; worst angle %.2g deg, shift %.2g m\n",
              most_orthogonal, worst_angle, worst_shift);
}

// The iteration multiplies by adj(C)^4, whose entries scale with the sixteenth power of
// the neighbourhood's size: from a tenth of a millimetre (entries below 1e-60 here) to a
// hundred metres (a cloud in millimetres read as metres) it must still find the
// closed-form eigenvector, with every instruction set.
TEST(Normals, InverseIterationHoldsFromSubMillimetreToHundredMetreNeighbourhoods) {
  const auto base = randomCloud(1001, 21);  // ~1 m across, neighbourhoods ~0.1 m
  const KnnGraph g = bruteForceKnnGraph(base, 12);
  for (const float scale : {1e-3f, 1e-1f, 1.f, 1e2f}) {
    std::vector<Eigen::Vector3f> pts(base.size());
    for (std::size_t i = 0; i < pts.size(); ++i) pts[i] = base[i] * scale;
    const Eigen::Vector3f viewpoint(0, 0, 5 * scale);
    std::vector<Eigen::Vector3f> exact, proj;
    std::vector<float> curv;
    {
      const ScopedSimd portable(Simd::kPortable);
      estimateNormals(pts, g, viewpoint, exact, curv, &proj, nullptr);
    }
    std::vector<Eigen::Vector3f> near(pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i) {
      near[i] = Eigen::AngleAxisf(static_cast<float>(10 * kDeg), exact[i].unitOrthogonal()) * exact[i];
    }
    for (Simd simd : simdChoices()) {
      const ScopedSimd use(simd);
      std::vector<Eigen::Vector3f> fast, fast_proj;
      std::vector<float> fast_curv;
      estimateNormals(pts, g, viewpoint, fast, fast_curv, &fast_proj, &near);
      double worst_angle = 0, worst_shift = 0, worst_curv = 0;
      for (std::size_t i = 0; i < pts.size(); ++i) {
        worst_angle = std::max(worst_angle, std::acos(std::min(1.0, static_cast<double>(exact[i].dot(fast[i])))) / kDeg);
        worst_shift = std::max(worst_shift, static_cast<double>((fast_proj[i] - proj[i]).norm()) / scale);
        worst_curv = std::max(worst_curv, static_cast<double>(std::abs(fast_curv[i] - curv[i])));
      }
      EXPECT_LT(worst_angle, 0.05) << "scale " << scale << " " << toString(simd);
      EXPECT_LT(worst_shift, 1e-5) << "scale " << scale << " " << toString(simd);  // in units of the scale
      EXPECT_LT(worst_curv, 1e-4) << "scale " << scale << " " << toString(simd);
    }
  }
}

// The vector normals must be the portable loop's to the last bit, for every outcome a
// lane can have: the closed-form solver (no start), inverse iteration converging,
// failing (a start orthogonal to the normal, a zero start, a line with no plane) and
// too few neighbours; on noisy sheets, exact lattices (planes with tied covariances)
// and point counts that leave a partial block of eight.
TEST(Normals, EveryInstructionSetGivesThePortableBits) {
  std::vector<std::vector<Eigen::Vector3f>> clouds = {randomCloud(1001, 21)};
  std::vector<Eigen::Vector3f> lattice, line;
  for (int i = 0; i < 20; ++i) {
    for (int j = 0; j < 19; ++j) lattice.emplace_back(0.01f * i, 0.01f * j, 1.f + 0.005f * i);
  }
  for (int i = 0; i < 40; ++i) line.emplace_back(0.01f * i, 0.f, 2.f);
  line.emplace_back(5.f, 5.f, 5.f);  // alone: no neighbours within the radius
  clouds.push_back(lattice);
  clouds.push_back(line);
  for (std::size_t c = 0; c < clouds.size(); ++c) {
    const auto& pts = clouds[c];
    const KnnGraph g = buildKnnGraph(pts, 12, 0.03f, 0.5f);
    std::vector<Eigen::Vector3f> ref_n, ref_p;
    std::vector<float> ref_c;
    {
      const ScopedSimd portable(Simd::kPortable);
      estimateNormals(pts, g, Eigen::Vector3f(0, 0, 5), ref_n, ref_c, &ref_p, nullptr);
    }
    // Starts: the normals themselves, 20 degrees off, orthogonal to them, zero.
    std::vector<Eigen::Vector3f> near(pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const Eigen::Vector3f side = ref_n[i].unitOrthogonal();
      switch (i % 4) {
        case 0: near[i] = ref_n[i]; break;
        case 1: near[i] = Eigen::AngleAxisf(static_cast<float>(20 * kDeg), side) * ref_n[i]; break;
        case 2: near[i] = side; break;
        default: near[i] = Eigen::Vector3f::Zero();
      }
    }
    std::vector<Eigen::Vector3f> ref_nn, ref_np;
    std::vector<float> ref_nc;
    {
      const ScopedSimd portable(Simd::kPortable);
      estimateNormals(pts, g, Eigen::Vector3f(0, 0, 5), ref_nn, ref_nc, &ref_np, &near);
    }
    for (Simd simd : simdChoices()) {
      const ScopedSimd use(simd);
      std::vector<Eigen::Vector3f> n, p;
      std::vector<float> curv;
      estimateNormals(pts, g, Eigen::Vector3f(0, 0, 5), n, curv, &p, nullptr);
      EXPECT_EQ(n, ref_n) << "cloud " << c << " " << toString(simd);
      EXPECT_EQ(curv, ref_c) << "cloud " << c << " " << toString(simd);
      EXPECT_EQ(p, ref_p) << "cloud " << c << " " << toString(simd);
      estimateNormals(pts, g, Eigen::Vector3f(0, 0, 5), n, curv, &p, &near);
      EXPECT_EQ(n, ref_nn) << "cloud " << c << " " << toString(simd) << " with starts";
      EXPECT_EQ(curv, ref_nc) << "cloud " << c << " " << toString(simd) << " with starts";
      EXPECT_EQ(p, ref_np) << "cloud " << c << " " << toString(simd) << " with starts";
      std::vector<float> no_projection_curv;
      estimateNormals(pts, g, Eigen::Vector3f(0, 0, 5), n, no_projection_curv, nullptr, &near);
      EXPECT_EQ(no_projection_curv, ref_nc) << "cloud " << c << " " << toString(simd) << " without projection";
    }
    // The lone point and the line's points have no plane; the lattice is exactly planar.
    if (c == 2) {
      EXPECT_EQ(ref_n.back(), Eigen::Vector3f::Zero());
      EXPECT_EQ(ref_c.back(), 1.f);
    }
  }
}

// Rough segments in coarse voxels are projected with fewer neighbours than the normals
// use: the first k of each row of the wide graph must give what a k-graph gives.
TEST(Normals, ProjectionOnTheFirstKNeighboursEqualsTheProjectionOfAKGraph) {
  const auto pts = randomCloud(2000, 5);
  const KnnGraph wide = buildKnnGraph(pts, 30, 0.05f, 1.f);
  const KnnGraph narrow = bruteForceKnnGraph(pts, 7);
  std::vector<Eigen::Vector3f> n, reference;
  std::vector<float> curv;
  estimateNormals(pts, narrow, Eigen::Vector3f(0, 0, 5), n, curv, &reference);
  std::vector<int> which;
  for (int i = 0; i < static_cast<int>(pts.size()); i += 3) which.push_back(i);
  std::vector<Eigen::Vector3f> projected = pts;
  projectOntoLocalPlanes(pts, wide, 7, which, projected);
  std::size_t moved = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (i % 3 == 0) {
      EXPECT_LT((projected[i] - reference[i]).norm(), 1e-6f) << i;
      moved += (projected[i] - pts[i]).norm() > 1e-4f;
    } else {
      EXPECT_EQ(projected[i], pts[i]) << i << " is not in `which`";
    }
  }
  EXPECT_GT(moved, which.size() / 2);  // a random cloud is not planar: the projection moves points
}

TEST(RgbN, PerCloudMinMaxNormalisation) {
  const std::vector<Eigen::Vector3f> n = {{0, 0, 1}, {0.6f, 0, 0.8f}, {-0.6f, 0.8f, 0}};
  const auto c = normalColours(n);
  EXPECT_EQ(c[2][0], 0);    // min x
  EXPECT_EQ(c[1][0], 255);  // max x
  EXPECT_EQ(c[0][0], 128);  // (0 - -0.6) / 1.2
  EXPECT_EQ(c[0][1], 0);
  EXPECT_EQ(c[2][1], 255);
  EXPECT_EQ(c[0][2], 255);
  EXPECT_EQ(c[2][2], 0);
}

TEST(RgbN, YCrCbOfKnownColours) {
  const Eigen::Vector3f white = rgbToYCrCb({255, 255, 255});
  EXPECT_NEAR(white.x(), 255, 0.01);
  EXPECT_NEAR(white.y(), 128, 0.01);
  EXPECT_NEAR(white.z(), 128, 0.01);
  const Eigen::Vector3f red = rgbToYCrCb({255, 0, 0});
  EXPECT_NEAR(red.x(), 76.245, 0.01);
  EXPECT_NEAR(red.y(), 128 + 0.713 * (255 - 76.245), 0.01);
}

// The top and side of a box joined by a rounded edge (radius 15 cm), with exact
// normals: across the edge the normal turns 90 degrees in ~4-degree steps, each well
// under the colour threshold, as PCA normals do across a sharp crease.
TEST(RegionGrowing, TheMeanNormalGateStopsARegionAtARoundedEdge) {
  std::vector<Eigen::Vector3f> pts, normals;
  const float r = 0.15f, step = 0.01f;
  std::vector<int> face;  // 0 top, 1 edge, 2 side
  for (float y = 0; y < 0.3f; y += step) {
    for (float x = -0.3f; x < 0; x += step) {  // top: z = 0, normal +z
      pts.emplace_back(x, y, 0.f), normals.emplace_back(0.f, 0.f, 1.f), face.push_back(0);
    }
    for (float s = 0; s < 0.5f * static_cast<float>(M_PI) * r; s += step) {  // the rounded edge
      const float t = s / r;
      pts.emplace_back(r * std::sin(t), y, -r + r * std::cos(t));
      normals.emplace_back(std::sin(t), 0.f, std::cos(t)), face.push_back(1);
    }
    for (float z = -r; z > -r - 0.3f; z -= step) {  // side: x = r, normal +x
      pts.emplace_back(r, y, z), normals.emplace_back(1.f, 0.f, 0.f), face.push_back(2);
    }
  }
  const KnnGraph g = bruteForceKnnGraph(pts, 16);
  const auto colours = normalColours(normals);
  const std::vector<bool> eligible(pts.size(), true);
  const auto regionOf = [&](double gate_deg) {
    int regions = 0;
    return growRegions(pts, colours, g, eligible, 12.0, 0.025, 1, &regions, &normals, gate_deg);
  };
  const auto majority = [&](const std::vector<int>& labels, int f) {
    std::map<int, int> votes;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      if (face[i] == f) ++votes[labels[i]];
    }
    return std::max_element(votes.begin(), votes.end(), [](auto& a, auto& b) { return a.second < b.second; })->first;
  };
  // The paper's neighbour-to-neighbour colour test alone: one region over both faces.
  const auto open = regionOf(180.0);
  EXPECT_EQ(majority(open, 0), majority(open, 2));
  // With the gate: top and side are separate regions, each face whole, and no point
  // more than 40 degrees (plus the region's own drift) from the face it joined.
  const auto gated = regionOf(40.0);
  const int top = majority(gated, 0), side = majority(gated, 2);
  EXPECT_NE(top, side);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (face[i] == 0) {
      EXPECT_EQ(gated[i], top);
    }
    if (face[i] == 2) {
      EXPECT_EQ(gated[i], side);
    }
    if (gated[i] == top) {
      EXPECT_GT(normals[i].z(), std::cos(50 * kDeg));
    }
    if (gated[i] == side) {
      EXPECT_GT(normals[i].x(), std::cos(50 * kDeg));
    }
  }
}

TEST(Ransac, AdaptiveIterationsFindThePlaneAndRespectGravity) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 3000; ++i) pts.emplace_back(u(rng), 1.2f, 2 + u(rng));          // floor y = 1.2 (camera frame)
  for (int i = 0; i < 6000; ++i) pts.emplace_back(u(rng), u(rng), 3.0f);              // a wall twice as big
  for (int i = 0; i < 1000; ++i) pts.emplace_back(u(rng), u(rng), 2 + u(rng));        // clutter
  std::vector<int> all(pts.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  RansacOptions o;
  auto largest = ransacPlane(pts, all, o, rng);
  ASSERT_TRUE(largest);
  EXPECT_NEAR(std::abs(largest->plane(2)), 1.0, 1e-3);  // without gravity: the wall (paper's limitation)
  // Eq. 6 with w = 0.6: N = log(0.01) / log(1 - 0.216) = 18.9; allow for the ramp-up.
  EXPECT_LT(largest->iterations, 100);
  o.required_normal = Eigen::Vector3f(0, -1, 0);  // "up" in the camera frame
  auto floor = ransacPlane(pts, all, o, rng);
  ASSERT_TRUE(floor);
  EXPECT_NEAR(std::abs(floor->plane(1)), 1.0, 1e-3);
  EXPECT_NEAR(std::abs(floor->plane(3)), 1.2, 1e-3);
  EXPECT_NEAR(static_cast<double>(floor->inliers.size()), 3000, 60);
}

// ransacPlane judges planes on copies of the points laid out for vector loops; its
// inliers must still be exactly the points the plain rule accepts: |n.p + d| <= the
// distance and |n.normal| >= the (double) cosine, with Eigen's dot. A tilted plane
// with pairs of points mirrored about it, so the fitted plane is that plane to within
// rounding and the pairs lie within a few rounding errors of both thresholds: summing
// the dot in another order or rounding the cosine to the nearest float changes the
// inliers. Each instruction set must find the same plane, inliers and iteration count
// (20,000 points: the vector loops end on a partial vector).
TEST(Ransac, InliersAreExactlyThePointsThePlainRuleAccepts) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1, 1), jitter(-1, 1);
  const Eigen::Vector3f n0 = Eigen::Vector3f(0.3f, -0.9f, 0.2f).normalized();
  const Eigen::Vector3f e1 = n0.unitOrthogonal(), e2 = n0.cross(e1);
  const Eigen::Vector3f centre(0.4f, 0.7f, 2.3f);
  const double tolerance_deg = 30.0;  // the float nearest cos 30 degrees is below it
  const float dist = 0.02f;
  std::vector<Eigen::Vector3f> pts, normals;
  // The plane itself, every hypothesis drawn from it; its normals lean the tolerance
  // (give or take a rounding error) towards random directions.
  for (int i = 0; i < 10000; ++i) {
    pts.push_back(centre + u(rng) * e1 + u(rng) * e2);
    const Eigen::Vector3f axis = (u(rng) * e1 + u(rng) * e2).normalized();
    const double tilt = tolerance_deg + 1e-5 * jitter(rng);
    normals.push_back(Eigen::AngleAxisf(static_cast<float>(tilt * kDeg), axis) * n0);
  }
  for (int i = 0; i < 5000; ++i) {  // mirrored pairs at the distance threshold
    const Eigen::Vector3f q = centre + u(rng) * e1 + u(rng) * e2;
    const float off = dist + 3e-7f * jitter(rng);
    for (const float side : {1.f, -1.f}) {
      pts.push_back(q + side * off * n0);
      normals.push_back(n0);
    }
  }
  std::vector<int> all(pts.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  for (const bool with_normals : {false, true}) {
    for (const std::size_t sample : {std::size_t{0}, std::size_t{4096}}) {
      RansacOptions o;
      o.distance_m = dist;
      o.score_sample = sample;
      if (with_normals) {
        o.point_normals = &normals;
        o.normal_tolerance_deg = tolerance_deg;
      }
      std::mt19937 r(3);
      const auto fit = [&] {
        const ScopedSimd portable(Simd::kPortable);
        return ransacPlane(pts, all, o, r);
      }();
      ASSERT_TRUE(fit);
      for (const Simd simd : simdChoices()) {
        const ScopedSimd use(simd);
        std::mt19937 r_simd(3);
        const auto same = ransacPlane(pts, all, o, r_simd);
        ASSERT_TRUE(same) << toString(simd);
        EXPECT_EQ(same->plane, fit->plane) << toString(simd);
        EXPECT_EQ(same->inliers, fit->inliers) << toString(simd);
        EXPECT_EQ(same->iterations, fit->iterations) << toString(simd);
      }
      const Eigen::Vector3f n = fit->plane.head<3>();
      const double cos_normal = std::cos(tolerance_deg * M_PI / 180.0);
      std::vector<int> expected;
      for (int i : all) {
        const auto k = static_cast<std::size_t>(i);
        if (std::abs(n.dot(pts[k]) + fit->plane(3)) > dist) continue;
        if (with_normals && std::abs(n.dot(normals[k])) < cos_normal) continue;
        expected.push_back(i);
      }
      EXPECT_EQ(fit->inliers, expected) << "normals " << with_normals << ", score sample " << sample;
      // The thresholds cut through the point set: both sides are populated.
      EXPECT_GT(expected.size(), pts.size() / 10);
      EXPECT_LT(expected.size(), pts.size() * 9 / 10);
    }
  }
}

TEST(GroundReclaim, TheFootOfAGentleRampGoesBackToTheRamp) {
  // Floor z = 0 for x < 1, a 5 degree ramp from x = 1 to 1.6, sampled every cm.
  const float t5 = static_cast<float>(std::tan(5 * kDeg));
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i <= 160; ++i) {
    for (int j = 0; j <= 60; ++j) {
      const float x = 0.01f * static_cast<float>(i);
      pts.emplace_back(x, 0.01f * static_cast<float>(j), x > 1.f ? (x - 1.f) * t5 : 0.f);
    }
  }
  const KnnGraph g = buildKnnGraph(pts, 30, 0.04f, 0.2f);
  const Eigen::Vector4f ground(0, 0, 1, 0);
  std::vector<bool> is_ground(pts.size());
  std::vector<int> labels(pts.size(), -1);
  std::vector<int> ramp, fragment;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    is_ground[i] = pts[i].z() <= 0.02f;  // what RANSAC with a 2 cm threshold takes
    if (!is_ground[i]) {
      labels[i] = 0;
      ramp.push_back(static_cast<int>(i));
    }
  }
  // A second region lying on the floor itself: parallel to the ground, it takes nothing.
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (pts[i].x() < 0.1f) {
      is_ground[i] = false;
      labels[i] = 1;
      fragment.push_back(static_cast<int>(i));
    }
  }
  const std::vector<Eigen::Vector4f> planes = {leastSquaresPlane(pts, ramp), Eigen::Vector4f(0, 0, 1, 0)};
  const std::size_t moved = reclaimGroundPoints(pts, g, 0.025, ground, planes, 3.0, 30.0, 0.02, labels, is_ground);
  std::size_t expected = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const float x = pts[i].x();
    if (x < 0.1f) {
      EXPECT_EQ(labels[i], 1) << i;
    } else if (x > 1.005f) {  // every ramp point, including its foot
      EXPECT_EQ(labels[i], 0) << "x " << x;
      EXPECT_FALSE(is_ground[i]);
      expected += pts[i].z() <= 0.02f;
    } else {  // the floor stays ground
      EXPECT_TRUE(is_ground[i]) << "x " << x;
      EXPECT_EQ(labels[i], -1);
    }
  }
  EXPECT_EQ(moved, expected);
  EXPECT_GT(moved, 60u * 20);
}

TEST(GroundReclaim, FloorBesideARampsFootKeepsItsFloorNormal) {
  // A 15-degree ramp 30 cm wide from x = 1 on a floor 1.3 m wide with +-4 mm noise.
  // Along the line where the ramp's plane meets the floor, extended sideways past the
  // ramp's edges, noisy floor points are as close to the ramp's plane as to the
  // floor's, and the walk from the ramp spreads along it. Their normals (up) keep
  // them floor; the ramp's own foot (ramp normals) is still taken back.
  const float t15 = static_cast<float>(std::tan(15 * kDeg));
  const Eigen::Vector3f up(0, 0, 1), ramp_n = Eigen::Vector3f(-t15, 0, 1).normalized();
  std::vector<Eigen::Vector3f> pts, normals;
  std::vector<bool> is_ground;
  std::vector<int> labels;
  for (int i = 80; i <= 140; ++i) {
    for (int j = -50; j <= 80; ++j) {
      const float x = 0.01f * static_cast<float>(i), y = 0.01f * static_cast<float>(j);
      const bool on_ramp = x > 1.f && j >= 0 && j <= 30;
      const float noise = (i + j) % 2 != 0 ? 0.004f : -0.004f;
      const float z = on_ramp ? (x - 1.f) * t15 : noise;
      pts.emplace_back(x, y, z);
      normals.push_back(on_ramp ? ramp_n : up);
      is_ground.push_back(z <= 0.02f);
      labels.push_back(z <= 0.02f ? -1 : 0);
    }
  }
  const KnnGraph g = bruteForceKnnGraph(pts, 30);
  const std::vector<Eigen::Vector4f> planes = {Eigen::Vector4f(-t15, 0, 1, t15).normalized()};
  auto labels_plain = labels;
  auto ground_plain = is_ground;
  reclaimGroundPoints(pts, g, 0.025, Eigen::Vector4f(0, 0, 1, 0), planes, 3.0, 30.0, 0.02, labels_plain, ground_plain);
  std::size_t floor_taken_plain = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) floor_taken_plain += normals[i] == up && labels_plain[i] == 0;
  EXPECT_GT(floor_taken_plain, 10u);  // the leak the normals stop
  reclaimGroundPoints(pts, g, 0.025, Eigen::Vector4f(0, 0, 1, 0), planes, 3.0, 30.0, 0.02, labels, is_ground, &normals);
  std::size_t foot = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (normals[i] == up) {
      EXPECT_EQ(labels[i], -1) << pts[i].transpose();
      EXPECT_TRUE(is_ground[i]);
    } else {
      EXPECT_EQ(labels[i], 0) << pts[i].transpose();  // the whole ramp, foot included
      foot += pts[i].z() <= 0.02f;
    }
  }
  EXPECT_GT(foot, 31u * 5);
}

TEST(GroundReclaim, UnderNoiseTheRampsFootprintDecidesWhereThePlanesCannot) {
  // A 5-degree ramp 40 cm wide from x = 1 on a floor, every height with +-5 mm of noise
  // and every normal tilted 6 degrees in a random direction: in the ramp's first
  // ~10 cm neither the distances to the two planes nor the normals tell ramp from
  // floor. The ramp's footprint does: beyond the line where its plane meets the floor,
  // between its sides, the floor cannot be (there the ramp hides it).
  const float t5 = static_cast<float>(std::tan(5 * kDeg));
  const Eigen::Vector3f up(0, 0, 1), ramp_n = Eigen::Vector3f(-t5, 0, 1).normalized();
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> height_noise(-0.005f, 0.005f), turn(0.f, static_cast<float>(2 * M_PI));
  std::vector<Eigen::Vector3f> pts, normals;
  std::vector<bool> is_ground, truly_ramp;
  std::vector<int> labels;
  for (int i = 60; i <= 160; ++i) {
    for (int j = -50; j <= 50; ++j) {
      const float x = 0.01f * static_cast<float>(i), y = 0.01f * static_cast<float>(j);
      const bool on_ramp = x > 1.f && std::abs(y) <= 0.2f + 1e-4f;
      const float z = (on_ramp ? (x - 1.f) * t5 : 0.f) + height_noise(rng);
      pts.emplace_back(x, y, z);
      const Eigen::Vector3f n = on_ramp ? ramp_n : up;
      const Eigen::Vector3f side = n.cross(Eigen::Vector3f::UnitY()).normalized();
      const Eigen::Vector3f across = n.cross(side);
      const float a = turn(rng);
      const float tilt = static_cast<float>(6 * kDeg);
      normals.push_back((n * std::cos(tilt) + (side * std::cos(a) + across * std::sin(a)) * std::sin(tilt)).normalized());
      truly_ramp.push_back(on_ramp);
      is_ground.push_back(z <= 0.02f);  // RANSAC's 2 cm band: the ramp's first ~23 cm
      labels.push_back(z <= 0.02f ? -1 : 0);
    }
  }
  std::vector<int> ramp;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (labels[i] == 0) ramp.push_back(static_cast<int>(i));
  }
  const std::vector<Eigen::Vector4f> planes = {leastSquaresPlane(pts, ramp)};
  const KnnGraph g = buildKnnGraph(pts, 30, 0.04f, 0.2f);
  // A rough region (its plane only a mean) gets no footprint: the earlier tests alone.
  auto labels_rough = labels;
  auto ground_rough = is_ground;
  const std::vector<bool> rough = {true};
  reclaimGroundPoints(pts, g, 0.025, Eigen::Vector4f(0, 0, 1, 0), planes, 3.0, 30.0, 0.02, labels_rough, ground_rough,
                      &normals, &rough);
  reclaimGroundPoints(pts, g, 0.025, Eigen::Vector4f(0, 0, 1, 0), planes, 3.0, 30.0, 0.02, labels, is_ground, &normals);
  std::size_t far_ramp_rough = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) far_ramp_rough += truly_ramp[i] && pts[i].x() >= 1.1f && labels_rough[i] == 0;
  std::size_t far_ramp = 0, far_ramp_taken = 0, front = 0, front_kept = 0, beside = 0, beside_kept = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const float x = pts[i].x(), y = pts[i].y();
    const bool kept = is_ground[i] && labels[i] == -1;
    if (truly_ramp[i] && x >= 1.1f) {  // the ramp's plane at least 8.7 mm above the floor
      ++far_ramp;
      far_ramp_taken += labels[i] == 0;
    } else if (!truly_ramp[i] && x < 0.88f) {  // the floor in front: the ramp's plane >= 10 mm below it
      ++front;
      front_kept += kept;
    } else if (!truly_ramp[i] && std::abs(y) > 0.25f) {  // beside it: the distance and normal tests' part
      ++beside;
      beside_kept += kept;
    }
  }
  EXPECT_EQ(far_ramp_taken, far_ramp);  // 1886 of 2091 without the footprint
  EXPECT_LT(far_ramp_rough, far_ramp - 100);
  EXPECT_GT(far_ramp, 41u * 50);
  EXPECT_EQ(front_kept, front);
  EXPECT_GE(beside_kept, beside - beside / 200) << "of " << beside;
}

TEST(GroundReclaim, FloorAtTheBaseOfAWallStaysFloor) {
  // A floor with +-3 mm noise meeting a wall at x = 0.5: the row of floor points at the
  // wall's base is closer to the wall's plane than to the (noisy) floor, but a wall is
  // not a ramp, so nothing moves unless the angle limit lets walls in.
  std::vector<Eigen::Vector3f> pts;
  std::vector<int> labels;
  std::vector<bool> is_ground;
  for (int i = 0; i <= 50; ++i) {
    for (int j = 0; j <= 60; ++j) {
      pts.emplace_back(0.01f * static_cast<float>(i), 0.01f * static_cast<float>(j), (i + j) % 2 != 0 ? 0.003f : -0.003f);
      labels.push_back(-1);
      is_ground.push_back(true);
    }
  }
  for (int k = 2; k <= 50; ++k) {
    for (int j = 0; j <= 60; ++j) {
      pts.emplace_back(0.5f, 0.01f * static_cast<float>(j), 0.01f * static_cast<float>(k));
      labels.push_back(0);
      is_ground.push_back(false);
    }
  }
  const KnnGraph g = buildKnnGraph(pts, 30, 0.04f, 0.2f);
  const std::vector<Eigen::Vector4f> planes = {Eigen::Vector4f(1, 0, 0, -0.5f)};
  auto labels_steep = labels;
  auto ground_steep = is_ground;
  EXPECT_EQ(reclaimGroundPoints(pts, g, 0.025, Eigen::Vector4f(0, 0, 1, 0), planes, 3.0, 30.0, 0.02, labels, is_ground), 0u);
  // With walls allowed, the base row (x = 0.5, |z| = 3 mm > 0) moves: the limit is what
  // keeps it.
  EXPECT_EQ(reclaimGroundPoints(pts, g, 0.025, Eigen::Vector4f(0, 0, 1, 0), planes, 3.0, 90.0, 0.02, labels_steep,
                                ground_steep),
            61u);
}

// Tiles of a 1 cm grid, each its own region, with normals leaning `lean_deg` off the
// tiles' plane in alternating directions (the facets of a rough surface when large).
struct Tiles {
  std::vector<Eigen::Vector3f> points, normals;
  std::vector<int> labels;
};
Tiles tiles(int nx, int ny, int tile_cm_x, int tile_cm_y, double lean_deg, const Eigen::Matrix3f& rot = Eigen::Matrix3f::Identity()) {
  Tiles t;
  for (int i = 0; i < nx * tile_cm_x; ++i) {
    for (int j = 0; j < ny * tile_cm_y; ++j) {
      const int tile = (i / tile_cm_x) * ny + j / tile_cm_y;
      const double a = (tile % 2 ? 1 : -1) * lean_deg * kDeg;
      t.points.push_back(rot * Eigen::Vector3f(0.01f * i, 0.01f * j, 0.f));
      t.normals.push_back(rot * Eigen::Vector3f(static_cast<float>(std::sin(a)), 0.f, static_cast<float>(std::cos(a))));
      t.labels.push_back(tile);
    }
  }
  return t;
}
std::vector<int> merge(const Tiles& t, const std::optional<Eigen::Vector3f>& up, int* regions, std::vector<bool>* rough) {
  const KnnGraph g = bruteForceKnnGraph(t.points, 12);
  // min segment 50, fragments < 150 points or < 8 cm wide, groups of >= 3 fragments,
  // >= 100 points, >= 15 cm wide, normals >= 20 degrees off, <= 20 degrees from level.
  return mergeFragments(t.points, t.normals, g, 0.025, t.labels, 50, 150, 0.08, 3, 100, 0.15, 20.0, up, 20.0, regions, rough);
}

TEST(RoughMerge, ConnectedSteepFragmentsOfALevelSurfaceBecomeOneRoughRegion) {
  const Tiles t = tiles(3, 3, 10, 10, 45.0);  // 9 tiles of 100 points
  int regions = 0;
  std::vector<bool> rough;
  const auto labels = merge(t, Eigen::Vector3f::UnitZ(), &regions, &rough);
  ASSERT_EQ(regions, 1);
  EXPECT_EQ(rough, std::vector<bool>{true});
  for (int l : labels) EXPECT_EQ(l, 0);
}

TEST(RoughMerge, FragmentsOfASmoothSurfaceStaySeparate) {
  // Noise breaks a smooth floor into tiles whose normals lean only a few degrees.
  const Tiles t = tiles(3, 3, 10, 10, 5.0);
  int regions = 0;
  std::vector<bool> rough;
  const auto labels = merge(t, Eigen::Vector3f::UnitZ(), &regions, &rough);
  EXPECT_EQ(regions, 9);  // every tile has >= 50 points: each stays a region
  EXPECT_EQ(std::count(rough.begin(), rough.end(), true), 0);
  for (std::size_t i = 0; i < labels.size(); ++i) EXPECT_EQ(labels[i] >= 0, true);
}

TEST(RoughMerge, AStripAlongAnEdgeIsNotARoughSurface) {
  // Fragments along a crease: 6 tiles of 10 x 3 cm in a row, 60 x 3 cm in all.
  const Tiles t = tiles(6, 1, 10, 3, 45.0);
  int regions = 0;
  std::vector<bool> rough;
  const auto labels = merge(t, Eigen::Vector3f::UnitZ(), &regions, &rough);
  EXPECT_EQ(regions, 0);  // 30-point tiles are too small to stand alone
  for (int l : labels) EXPECT_EQ(l, -1);
}

TEST(RoughMerge, ASteepGroupIsNotRoughGroundUnlessLevelIsUnknown) {
  Eigen::Matrix3f rot = Eigen::AngleAxisf(static_cast<float>(50 * kDeg), Eigen::Vector3f::UnitX()).toRotationMatrix();
  const Tiles t = tiles(3, 3, 10, 10, 45.0, rot);
  int regions = 0;
  std::vector<bool> rough;
  merge(t, Eigen::Vector3f::UnitZ(), &regions, &rough);
  EXPECT_EQ(std::count(rough.begin(), rough.end(), true), 0);
  EXPECT_EQ(regions, 9);
  merge(t, std::nullopt, &regions, &rough);
  EXPECT_EQ(regions, 1);
  EXPECT_EQ(std::count(rough.begin(), rough.end(), true), 1);
}

// Two rough pieces of one surface cut apart by a 2 cm strip the ground took (a valley
// in the floor's RANSAC band), next to a smooth region: the strip goes to the rough
// pieces, which become one region; the smooth region stays apart.
TEST(RoughMerge, PiecesSeparatedByAGroundValleyBecomeOneRegion) {
  std::vector<Eigen::Vector3f> pts;
  std::vector<int> labels;
  std::vector<bool> ground;
  for (int x = 0; x < 40; ++x) {
    for (int y = 0; y < 10; ++y) {
      pts.emplace_back(0.01f * static_cast<float>(x), 0.01f * static_cast<float>(y), 0.f);
      const bool valley = x == 14 || x == 15;
      ground.push_back(valley);
      labels.push_back(valley ? -1 : x < 14 ? 0 : x < 30 ? 1 : 2);
    }
  }
  const KnnGraph g = bruteForceKnnGraph(pts, 16);
  std::vector<bool> rough = {true, true, false};
  int regions = 3;
  EXPECT_EQ(absorbGroundIntoRough(g, 0.025, rough, 0.5, 3, labels, ground), 20u);
  EXPECT_GT(joinTouchingRoughRegions(g, 0.025, rough, labels, &regions), 0);
  ASSERT_EQ(regions, 2);
  EXPECT_EQ(rough, (std::vector<bool>{true, false}));
  for (std::size_t i = 0; i < pts.size(); ++i) {
    EXPECT_FALSE(ground[i]);
    EXPECT_EQ(labels[i], pts[i].x() < 0.295f ? 0 : 1) << pts[i].transpose();
  }
}

// The floor's RANSAC band took a 2 cm strip out of a rough surface: the two halves,
// 10 cm wide each, are too narrow to pass as rough alone. Given the ground mask, the
// fragments on either side of the strip connect through it and form one rough region.
TEST(RoughMerge, FragmentsConnectAcrossOneGroundPoint) {
  Tiles t = tiles(4, 2, 5, 10, 45.0);  // 20 x 20 cm of 5 x 10 cm tiles
  std::vector<bool> ground(t.points.size(), false);
  for (std::size_t i = 0; i < t.points.size(); ++i) {
    const int row = static_cast<int>(std::lround(t.points[i].y() * 100));
    if (row == 9 || row == 10) {
      ground[i] = true;  // the strip: no region
      t.labels[i] = -1;
    }
  }
  const KnnGraph g = bruteForceKnnGraph(t.points, 12);
  for (const bool bridged : {false, true}) {
    int regions = 0;
    std::vector<bool> rough;
    const auto labels = mergeFragments(t.points, t.normals, g, 0.025, t.labels, 50, 150, 0.08, 3, 100, 0.15, 20.0,
                                       Eigen::Vector3f::UnitZ(), 20.0, &regions, &rough, bridged ? &ground : nullptr);
    if (!bridged) {
      EXPECT_EQ(regions, 0);  // each half is a strip 18 x 9 cm: not rough, and its tiles are too small
      continue;
    }
    ASSERT_EQ(regions, 1);
    EXPECT_EQ(rough, std::vector<bool>{true});
    for (std::size_t i = 0; i < labels.size(); ++i) EXPECT_EQ(labels[i], ground[i] ? -1 : 0) << i;
  }
}

// A floor region (z = 0) and a wall region (x = 0.3 m) on a 1 cm grid, with a band of
// floor points region growing left out, and around it the cases that must stay out.
TEST(Adoption, UnsegmentedPointsJoinTheRegionWhosePlaneTheyLieOn) {
  struct Case {
    std::vector<Eigen::Vector3f> pts, normals;
    std::vector<int> labels;
    std::vector<bool> ground;
  };
  auto build = [](bool reversed) {
    Case c;
    auto add = [&](float x, float y, float z, Eigen::Vector3f n, int label, bool ground = false) {
      c.pts.emplace_back(x, y, z);
      c.normals.push_back(n.normalized());
      c.labels.push_back(label);
      c.ground.push_back(ground);
    };
    const Eigen::Vector3f up(0, 0, 1), tilted(std::sin(60 * kDeg), 0, std::cos(60 * kDeg));
    for (int y = 0; y < 10; ++y) {
      const float fy = 0.01f * static_cast<float>(y);
      for (int x = 0; x < 30; ++x) {
        const float fx = 0.01f * static_cast<float>(x);
        if (x >= 10 && x < 15) {  // the left-out band
          if (x == 12 && y == 5) add(fx, fy, 0.03f, up, -1);         // 3 cm above the plane
          else if (x == 13 && y == 5) add(fx, fy, 0.f, tilted, -1);  // normal 60 degrees off
          else if (x == 11 && y == 2) add(fx, fy, 0.f, up, -1, true);  // ground: never moves
          else add(fx, fy, 0.f, up, -1);
        } else if (x >= 25) {
          add(fx, fy, 0.f, up, 2);  // a rough region on the same plane: takes nothing
        } else if (x >= 20 && x < 25) {
          add(fx, fy, 0.f, up, -1);  // left out between the floor and the rough region
        } else {
          add(fx, fy, 0.f, up, 0);
        }
      }
      for (int z = 1; z < 10; ++z) add(0.305f, fy, 0.01f * static_cast<float>(z), Eigen::Vector3f::UnitX(), z < 3 ? -1 : 1);
    }
    if (reversed) {
      std::reverse(c.pts.begin(), c.pts.end());
      std::reverse(c.normals.begin(), c.normals.end());
      std::reverse(c.labels.begin(), c.labels.end());
      std::reverse(c.ground.begin(), c.ground.end());
    }
    return c;
  };
  const std::vector<Eigen::Vector4f> planes = {{0, 0, 1, 0}, {2, 0, 0, -0.61f}, {0, 0, 1, 0}};
  const std::vector<bool> rough = {false, false, true};
  std::vector<std::vector<int>> results;
  for (bool reversed : {false, true}) {
    Case c = build(reversed);
    const KnnGraph g = bruteForceKnnGraph(c.pts, 16);
    const std::size_t adopted =
        adoptUnsegmentedPoints(c.pts, c.normals, g, 0.025, planes, rough, 0.02, 40.0, c.labels, c.ground);
    std::size_t expected_adopted = 0;
    for (std::size_t i = 0; i < c.pts.size(); ++i) {
      const Eigen::Vector3f& p = c.pts[i];
      int want = -1;
      const bool lifted = p.z() > 0.025f && p.x() < 0.3f;
      const bool off_normal = c.normals[i].x() > 0.5f && p.x() < 0.3f;
      if (c.ground[i] || lifted || off_normal) {
        want = -1;
      } else if (p.x() > 0.3f) {
        want = 1;  // the wall's left-out foot joins the wall
      } else if (p.x() < 0.245f) {
        want = 0;  // the band and the gap before the rough region join the floor
      } else {
        want = 2;
      }
      EXPECT_EQ(c.labels[i], want) << p.transpose();
      if (c.labels[i] >= 0 && (p.x() > 0.3f ? p.z() < 0.025f : (p.x() >= 0.095f && p.x() < 0.145f) || (p.x() >= 0.195f && p.x() < 0.245f))) {
        ++expected_adopted;
      }
    }
    EXPECT_EQ(adopted, expected_adopted);
    std::vector<int> l = c.labels;
    if (reversed) std::reverse(l.begin(), l.end());
    results.push_back(l);
  }
  EXPECT_EQ(results[0], results[1]);  // visiting order does not matter
  std::vector<int> labels(3, -1);
  EXPECT_THROW(adoptUnsegmentedPoints({}, {}, KnnGraph{}, 0.025, planes, rough, 0.02, 40.0, labels, {}),
               std::invalid_argument);
}

TEST(RoughMerge, APyramidFieldIsOneLevelSegmentWithItsExactAreaRatio) {
  // 6 x 6 pyramids of 10 cm pitch with 48-degree faces (A/A' = 1.5 exactly), sampled
  // every 2 mm, seen from 1 m above; no floor around it, gravity known.
  const double pitch = 0.1, h = 0.5 * pitch * std::sqrt(1.25);
  std::vector<Eigen::Vector3f> cloud;
  for (int i = 0; i < 300; ++i) {
    for (int j = 0; j < 300; ++j) {
      const double x = 0.002 * i + 0.001, y = 0.002 * j + 0.001;
      const double fx = std::fmod(x, pitch) / pitch - 0.5, fy = std::fmod(y, pitch) / pitch - 0.5;
      const double z = h * (1.0 - 2.0 * std::max(std::abs(fx), std::abs(fy)));
      // Camera frame (OpenCV): x right, y down, z forward; the field faces the camera.
      cloud.emplace_back(static_cast<float>(x - 0.3), static_cast<float>(y - 0.3), static_cast<float>(1.0 - z));
    }
  }
  for (const bool smoothing : {true, false}) {
    PerceptionParams params;
    params.min_range_m = 0.1;
    params.roughness_smoothing = smoothing;
    const FramePipeline pipeline(params);
    const FrameResult r = pipeline.process(cloud, Eigen::Vector3f(0, 0, 1));  // gravity along +z: looking down
    const Segment* best = nullptr;
    for (const auto& seg : r.segments) {
      if (!best || seg.points.size() > best->points.size()) best = &seg;
    }
    ASSERT_NE(best, nullptr);
    EXPECT_TRUE(best->is_rough);
    EXPECT_GE(best->points.size(), 0.9 * r.points.size());
    EXPECT_LE(best->slope_deg, 2.0);
    std::printf("[ info ] pyramid field, smoothing %s: %zu of %zu points in one segment, slope %.2f deg, r %.3f (exact 1.5)\n",
                smoothing ? "on" : "off", best->points.size(), r.points.size(), best->slope_deg, best->roughness);
    if (smoothing) {
      // One projection pass rounds the creases: the noise-free field measures ~1.19.
      // Under Kinect noise at 1.5-2.5 m the same pass measures ~1.4-1.5 (the demo's
      // rough patch); docs/PERCEPTION.md has both. Here: rough, well above flat.
      EXPECT_GE(best->roughness, 1.15);
    } else {
      // Raw 1 cm voxel centroids: the Delaunay area misses only the crease voxels.
      EXPECT_NEAR(best->roughness, 1.5, 0.1);
    }
  }
}

// The insertion order follows the input order within each round (and CGAL, the
// reference, takes row order and any other order by different routes). All must give
// the same triangulation (generic points: no four on a circle) and so the same areas.
TEST(Roughness, RowOrderAndShuffledOrderGiveTheSameTriangulation) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> jitter(-0.003f, 0.003f);
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 60; ++i) {
    for (int j = 0; j < 45; ++j) {
      const float x = 0.01f * i + jitter(rng), y = 0.01f * j + jitter(rng);
      pts.emplace_back(x, y, 0.02f * std::sin(40.f * x) * std::cos(30.f * y) + jitter(rng));
    }
  }
  std::vector<int> rows(pts.size());
  for (std::size_t i = 0; i < rows.size(); ++i) rows[i] = static_cast<int>(i);
  std::vector<int> shuffled = rows;
  std::shuffle(shuffled.begin(), shuffled.end(), rng);
  const Eigen::Vector4f plane(0, 0, 1, 0);
  const auto in_rows = delaunayRoughness(pts, rows, plane, 0.05);
  EXPECT_GT(in_rows.first, 1.05);  // a bumpy surface: the test would notice a lost triangle
  for (const Triangulator who : {Triangulator::kOwn, Triangulator::kCgal}) {
    for (const auto* order : {&rows, &shuffled}) {
      const auto r = delaunayRoughness(pts, *order, plane, 0.05, who);
      EXPECT_NEAR(r.first, in_rows.first, 1e-9);
      EXPECT_NEAR(r.second, in_rows.second, 1e-9);
    }
  }
}

// --- The library's Delaunay triangulation against CGAL and a brute-force check ------

using Triangle = std::array<int, 3>;

// Each triangle rotated to start at its smallest index, the list sorted: two
// triangulations of the same points are equal iff their canonical lists are.
std::vector<Triangle> canonical(std::vector<Triangle> tris) {
  for (auto& t : tris) std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
  std::sort(tris.begin(), tris.end());
  return tris;
}

double twiceSignedArea(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
}

// Brute force, for points whose coordinates are small multiples of a power of two (so
// every product below is exact): every triangle counter-clockwise and not flat, and no
// point strictly inside any triangle's circumcircle (the Delaunay property).
void expectEmptyCircles(const std::vector<Eigen::Vector2d>& pts, const std::vector<Triangle>& tris) {
  int bad = 0;
  for (const auto& t : tris) {
    const Eigen::Vector2d &a = pts[static_cast<std::size_t>(t[0])], &b = pts[static_cast<std::size_t>(t[1])],
                          &c = pts[static_cast<std::size_t>(t[2])];
    if (!(twiceSignedArea(a, b, c) > 0)) ++bad;
    for (const auto& d : pts) {
      const Eigen::Vector2d ad = a - d, bd = b - d, cd = c - d;
      const double det = ad.squaredNorm() * (bd.x() * cd.y() - cd.x() * bd.y()) -
                         bd.squaredNorm() * (ad.x() * cd.y() - cd.x() * ad.y()) +
                         cd.squaredNorm() * (ad.x() * bd.y() - bd.x() * ad.y());
      if (det > 0) ++bad;
    }
  }
  EXPECT_EQ(bad, 0);
}

TEST(Delaunay, OwnTrianglesAreCgalsForGenericPointsInAnyOrder) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  // Scattered points, and a jittered grid (the kind of points segments hold) in row order.
  std::vector<Eigen::Vector2d> scattered(3000), grid;
  for (auto& p : scattered) p = Eigen::Vector2d(u(rng), u(rng));
  for (int r = 0; r < 50; ++r) {
    for (int c = 0; c < 70; ++c) grid.emplace_back(0.01 * (c + jitter(rng)), 0.01 * (r + jitter(rng)));
  }
  for (auto* pts : {&scattered, &grid}) {
    const auto reference = canonical(delaunayTriangles(*pts, Triangulator::kCgal));
    const auto own = canonical(delaunayTriangles(*pts, Triangulator::kOwn));
    ASSERT_GT(reference.size(), pts->size());  // ~2n triangles
    EXPECT_EQ(own, reference);
    // Shuffled: the same triangles under the permutation.
    std::vector<int> perm(pts->size());
    for (std::size_t i = 0; i < perm.size(); ++i) perm[i] = static_cast<int>(i);
    std::shuffle(perm.begin(), perm.end(), rng);
    std::vector<Eigen::Vector2d> shuffled(pts->size());
    for (std::size_t i = 0; i < perm.size(); ++i) shuffled[i] = (*pts)[static_cast<std::size_t>(perm[i])];
    auto back = delaunayTriangles(shuffled, Triangulator::kOwn);
    for (auto& t : back) {
      for (int& v : t) v = perm[static_cast<std::size_t>(v)];
    }
    EXPECT_EQ(canonical(back), reference);
  }
}

TEST(Delaunay, OwnTrianglesAreDelaunayWhereFourPointsShareACircle) {
  // An exact lattice: every unit square's corners lie on one circle, so either diagonal
  // is Delaunay and CGAL's choice is not the only right one. Brute force instead: empty
  // circumcircles, and the triangles tile the rectangle exactly (areas sum to it).
  std::vector<Eigen::Vector2d> lattice;
  for (int r = 0; r <= 30; ++r) {
    for (int c = 0; c <= 40; ++c) lattice.emplace_back(0.25 * c, 0.25 * r);
  }
  std::mt19937 rng(8);
  std::shuffle(lattice.begin(), lattice.end(), rng);
  // Points on one circle (angles whose sines and cosines are exact) and the centre.
  std::vector<Eigen::Vector2d> ring = {{1, 0}, {0, 1}, {-1, 0}, {0, -1}, {0.6, 0.8}, {-0.8, 0.6}, {-0.6, -0.8}, {0.8, -0.6}, {0, 0}};
  for (const auto* pts : {&lattice, &ring}) {
    const auto own = delaunayTriangles(*pts, Triangulator::kOwn);
    expectEmptyCircles(*pts, own);
    double area = 0;
    for (const auto& t : own) {
      area += 0.5 * twiceSignedArea((*pts)[static_cast<std::size_t>(t[0])], (*pts)[static_cast<std::size_t>(t[1])],
                                    (*pts)[static_cast<std::size_t>(t[2])]);
    }
    if (pts == &lattice) {
      EXPECT_EQ(own.size(), 2u * 30 * 40);
      EXPECT_DOUBLE_EQ(area, 10.0 * 7.5);
    } else {
      EXPECT_EQ(own.size(), 8u);  // a fan around the centre
      double polygon = 0;
      for (const auto& t : delaunayTriangles(*pts, Triangulator::kCgal)) {
        polygon += 0.5 * twiceSignedArea((*pts)[static_cast<std::size_t>(t[0])], (*pts)[static_cast<std::size_t>(t[1])],
                                         (*pts)[static_cast<std::size_t>(t[2])]);
      }
      EXPECT_NEAR(area, polygon, 1e-12);
    }
  }
}

TEST(Delaunay, DuplicatesCollinearAndNonFinitePointsAreHandled) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Eigen::Vector2d> pts(500);
  for (auto& p : pts) p = Eigen::Vector2d(u(rng), u(rng));
  const auto reference = canonical(delaunayTriangles(pts, Triangulator::kCgal));
  // Each point twice, and two points with NaN / infinity appended: the same triangles,
  // each over one copy of its points (whichever was inserted first; the other is
  // skipped, as in CGAL), none over the non-finite points.
  std::vector<Eigen::Vector2d> doubled = pts;
  doubled.insert(doubled.end(), pts.begin(), pts.end());
  doubled.emplace_back(std::nan(""), 0.5);
  doubled.emplace_back(0.5, std::numeric_limits<double>::infinity());
  auto own = delaunayTriangles(doubled, Triangulator::kOwn);
  for (auto& t : own) {
    for (int& v : t) {
      EXPECT_LT(v, 1000);
      v %= 500;
    }
  }
  EXPECT_EQ(canonical(own), reference);
  // Collinear points (a line, and a line with a second copy): no triangle.
  std::vector<Eigen::Vector2d> line;
  for (int i = 0; i < 20; ++i) line.emplace_back(0.5 * i, 0.25 * i);
  line.insert(line.end(), line.begin(), line.end());
  EXPECT_TRUE(delaunayTriangles(line, Triangulator::kOwn).empty());
  // Collinear points first, then one off the line: a fan of 19 triangles.
  line.resize(20);
  line.emplace_back(0.0, 3.0);
  const auto fan = delaunayTriangles(line, Triangulator::kOwn);
  EXPECT_EQ(fan.size(), 19u);
  EXPECT_EQ(canonical(fan), canonical(delaunayTriangles(line, Triangulator::kCgal)));
  // Coordinates near the double range (products overflow; the exact predicates decide):
  // a square's corners and its centre, a fan of four.
  const double big = 1e308;
  const std::vector<Eigen::Vector2d> huge = {{-big, 0}, {big, 0}, {0, big}, {0, -big}, {0, 0}};
  EXPECT_EQ(canonical(delaunayTriangles(huge, Triangulator::kOwn)),
            canonical({{0, 3, 4}, {1, 2, 4}, {0, 4, 2}, {1, 4, 3}}));
  // Fewer than three points, and none.
  EXPECT_TRUE(delaunayTriangles({{0, 0}, {1, 1}}, Triangulator::kOwn).empty());
  EXPECT_TRUE(delaunayTriangles({}, Triangulator::kOwn).empty());
}

TEST(Roughness, FlatAndCorrugatedSurfacesMatchTheirExactRatio) {
  // A zigzag z = a * tri(x / P) sampled at its kinks: Delaunay reproduces it exactly,
  // so A/A' = sqrt(1 + (2a / (P/2))^2 ... per facet slope s = a / (P / 2).
  std::vector<Eigen::Vector3f> flat, zig;
  const float step = 0.01f, a = 0.01f, period = 0.04f;
  for (int i = 0; i <= 40; ++i) {
    for (int j = 0; j <= 40; ++j) {
      const float x = i * step, y = j * step;
      flat.emplace_back(x, y, 0.3f * x + 1.f);  // tilted plane
      const float ph = std::fmod(x, period) / period;
      zig.emplace_back(x, y, a * (1 - std::abs(2 * ph - 1)) * 2);
    }
  }
  std::vector<int> idx(flat.size());
  for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = static_cast<int>(i);
  const Eigen::Vector4f tilted = leastSquaresPlane(flat, idx);
  EXPECT_NEAR(delaunayRoughness(flat, idx, tilted, 0.05).first, 1.0, 1e-6);
  const double s = 2 * a / (period / 2);  // facet slope
  const auto [r, area] = delaunayRoughness(zig, idx, Eigen::Vector4f(0, 0, 1, 0), 0.05);
  EXPECT_NEAR(r, std::sqrt(1 + s * s), 1e-4);
  EXPECT_NEAR(area, 0.4 * 0.4 * std::sqrt(1 + s * s), 1e-4);
  // Collinear points: no triangle, r = 1 and no area, not NaN.
  std::vector<Eigen::Vector3f> line = {{0, 0, 0}, {0.01f, 0, 0}, {0.02f, 0, 0}, {0.03f, 0, 0}};
  const auto degenerate = delaunayRoughness(line, {0, 1, 2, 3}, Eigen::Vector4f(0, 0, 1, 0), 0.05);
  EXPECT_EQ(degenerate.first, 1.0);
  EXPECT_EQ(degenerate.second, 0.0);
}

// --- End to end on the corridor ------------------------------------------------

struct Truth {
  std::map<int, int> points_of_surface;             // ground-truth id -> labelled pixels with a point
  std::map<int, std::map<int, int>> segment_votes;  // ground-truth id -> segment -> points
};

// Assigns each reduced point the majority ground-truth label of its pixels.
Truth overlap(const sim::CorridorScene& scene, const sim::RenderedFrame& r, const FrameResult& res) {
  std::vector<std::map<int, int>> votes(res.points.size());
  for (std::size_t px = 0; px < res.point_of_pixel.size(); ++px) {
    const int p = res.point_of_pixel[px];
    if (p >= 0 && r.labels[px] > 0) ++votes[static_cast<std::size_t>(p)][r.labels[px]];
  }
  Truth t;
  for (std::size_t p = 0; p < votes.size(); ++p) {
    if (votes[p].empty()) continue;
    const int id = std::max_element(votes[p].begin(), votes[p].end(),
                                    [](const auto& a, const auto& b) { return a.second < b.second; })->first;
    ++t.points_of_surface[id];
    if (res.segment_of_point[p] >= 0) ++t.segment_votes[id][res.segment_of_point[p]];
  }
  (void)scene;
  return t;
}

class CorridorFrames : public ::testing::TestWithParam<sim::NoiseModel> {};

TEST_P(CorridorFrames, RampSlopesFloorRoughnessAndGround) {
  sim::CorridorParams params;
  params.noise = GetParam();
  params.kinect.edge_window_px = 0;  // per-frame accuracy on sharp edges (edges: CorridorMap.FootholdsAndPlans...)
  const sim::CorridorScene scene(params);
  const FramePipeline pipeline;
  std::map<int, std::vector<double>> slope_errors;  // ramp id -> errors
  std::vector<double> floor_roughness;
  for (int frame : {0, 30, 60, 90, 120}) {
    const auto r = scene.render(frame);
    const Eigen::Vector3f g_cam = (r.T_world_camera.linear().transpose() * scene.gravityDown()).cast<float>();
    const FrameResult res = pipeline.process(r.depth, params.intrinsics, g_cam);
    ASSERT_TRUE(res.ground_plane) << "frame " << frame;
    // The ground is the floor: its distance is the camera height.
    EXPECT_NEAR((*res.ground_plane)(3), r.T_world_camera.translation().z(), 0.03) << "frame " << frame;
    const Truth t = overlap(scene, r, res);
    for (const auto& [id, segs] : t.segment_votes) {
      const auto& s = scene.surface(id);
      const auto best = std::max_element(segs.begin(), segs.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
      const Segment& seg = res.segments[static_cast<std::size_t>(best->first)];
      if (s.kind == sim::SurfaceKind::kRamp && best->second >= 500) {
        slope_errors[id].push_back(std::abs(seg.slope_deg - s.slope_deg));
      }
      if (s.kind == sim::SurfaceKind::kFloor && seg.is_ground) {
        // Floor within 2 m of the camera (the spec's range for the noisy bound).
        floor_roughness.push_back(seg.roughness);
      }
    }
  }
  ASSERT_GE(slope_errors.size(), 4u);
  for (const auto& [id, errors] : slope_errors) {
    std::vector<double> e = errors;
    std::sort(e.begin(), e.end());
    const double median = e[e.size() / 2];
    if (GetParam() == sim::NoiseModel::kNone) {
      EXPECT_LE(e.back(), 0.3) << scene.surface(id).name;
    } else {
      EXPECT_LE(median, 1.5) << scene.surface(id).name;
    }
  }
  ASSERT_FALSE(floor_roughness.empty());
  for (double r : floor_roughness) {
    if (GetParam() == sim::NoiseModel::kNone) {
      EXPECT_NEAR(r, 1.0, 0.01);
    } else {
      EXPECT_LE(r, 1.05);
    }
  }
}

TEST_P(CorridorFrames, SurfacesAreCoveredByOneSegmentEach) {
  sim::CorridorParams params;
  params.noise = GetParam();
  params.kinect.edge_window_px = 0;  // per-frame accuracy on sharp edges (edges: CorridorMap.FootholdsAndPlans...)
  const sim::CorridorScene scene(params);
  const FramePipeline pipeline;
  // Per surface over several frames: points seen, points in its best segment, and the
  // labelled points of that segment (purity: the share of them that are this surface).
  std::map<int, std::pair<int, int>> cover;
  std::map<int, int> best_segment_size;
  for (int frame : {0, 45, 90, 135}) {
    const auto r = scene.render(frame);
    const Eigen::Vector3f g = (r.T_world_camera.linear().transpose() * scene.gravityDown()).cast<float>();
    const FrameResult res = pipeline.process(r.depth, params.intrinsics, g);
    const Truth t = overlap(scene, r, res);
    std::map<int, int> segment_size;  // labelled points per segment
    for (const auto& [id, votes] : t.segment_votes) {
      for (const auto& [seg, v] : votes) segment_size[seg] += v;
    }
    for (const auto& [id, n] : t.points_of_surface) {
      if (n < 500) continue;  // the spec's visibility threshold
      int best = 0, best_seg = -1;
      const auto it = t.segment_votes.find(id);
      if (it != t.segment_votes.end()) {
        for (const auto& [seg, votes] : it->second) {
          if (votes > best) best = votes, best_seg = seg;
        }
      }
      cover[id].first += n;
      cover[id].second += best;
      if (best_seg >= 0) best_segment_size[id] += segment_size[best_seg];
    }
  }
  // Every surface is covered >= 90 % by one segment except a known gap under noise,
  // printed and recorded in docs/PERCEPTION.md: the first riser (far, 15 cm tall) breaks up.
  const bool noisy = GetParam() != sim::NoiseModel::kNone;
  const std::set<std::string> gaps = noisy ? std::set<std::string>{"stair riser 1"} : std::set<std::string>{};
  int asserted = 0;
  for (const auto& [id, c] : cover) {
    const double frac = static_cast<double>(c.second) / c.first;
    const double purity = static_cast<double>(c.second) / std::max(1, best_segment_size[id]);
    const std::string& name = scene.surface(id).name;
    std::printf("[ info ] %-22s %6d points, %5.1f %% in one segment, purity %5.1f %%%s\n", name.c_str(), c.first,
                100 * frac, 100 * purity, gaps.count(name) ? " (known gap)" : "");
    if (!gaps.count(name)) {
      EXPECT_GE(frac, 0.9) << name;
      EXPECT_GE(purity, 0.9) << name;
      ++asserted;
    }
  }
  EXPECT_GE(asserted, 10);  // of 13 surfaces with >= 500 points
}

INSTANTIATE_TEST_SUITE_P(NoiseOffAndOn, CorridorFrames,
                         ::testing::Values(sim::NoiseModel::kNone, sim::NoiseModel::kKinect),
                         [](const auto& param_info) { return param_info.param == sim::NoiseModel::kNone ? "Exact" : "Kinect"; });

TEST(FramePipeline, OnePipelineServesSeveralThreadsWithIdenticalResults) {
  // `mobmap build` runs two frames through one const pipeline at once.
  sim::CorridorParams params;
  params.noise = sim::NoiseModel::kKinect;
  const sim::CorridorScene scene(params);
  const FramePipeline pipeline;
  const int frames[] = {10, 40, 70};
  std::vector<FrameResult> alone;
  for (int f : frames) alone.push_back(pipeline.process(scene.render(f).depth, params.intrinsics));
  std::vector<std::vector<FrameResult>> together(2);
  std::vector<std::thread> threads;
  for (std::size_t t = 0; t < together.size(); ++t) {
    threads.emplace_back([&, t] {
      for (int f : frames) together[t].push_back(pipeline.process(scene.render(f).depth, params.intrinsics));
    });
  }
  for (auto& th : threads) th.join();
  for (const auto& run : together) {
    ASSERT_EQ(run.size(), alone.size());
    for (std::size_t i = 0; i < run.size(); ++i) {
      EXPECT_EQ(run[i].points, alone[i].points);
      ASSERT_EQ(run[i].segments.size(), alone[i].segments.size());
      EXPECT_GT(run[i].segments.size(), 3u);
      for (std::size_t s = 0; s < run[i].segments.size(); ++s) {
        EXPECT_EQ(run[i].segments[s].points, alone[i].segments[s].points);
        EXPECT_EQ(run[i].segments[s].mobility, alone[i].segments[s].mobility);
      }
    }
  }
}

TEST(FramePipeline, FloorIsChosenAsGroundEvenWhenAWallHasMorePoints) {
  // Camera 1.3 m above a floor, looking at a wall 2.2 m ahead that fills most of the view.
  std::vector<sim::Triangle> tris = {
      {{-3, -1, 0}, {3, -1, 0}, {3, 2.2, 0}, 1}, {{-3, -1, 0}, {3, 2.2, 0}, {-3, 2.2, 0}, 1},  // floor z = 0
      {{-3, 2.2, 0}, {3, 2.2, 0}, {3, 2.2, 3}, 2}, {{-3, 2.2, 0}, {3, 2.2, 3}, {-3, 2.2, 3}, 2}};  // wall y = 2.2
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  Eigen::Matrix3d rot;
  const double pitch = 20 * kDeg;  // looking along +y, slightly down
  const Eigen::Vector3d fwd(0, std::cos(pitch), -std::sin(pitch)), right(1, 0, 0);
  rot.col(0) = right;
  rot.col(1) = fwd.cross(right);
  rot.col(2) = fwd;
  T.linear() = rot;
  T.translation() = Eigen::Vector3d(0, 0, 1.3);
  const PinholeIntrinsics k;
  const auto rc = sim::castRays(tris, k, T);
  int floor_px = 0, wall_px = 0;
  for (auto l : rc.labels) {
    floor_px += l == 1;
    wall_px += l == 2;
  }
  ASSERT_GT(wall_px, 2 * floor_px);
  ASSERT_GT(floor_px, 20000);
  const FramePipeline pipeline;
  const Eigen::Vector3f g_cam = (rot.transpose() * Eigen::Vector3d(0, 0, -1)).cast<float>();
  const FrameResult with_gravity = pipeline.process(rc.depth, k, g_cam);
  ASSERT_TRUE(with_gravity.ground_plane);
  EXPECT_NEAR((*with_gravity.ground_plane)(3), 1.3, 0.02);
  EXPECT_GT(with_gravity.ground_plane->head<3>().dot(-g_cam), 0.99f);
  EXPECT_EQ(with_gravity.reference, SlopeReference::kGravity);
}

// A camera 1.3 m above the floor (z = 0) of a room, looking along +y and pitched down
// by `pitch_deg` (negative: up); its pose and the frame it sees.
struct PitchedView {
  Eigen::Matrix3d rot;
  sim::RayCastResult rc;
  int pixels(int label) const { return static_cast<int>(std::count(rc.labels.begin(), rc.labels.end(), label)); }
};
PitchedView pitchedView(const std::vector<sim::Triangle>& tris, double pitch_deg) {
  PitchedView v;
  const double pitch = pitch_deg * kDeg;
  const Eigen::Vector3d fwd(0, std::cos(pitch), -std::sin(pitch)), right(1, 0, 0);
  v.rot.col(0) = right;
  v.rot.col(1) = fwd.cross(right);
  v.rot.col(2) = fwd;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = v.rot;
  T.translation() = Eigen::Vector3d(0, 0, 1.3);
  v.rc = sim::castRays(tris, PinholeIntrinsics{}, T);
  return v;
}

// Without gravity the paper's largest plane is the wall here; the upright prior takes
// the floor below the camera, and stays out of the way when the largest plane is a floor
// seen steeply (beyond the prior's cone). With gravity, a larger ceiling is never the
// ground: the ground is below the camera.
TEST(FramePipeline, UprightPriorTakesTheFloorOverALargerWallAndGravityNeverTakesACeiling) {
  const std::vector<sim::Triangle> room = {
      {{-3, -1, 0}, {3, -1, 0}, {3, 2.2, 0}, 1}, {{-3, -1, 0}, {3, 2.2, 0}, {-3, 2.2, 0}, 1},        // floor z = 0
      {{-3, 2.2, 0}, {3, 2.2, 0}, {3, 2.2, 3}, 2}, {{-3, 2.2, 0}, {3, 2.2, 3}, {-3, 2.2, 3}, 2},    // wall y = 2.2
      {{-4, -1, 1.8}, {4, 6, 1.8}, {4, -1, 1.8}, 3}, {{-4, -1, 1.8}, {-4, 6, 1.8}, {4, 6, 1.8}, 3},   // ceiling z = 1.8
      {{-4, -1, 0}, {4, -1, 0}, {4, 6, 0}, 1}, {{-4, -1, 0}, {4, 6, 0}, {-4, 6, 0}, 1}};             // a longer floor
  const PinholeIntrinsics k;
  const PitchedView level = pitchedView({room[0], room[1], room[2], room[3]}, 20.0);
  ASSERT_GT(level.pixels(2), 2 * level.pixels(1));
  const FramePipeline pipeline;
  const FrameResult prior = pipeline.process(level.rc.depth, k);
  ASSERT_TRUE(prior.ground_plane);
  EXPECT_EQ(prior.ground_rule, GroundRule::kUprightPrior);
  EXPECT_NEAR((*prior.ground_plane)(3), 1.3, 0.02);
  EXPECT_EQ(prior.reference, SlopeReference::kGround);
  EXPECT_LT(prior.segments.front().slope_deg, 0.5);
  PerceptionParams paper;
  paper.ground_upright_prior_deg = 0;
  const FrameResult largest = FramePipeline(paper).process(level.rc.depth, k);
  ASSERT_TRUE(largest.ground_plane);
  EXPECT_EQ(largest.ground_rule, GroundRule::kLargestPlane);
  // The wall: its normal is the camera's forward axis pitched up by 20 degrees.
  EXPECT_NEAR(std::abs((*largest.ground_plane)(2)), std::cos(20 * kDeg), 0.01);
  // Looking down at 55 degrees: the floor is the largest plane, outside the 45-degree
  // cone; the prior's search finds nothing but an edge fit, and the floor stays.
  const PitchedView steep = pitchedView({room[0], room[1]}, 55.0);
  const FrameResult down = pipeline.process(steep.rc.depth, k);
  ASSERT_TRUE(down.ground_plane);
  EXPECT_EQ(down.ground_rule, GroundRule::kLargestPlane);
  EXPECT_NEAR((*down.ground_plane)(3), 1.3, 0.02);
  // Level, in a long room with a ceiling 0.5 m overhead that fills more of the view
  // (the floor starts 3.1 m ahead, where the lowest rays meet it).
  const PitchedView up = pitchedView({room[4], room[5], room[6], room[7]}, 0.0);
  ASSERT_GT(up.pixels(3), 3 * up.pixels(1) / 2);
  const Eigen::Vector3f g_cam = (up.rot.transpose() * Eigen::Vector3d(0, 0, -1)).cast<float>();
  PerceptionParams loose;
  loose.max_range_m = 4.0;  // ceiling from 1.2 m, floor from 3.1 m: the ceiling has more voxels
  loose.ground_max_tilt_deg = 45;  // a ceiling passes the tilt test as well as the floor does
  const FrameResult with_gravity = FramePipeline(loose).process(up.rc.depth, k, g_cam);
  ASSERT_TRUE(with_gravity.ground_plane);
  EXPECT_EQ(with_gravity.ground_rule, GroundRule::kGravity);

  EXPECT_NEAR((*with_gravity.ground_plane)(3), 1.3, 0.02);
  EXPECT_GT(with_gravity.ground_plane->head<3>().dot(-g_cam), 0.99f);
}

TEST(FramePipeline, EmptyAllInvalidAndNanFramesGiveNoSegmentsAndNoNan) {
  const FramePipeline pipeline;
  const PinholeIntrinsics k;
  const FrameResult empty = pipeline.process(DepthImage(k.width, k.height), k);
  EXPECT_TRUE(empty.segments.empty());
  EXPECT_FALSE(empty.ground_plane);
  DepthImage nan_frame(k.width, k.height);
  std::fill(nan_frame.depth_m.begin(), nan_frame.depth_m.end(), std::numeric_limits<float>::quiet_NaN());
  EXPECT_TRUE(pipeline.process(nan_frame, k).segments.empty());
  std::vector<Eigen::Vector3f> cloud = {{NAN, 0, 1}, {0, 0, 1}};
  EXPECT_TRUE(pipeline.process(cloud).segments.empty());
  EXPECT_THROW((void)pipeline.process(DepthImage(10, 10), k), std::invalid_argument);
  EXPECT_THROW((void)pipeline.process(DepthImage(k.width, k.height), k, Eigen::Vector3f::Zero()), std::invalid_argument);
}

TEST(FramePipeline, ASinglePlaneIsOneGroundSegmentWithFiniteFeatures) {
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 100; ++i) {
    for (int j = 0; j < 100; ++j) pts.emplace_back(-0.5f + i * 0.01f, 1.0f, 1.0f + j * 0.01f);
  }
  const FrameResult r = FramePipeline().process(pts, Eigen::Vector3f(0, 1, 0));
  ASSERT_EQ(r.segments.size(), 1u);
  EXPECT_TRUE(r.segments[0].is_ground);
  EXPECT_NEAR(r.segments[0].slope_deg, 0.0, 0.1);
  EXPECT_NEAR(r.segments[0].roughness, 1.0, 0.01);
  EXPECT_GT(r.segments[0].mobility, 0.95);
  // Gravity is a direction: 1e30 long (its squared norm overflows a float) is the same.
  const FrameResult huge = FramePipeline().process(pts, Eigen::Vector3f(0, 1e30f, 0));
  ASSERT_EQ(huge.segments.size(), 1u);
  EXPECT_TRUE(huge.segments[0].is_ground);
  EXPECT_EQ(huge.segments[0].slope_deg, r.segments[0].slope_deg);
}

TEST(PerceptionParams, RejectsAbsurdValuesNamingTheField) {
  PerceptionParams p;
  p.voxel_size_m = 0;
  try {
    FramePipeline{p};
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("voxel_size_m"), std::string::npos);
  }
  p = {};
  p.max_range_m = 0.1;
  EXPECT_THROW(FramePipeline{p}, std::invalid_argument);
  p = {};
  p.ground_probability = 1.0;
  EXPECT_THROW(FramePipeline{p}, std::invalid_argument);
}

TEST(PerceptionParams, ScaledToCoarserVoxelsKeepTheirPhysicalSizes) {
  const PerceptionParams d;
  const PerceptionParams c = scaledToVoxel(d, 0.02);
  EXPECT_NO_THROW(validate(c));
  EXPECT_EQ(c.voxel_size_m, 0.02);
  // Counts of points on an area: a quarter (rounded).
  EXPECT_EQ(c.min_segment_points, 13);     // 50 / 4
  EXPECT_EQ(c.ground_min_points, 125);     // 500 / 4
  EXPECT_EQ(c.rough_fragment_max_points, 38);
  EXPECT_EQ(c.rough_min_points, 25);
  EXPECT_EQ(c.rough_smoothing_k, 7);       // 31 points on the same disc: 31 / 4 - 1
  // Spacing-tied distances double; neighbour counts and physical sizes stay.
  EXPECT_DOUBLE_EQ(c.neighbour_distance_m, 2 * d.neighbour_distance_m);
  EXPECT_DOUBLE_EQ(c.max_triangle_edge_m, 2 * d.max_triangle_edge_m);
  EXPECT_EQ(c.normal_k, d.normal_k);
  EXPECT_EQ(c.outlier_k, d.outlier_k);
  EXPECT_EQ(c.ground_distance_m, d.ground_distance_m);
  EXPECT_EQ(c.rough_min_width_m, d.rough_min_width_m);
  EXPECT_EQ(c.adopt_max_distance_m, d.adopt_max_distance_m);
  // The same voxel size changes nothing.
  const PerceptionParams same = scaledToVoxel(d, 0.01);
  EXPECT_EQ(same.min_segment_points, d.min_segment_points);
  EXPECT_EQ(same.ground_min_points, d.ground_min_points);
  EXPECT_EQ(same.rough_fragment_max_points, d.rough_fragment_max_points);
  EXPECT_EQ(same.rough_min_points, d.rough_min_points);
  EXPECT_EQ(same.rough_smoothing_k, d.rough_smoothing_k);
  EXPECT_DOUBLE_EQ(same.neighbour_distance_m, d.neighbour_distance_m);
  EXPECT_DOUBLE_EQ(same.max_triangle_edge_m, d.max_triangle_edge_m);
  // Rough joining switched off stays off.
  PerceptionParams off;
  off.rough_fragment_max_points = 0;
  EXPECT_EQ(scaledToVoxel(off, 0.02).rough_fragment_max_points, 0);
  // Much finer voxels: counts grow, and the result still validates.
  EXPECT_NO_THROW(validate(scaledToVoxel(d, 0.001)));
  EXPECT_EQ(scaledToVoxel(d, 0.001).min_segment_points, 5000);
  EXPECT_THROW((void)scaledToVoxel(d, 0.0), std::invalid_argument);
  EXPECT_THROW((void)scaledToVoxel(d, std::nan("")), std::invalid_argument);
}

}  // namespace
}  // namespace mobmap::perception
