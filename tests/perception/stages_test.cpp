// Paper steps 1-4 (voxel grid, outlier removal, normals, RGB-N) and the camera model against
// brute force and analytic oracles.
#include "perception_support.hpp"

namespace mobmap::perception {
namespace {

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

}  // namespace
}  // namespace mobmap::perception
