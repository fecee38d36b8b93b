// Paper step 5 (RANSAC ground) and the ground points given back to ramps.
#include "perception_support.hpp"

namespace mobmap::perception {
namespace {

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


}  // namespace
}  // namespace mobmap::perception
