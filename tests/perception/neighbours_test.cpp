// The exact kNN graph against brute force, on every instruction set the machine has.
#include "perception_support.hpp"

namespace mobmap::perception {
namespace {

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

}  // namespace
}  // namespace mobmap::perception
