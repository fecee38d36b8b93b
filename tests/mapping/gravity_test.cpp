// Map parameters and gravity: alignment, the floor-normal consensus, rigid transforms.
#include "mapping_support.hpp"

namespace mobmap::mapping {
namespace {

TEST(MapParams, RejectsAbsurdValuesNamingTheField) {
  MapParams p;
  p.resolution_m = -0.02;
  try {
    MobilityMap{p};
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("resolution_m"), std::string::npos);
  }
  p = {};
  p.prob_hit = 0.4;
  EXPECT_THROW(MobilityMap{p}, std::invalid_argument);
}


TEST(Gravity, AlignmentSendsGravityToMinusZAndIsIdentityForZUp) {
  const Eigen::Vector3d g(-0.0089, 0.9044, 0.4265);  // 7-Scenes redkitchen
  const Eigen::Matrix3d r = gravityAlignment(g);
  EXPECT_LT((r * g.normalized() - Eigen::Vector3d(0, 0, -1)).norm(), 1e-12);
  EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
  EXPECT_LT((gravityAlignment({0, 0, -3}) - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_LT((gravityAlignment({0, 0, 1}) * Eigen::Vector3d(0, 0, 1) - Eigen::Vector3d(0, 0, -1)).norm(), 1e-12);
  EXPECT_THROW(gravityAlignment(Eigen::Vector3d::Zero()), std::invalid_argument);
}

// Floors seen in five frames, 1-2 degrees apart around a known "down", and two frames
// that took a wall for the floor (one of them heavier than any single floor).
TEST(Gravity, ConsensusOfFloorNormalsOutvotesWallsAndAveragesTheFloors) {
  const Eigen::Vector3d truth = Eigen::Vector3d(0.31, -0.93, 0.19).normalized();
  const Eigen::Vector3d side = truth.unitOrthogonal();
  const auto tilted = [&](double deg, const Eigen::Vector3d& axis) {
    return Eigen::AngleAxisd(deg * M_PI / 180.0, axis.cross(truth).normalized()) * truth;
  };
  std::vector<DownObservation> obs;
  for (double deg : {-1.5, -0.5, 0.0, 0.5, 1.5}) obs.push_back({tilted(deg, side), 1000.0});
  const Eigen::Vector3d wall = side;
  obs.push_back({wall, 3000.0});
  obs.push_back({truth.cross(wall), 500.0});  // another vertical plane
  obs.push_back({Eigen::Vector3d(std::nan(""), 0, 0), 1e9});            // ignored
  obs.push_back({Eigen::Vector3d::Zero(), 1e9});                         // ignored
  obs.push_back({truth, 0.0});                                            // no weight: ignored
  const auto c = consensusDown(obs, 5.0);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->agreeing, 5);
  EXPECT_NEAR(c->weight_share, 5000.0 / 8500.0, 1e-12);
  EXPECT_LT(std::acos(std::min(1.0, c->down.dot(truth))) * 180.0 / M_PI, 0.01);  // symmetric tilts cancel
  EXPECT_NEAR(c->spread_deg, 1.5, 1e-6);
  EXPECT_NEAR(c->down.norm(), 1.0, 1e-12);
  // Scale does not matter; only the weights do.
  std::vector<DownObservation> scaled = {{truth * 9.81, 1.0}, {-truth * 1e-3, 2.0}};
  const auto up_wins = consensusDown(scaled);
  ASSERT_TRUE(up_wins);
  EXPECT_LT((up_wins->down + truth).norm(), 1e-12);
  EXPECT_EQ(up_wins->agreeing, 1);
  EXPECT_FALSE(consensusDown({}));
  EXPECT_FALSE(consensusDown({{Eigen::Vector3d::Zero(), 1.0}}));
}

TEST(Gravity, CheckRigidNamesTheProblem) {
  Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
  EXPECT_FALSE(checkRigid(t));
  t(0, 0) = 1.1;
  EXPECT_NE(checkRigid(t)->find("orthonormal"), std::string::npos);
  t = Eigen::Matrix4d::Identity();
  t(3, 0) = 1;
  EXPECT_NE(checkRigid(t)->find("bottom row"), std::string::npos);
  t = Eigen::Matrix4d::Identity();
  t(1, 1) = std::nan("");
  EXPECT_NE(checkRigid(t)->find("NaN"), std::string::npos);
}

}  // namespace
}  // namespace mobmap::mapping
