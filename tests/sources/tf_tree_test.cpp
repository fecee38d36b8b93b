// TfTree against exact answers: composed chains, interpolation between samples of a
// motion it reproduces exactly (constant velocity and turn rate), no extrapolation, and
// the broken trees it refuses.
#include "mobmap/sources/tf_tree.hpp"

#include "mobmap/mapping/trajectory.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace mobmap::sources {
namespace {

Eigen::Isometry3d pose(const Eigen::Vector3d& axis, double angle, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
  T.translation() = t;
  return T;
}

void add(TfTree& tree, const std::string& parent, const std::string& child, std::int64_t ns, const Eigen::Isometry3d& T,
         bool is_static) {
  tree.add(parent, child, ns, T.translation(), Eigen::Quaterniond(T.linear()), is_static);
}

void expectNear(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double tol = 1e-12) {
  EXPECT_LT((a.matrix() - b.matrix()).cwiseAbs().maxCoeff(), tol) << a.matrix() << "\n vs\n" << b.matrix();
}

constexpr std::int64_t kSecond = 1000000000;

// The base moves at constant velocity and turns at a constant rate about one axis:
// slerp and lerp between any two samples give its pose exactly.
Eigen::Isometry3d baseAt(double t) {
  return pose(Eigen::Vector3d(0.1, 0.2, 1.0), 0.3 * t, Eigen::Vector3d(1.0 + 0.5 * t, -2.0 + 0.25 * t, 0.1));
}

TEST(TfTree, ComposesStaticAndSampledLinksThroughTheCommonAncestor) {
  TfTree tree;
  const Eigen::Isometry3d T_map_odom = pose(Eigen::Vector3d::UnitZ(), 0.7, Eigen::Vector3d(3, -1, 0));
  const Eigen::Isometry3d T_base_link = pose(Eigen::Vector3d::UnitY(), 0.3, Eigen::Vector3d(0.2, 0, 0.9));
  const Eigen::Isometry3d T_link_optical = pose(Eigen::Vector3d(1, -1, 1), 2.0943951023931953, Eigen::Vector3d(0, 0.02, 0));
  add(tree, "map", "odom", 0, T_map_odom, true);
  add(tree, "base_link", "camera_link", 0, T_base_link, true);
  add(tree, "camera_link", "optical", 0, T_link_optical, true);
  add(tree, "base_link", "imu", 0, pose(Eigen::Vector3d::UnitX(), 0.1, Eigen::Vector3d(0, 0, 0.3)), true);
  for (int i = 0; i <= 10; ++i) add(tree, "odom", "base_link", i * kSecond / 10, baseAt(i * 0.1), false);

  // Between samples, at a sample, and from one branch to another.
  for (const double t : {0.0, 0.05, 0.1, 0.37, 0.999, 1.0}) {
    SCOPED_TRACE(t);
    const auto ns = static_cast<std::int64_t>(std::llround(t * 1e9));
    const auto got = tree.lookup("map", "optical", ns, kSecond);
    ASSERT_TRUE(got);
    expectNear(*got, T_map_odom * baseAt(t) * T_base_link * T_link_optical, 1e-9);
  }
  const auto imu_in_optical = tree.lookup("optical", "imu", 0, 0);
  ASSERT_TRUE(imu_in_optical);
  expectNear(*imu_in_optical, (T_base_link * T_link_optical).inverse() * pose(Eigen::Vector3d::UnitX(), 0.1, Eigen::Vector3d(0, 0, 0.3)));
  expectNear(*tree.lookup("optical", "optical", 5, 0), Eigen::Isometry3d::Identity());
}

// One interpolator, one meaning of the gap: a TUM trajectory (mapping::Trajectory) and a
// TF link with the same samples give the same pose, bit for bit, or both none, at random
// stamps and gaps, on samples irregularly spaced in time.
TEST(TfTree, AgreesWithATrajectoryOfTheSameSamples) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> step(0.01, 0.2), unit(0.0, 1.0);
  TfTree tree;
  mapping::Trajectory trajectory;
  double t = 1000.0;
  for (int i = 0; i < 60; ++i) {
    t += step(rng);
    const std::int64_t ns = mapping::stampNs(t);
    // A wobbling motion: interpolation is not exact, so both must take the same way.
    const Eigen::Isometry3d T = pose(Eigen::Vector3d(unit(rng), unit(rng), 1.0), 3.0 * unit(rng),
                                     Eigen::Vector3d(t, std::sin(t), unit(rng)));
    add(tree, "odom", "camera", ns, T, false);
    trajectory.insert(static_cast<double>(ns) * 1e-9, T);
  }
  int posed = 0, unposed = 0;
  for (int i = 0; i < 2000; ++i) {
    const std::int64_t stamp = mapping::stampNs(1000.0 + (t - 1000.0 + 0.1) * unit(rng));
    const double gap = 0.25 * unit(rng);
    const auto from_tf = tree.lookup("odom", "camera", stamp, mapping::stampNs(gap));
    const auto from_trajectory = trajectory.at(static_cast<double>(stamp) * 1e-9, gap);
    ASSERT_EQ(from_tf.has_value(), from_trajectory.has_value()) << stamp << " gap " << gap;
    if (from_tf) {
      ++posed;
      EXPECT_TRUE(from_tf->matrix() == from_trajectory->matrix()) << stamp;
    } else {
      ++unposed;
    }
  }
  EXPECT_GT(posed, 200);
  EXPECT_GT(unposed, 200);
}

TEST(TfTree, NeverExtrapolatesAndHonoursTheGap) {
  TfTree tree;
  add(tree, "odom", "base", kSecond, baseAt(1.0), false);
  add(tree, "odom", "base", 3 * kSecond, baseAt(3.0), false);
  std::string why;
  EXPECT_FALSE(tree.lookup("odom", "base", kSecond / 2, 10 * kSecond, &why));
  EXPECT_NE(why.find("no sample before"), std::string::npos) << why;
  EXPECT_FALSE(tree.lookup("odom", "base", 4 * kSecond, 10 * kSecond, &why));
  EXPECT_NE(why.find("no sample after"), std::string::npos) << why;
  // 2 s apart: too far for a 1 s gap, fine for 2 s; a sample's own stamp needs no neighbour.
  EXPECT_FALSE(tree.lookup("odom", "base", 2 * kSecond, kSecond, &why));
  EXPECT_NE(why.find("2.000 s apart"), std::string::npos) << why;
  ASSERT_TRUE(tree.lookup("odom", "base", 2 * kSecond, 2 * kSecond));
  expectNear(*tree.lookup("odom", "base", 2 * kSecond, 2 * kSecond), baseAt(2.0), 1e-9);
  ASSERT_TRUE(tree.lookup("odom", "base", 3 * kSecond, 0));
  // Samples out of order are put in order once they are all in.
  add(tree, "odom", "base", 2 * kSecond, baseAt(2.0), false);
  EXPECT_FALSE(tree.sorted());
  EXPECT_THROW((void)tree.lookup("odom", "base", 2 * kSecond, kSecond), std::logic_error);
  tree.sortSamples();
  EXPECT_TRUE(tree.sorted());
  expectNear(*tree.lookup("odom", "base", 2500 * kSecond / 1000, kSecond), baseAt(2.5), 1e-9);
}

// Samples arriving in any order give, once sorted, the lookups of the same samples added
// in stamp order, bit for bit; equal stamps keep the order they arrived in.
TEST(TfTree, SamplesInAnyOrderGiveTheLookupsOfSamplesInOrder) {
  constexpr int kSamples = 20000;
  TfTree ascending, descending, shuffled;
  std::vector<int> order(kSamples);
  for (int i = 0; i < kSamples; ++i) order[static_cast<std::size_t>(i)] = i;
  std::uint64_t state = 12345;
  for (std::size_t i = order.size() - 1; i > 0; --i) {  // Fisher-Yates with a fixed LCG
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    std::swap(order[i], order[(state >> 33) % (i + 1)]);
  }
  const std::int64_t step = kSecond / 100;
  for (int i = 0; i < kSamples; ++i) add(ascending, "odom", "base", i * step, baseAt(i * 0.01), false);
  for (int i = kSamples - 1; i >= 0; --i) add(descending, "odom", "base", i * step, baseAt(i * 0.01), false);
  for (int i : order) add(shuffled, "odom", "base", i * step, baseAt(i * 0.01), false);
  EXPECT_TRUE(ascending.sorted());
  descending.sortSamples();
  shuffled.sortSamples();
  for (std::int64_t t = step / 3; t < (kSamples - 1) * step; t += 997 * step / 7) {
    const auto a = ascending.lookup("odom", "base", t, step), d = descending.lookup("odom", "base", t, step),
               s = shuffled.lookup("odom", "base", t, step);
    ASSERT_TRUE(a && d && s) << t;
    EXPECT_EQ(a->matrix(), d->matrix()) << t;
    EXPECT_EQ(a->matrix(), s->matrix()) << t;
    expectNear(*a, baseAt(static_cast<double>(t) * 1e-9), 1e-9);
  }
  // Two samples at one stamp: the later one added is the one found after the earlier.
  TfTree twice;
  add(twice, "odom", "base", 2 * kSecond, baseAt(2.0), false);
  add(twice, "odom", "base", kSecond, baseAt(1.0), false);
  add(twice, "odom", "base", kSecond, baseAt(5.0), false);
  twice.sortSamples();
  expectNear(*twice.lookup("odom", "base", kSecond, 0), baseAt(1.0), 1e-12);
}

TEST(TfTree, RefusesBrokenTrees) {
  TfTree tree;
  add(tree, "a", "b", 0, Eigen::Isometry3d::Identity(), true);
  EXPECT_THROW(add(tree, "c", "b", 0, Eigen::Isometry3d::Identity(), true), TfError);  // two parents
  EXPECT_THROW(add(tree, "a", "a", 0, Eigen::Isometry3d::Identity(), true), TfError);  // its own parent
  EXPECT_THROW(add(tree, "a", "b", 0, Eigen::Isometry3d::Identity(), false), TfError);  // static and sampled
  EXPECT_THROW(tree.add("a", "x", 0, Eigen::Vector3d(NAN, 0, 0), Eigen::Quaterniond::Identity(), true), TfError);
  EXPECT_THROW(tree.add("a", "x", 0, Eigen::Vector3d::Zero(), Eigen::Quaterniond(2, 0, 0, 0), true), TfError);
  add(tree, "b", "c", 0, Eigen::Isometry3d::Identity(), true);
  add(tree, "c", "a", 0, Eigen::Isometry3d::Identity(), true);
  try {
    (void)tree.lookup("a", "c", 0, 0);
    FAIL() << "a cycle was not found";
  } catch (const TfError& e) {
    EXPECT_NE(std::string(e.what()).find("cycle"), std::string::npos) << e.what();
  }
  TfTree two;
  add(two, "map", "odom", 0, Eigen::Isometry3d::Identity(), true);
  add(two, "base", "camera", 0, Eigen::Isometry3d::Identity(), true);
  try {
    (void)two.lookup("map", "camera", 0, 0);
    FAIL();
  } catch (const TfError& e) {
    EXPECT_NE(std::string(e.what()).find("not connected: their roots are \"base\" and \"map\""), std::string::npos) << e.what();
  }
  try {
    (void)two.lookup("map", "lidar", 0, 0);
    FAIL();
  } catch (const TfError& e) {
    EXPECT_NE(std::string(e.what()).find("\"lidar\" is not in the TF tree (its frames: base, camera, map, odom)"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace mobmap::sources

TEST(TfTree, ForgettingOldSamplesKeepsEveryLookupFromTheCutOn) {
  // A live buffer's bound: lookups at and after the cut are those of the full tree.
  mobmap::sources::TfTree full, pruned;
  for (int i = 0; i < 100; ++i) {
    const std::int64_t t = i * 10'000'000LL;
    const Eigen::Vector3d p(0.01 * i, std::sin(0.1 * i), 0.0);
    const Eigen::Quaterniond q(Eigen::AngleAxisd(0.02 * i, Eigen::Vector3d::UnitZ()));
    for (auto* tree : {&full, &pruned}) {
      tree->add("odom", "base", t, p, q, false);
      tree->add("base", "camera", 0, Eigen::Vector3d(0.1, 0, 0.5), Eigen::Quaterniond::Identity(), true);
    }
  }
  const std::int64_t cut = 503'000'000LL;  // between two samples
  pruned.forgetBefore(cut);
  for (const auto& e : pruned.edges()) {
    if (e.child == "base") {
      EXPECT_EQ(e.samples, 50u);  // the one before the cut and the 49 after it
    }
  }
  for (std::int64_t t = cut; t <= 990'000'000LL; t += 7'000'000LL) {
    const auto a = full.lookup("odom", "camera", t, 20'000'000LL), b = pruned.lookup("odom", "camera", t, 20'000'000LL);
    ASSERT_TRUE(a && b) << t;
    EXPECT_TRUE(a->isApprox(*b, 1e-12)) << t;
  }
  EXPECT_FALSE(pruned.lookup("odom", "camera", cut - 20'000'000LL, 20'000'000LL));
}
