#pragma once
// What the perception tests share: random clouds, the instruction sets to run the
// kernels on, graph comparison.
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

constexpr double kDeg = M_PI / 180.0;

inline std::vector<Eigen::Vector3f> randomCloud(int n, unsigned seed) {
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
inline std::vector<Simd> simdChoices() {
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

inline void expectSameGraph(const KnnGraph& fast, const KnnGraph& ref, const std::string& what) {
  EXPECT_EQ(fast.count, ref.count) << what;
  EXPECT_EQ(fast.indices, ref.indices) << what;
  EXPECT_EQ(fast.sq_dist, ref.sq_dist) << what;
}

}  // namespace mobmap::perception
