// The synthetic corridor against independent analytic oracles.
#include "mobmap/sim/corridor_scene.hpp"

#include <gtest/gtest.h>
#include "mobmap/gp/rule_table.hpp"
#include <map>

#include <cmath>
#include <set>

namespace mobmap::sim {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;
// Depth is stored as float: 2^-24 relative, under 1 um at 10 m.
constexpr double kFloatDepthTol = 1e-5;

Eigen::Vector3d worldRay(const perception::PinholeIntrinsics& k, const Eigen::Isometry3d& T, int u, int v) {
  return T.linear() * perception::pixelRay(k, u, v);  // camera z component of the ray is 1
}

TEST(CorridorScene, FloorDepthEqualsAnalyticRayPlaneIntersection) {
  const CorridorScene scene;
  for (int frame : {0, 57, 200}) {
    const RenderedFrame r = scene.render(frame);
    const auto& k = scene.params().intrinsics;
    int checked = 0;
    for (int v = 0; v < k.height; v += 7) {
      for (int u = 0; u < k.width; u += 7) {
        if (r.labels[static_cast<std::size_t>(v * k.width + u)] != 1) continue;  // floor
        const Eigen::Vector3d o = r.T_world_camera.translation();
        const Eigen::Vector3d d = worldRay(k, r.T_world_camera, u, v);
        const double t = -o.z() / d.z();  // o + t d on z = 0; t is the camera depth
        EXPECT_NEAR(r.exact_depth.at(u, v), t, kFloatDepthTol) << "frame " << frame << " pixel " << u << "," << v;
        ++checked;
      }
    }
    EXPECT_GT(checked, 500) << "frame " << frame;
  }
}

TEST(CorridorScene, RampDepthEqualsAnalyticRayPlaneIntersection) {
  const CorridorScene scene;
  const RenderedFrame r = scene.render(30);
  const auto& k = scene.params().intrinsics;
  std::set<int> ramps_seen;
  for (int v = 0; v < k.height; v += 3) {
    for (int u = 0; u < k.width; u += 3) {
      const int id = r.labels[static_cast<std::size_t>(v * k.width + u)];
      if (id == 0 || scene.surface(id).kind != SurfaceKind::kRamp) continue;
      const Surface& s = scene.surface(id);
      const Eigen::Vector3d p0 = s.polygons[0][0];
      const Eigen::Vector3d o = r.T_world_camera.translation();
      const Eigen::Vector3d d = worldRay(k, r.T_world_camera, u, v);
      const double t = s.normal.dot(p0 - o) / s.normal.dot(d);
      EXPECT_NEAR(r.exact_depth.at(u, v), t, kFloatDepthTol);
      ramps_seen.insert(id);
    }
  }
  EXPECT_GE(ramps_seen.size(), 3u);
}

TEST(CorridorScene, RampSlopesAreExactAndScoredByThePaperTable) {
  const CorridorScene scene;
  std::vector<double> slopes;
  for (const auto& s : scene.surfaces()) {
    if (s.kind == SurfaceKind::kRamp) slopes.push_back(s.slope_deg);
    if (s.kind == SurfaceKind::kWall || s.kind == SurfaceKind::kStairRiser) {
      EXPECT_DOUBLE_EQ(s.slope_deg, 90.0);
      EXPECT_DOUBLE_EQ(s.expected_mobility, 0.0);
    }
    if (s.kind == SurfaceKind::kStairTread || s.kind == SurfaceKind::kFloor) {
      EXPECT_DOUBLE_EQ(s.slope_deg, 0.0);
      EXPECT_DOUBLE_EQ(s.expected_mobility, 1.0);
    }
  }
  const std::vector<double> expected = {5, 15, 25, 35, 45};
  ASSERT_EQ(slopes.size(), expected.size());
  for (std::size_t i = 0; i < slopes.size(); ++i) EXPECT_NEAR(slopes[i], expected[i], 1e-9);
}

TEST(CorridorScene, StairRisersAreBetween15And18Centimetres) {
  const CorridorScene scene;
  int risers = 0;
  for (const auto& s : scene.surfaces()) {
    if (s.kind != SurfaceKind::kStairRiser) continue;
    double zmin = 1e9, zmax = -1e9;
    for (const auto& p : s.polygons[0]) {
      zmin = std::min(zmin, p.z());
      zmax = std::max(zmax, p.z());
    }
    EXPECT_GE(zmax - zmin, 0.15);
    EXPECT_LE(zmax - zmin, 0.18);
    ++risers;
  }
  EXPECT_GE(risers, 3);
}

TEST(CorridorScene, RoughPatchPointsLieOnTheHeightField) {
  const CorridorScene scene;
  const RenderedFrame r = scene.render(20);
  const auto& k = scene.params().intrinsics;
  const int rough_id = [&] {
    for (const auto& s : scene.surfaces()) {
      if (s.kind == SurfaceKind::kRough) return s.id;
    }
    return -1;
  }();
  int n = 0;
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      if (r.labels[static_cast<std::size_t>(v * k.width + u)] != rough_id) continue;
      const Eigen::Vector3d p = r.T_world_camera * perception::backProject(k, u, v, r.exact_depth.at(u, v));
      EXPECT_NEAR(p.z(), scene.roughPatch().heightAt(p.x(), p.y()), 1e-4);
      ++n;
    }
  }
  EXPECT_GT(n, 1000);
}

TEST(PyramidField, ExactRatioMatchesBruteForceFineTriangulation) {
  const CorridorScene scene;
  const PyramidField& f = scene.roughPatch();
  EXPECT_NEAR(f.exactAreaRatio(), 1.5, 1e-12);  // designed value
  // A regular grid triangulation converges to the true area as it is refined; with
  // 64 grid cells per pyramid the only error is in the cells straddling a ridge.
  const double coarse = bruteForceAreaRatio(f, f.nx * 8);
  const double fine = bruteForceAreaRatio(f, f.nx * 64);
  EXPECT_NEAR(fine, f.exactAreaRatio(), 2e-3);
  EXPECT_LT(std::abs(fine - f.exactAreaRatio()), std::abs(coarse - f.exactAreaRatio()) + 1e-12);
  // With the grid aligned to every ridge (even cells per pyramid, diagonal split
  // matching half the ridges) the error comes only from the other diagonal.
  EXPECT_GT(f.exactAreaRatio(), 1.2);
}

TEST(CorridorScene, DeterministicForASeedAndSeedChangesNoise) {
  CorridorParams p;
  p.noise = NoiseModel::kKinect;
  p.seed = 7;
  const CorridorScene a(p), b(p);
  p.seed = 8;
  const CorridorScene c(p);
  const auto ra = a.render(12), rb = b.render(12), rc = c.render(12);
  EXPECT_EQ(ra.depth.depth_m, rb.depth.depth_m);
  EXPECT_EQ(ra.labels, rb.labels);
  EXPECT_NE(ra.depth.depth_m, rc.depth.depth_m);
  EXPECT_EQ(ra.exact_depth.depth_m, rc.exact_depth.depth_m);  // geometry does not depend on the seed
}

TEST(CorridorScene, KinectNoiseGrowsWithTheSquareOfDepth) {
  CorridorParams p;
  p.noise = NoiseModel::kKinect;
  p.kinect.edge_window_px = 0;  // the per-pixel noise alone: no edge smoothing, no shadow
  p.kinect.projector_shadow = false;
  const CorridorScene scene(p);
  // Residuals binned by depth: sigma(z) = sqrt((s1 z^2)^2 + q(z)^2 / 12), q the
  // disparity quantisation step in depth, z^2 / (fx b) / 8.
  const double bins[][2] = {{1.5, 1.9}, {2.6, 3.2}};  // the nearest floor is ~1.5 m deep
  for (const auto& bin : bins) {
    double sum2 = 0, zsum = 0;
    int n = 0;
    for (int f = 0; f < 60; f += 6) {
      const auto r = scene.render(f);
      for (std::size_t i = 0; i < r.depth.depth_m.size(); ++i) {
        const double z = r.exact_depth.depth_m[i];
        if (z < bin[0] || z > bin[1] || r.depth.depth_m[i] <= 0) continue;
        const double e = r.depth.depth_m[i] - z;
        sum2 += e * e;
        zsum += z;
        ++n;
      }
    }
    ASSERT_GT(n, 1000);
    const double zm = zsum / n;
    const double axial = p.kinect.axial_sigma_at_1m_m * zm * zm;
    const double q = zm * zm / (p.intrinsics.fx * p.kinect.baseline_m) * p.kinect.disparity_subpixel;
    const double model = std::sqrt(axial * axial + q * q / 12.0);
    EXPECT_NEAR(std::sqrt(sum2 / n), model, 0.25 * model) << "depth bin around " << zm << " m";
  }
}

TEST(CorridorScene, GrazingReturnsGoMissingWithKinectNoise) {
  CorridorParams p;
  p.noise = NoiseModel::kKinect;
  p.kinect.edge_window_px = 0;  // the per-pixel noise alone: no edge smoothing, no shadow
  p.kinect.projector_shadow = false;
  const CorridorScene scene(p);
  const auto tris = scene.trianglesAt(40);
  const auto rc = castRays(tris, p.intrinsics, scene.cameraPose(40));
  const auto r = scene.render(40);
  int steep = 0, steep_missing = 0, facing = 0, facing_missing = 0;
  for (std::size_t i = 0; i < rc.incidence_cos.size(); ++i) {
    if (rc.labels[i] == 0 || rc.depth.depth_m[i] > p.kinect.max_depth_m) continue;
    const double angle = std::acos(std::min(1.0f, rc.incidence_cos[i])) / kDeg;
    const bool missing = r.depth.depth_m[i] <= 0;
    if (angle > p.kinect.dropout_full_deg) {
      ++steep;
      steep_missing += missing;
    } else if (angle < p.kinect.dropout_start_deg) {
      ++facing;
      facing_missing += missing;
    }
  }
  EXPECT_GT(steep, 100);
  EXPECT_EQ(steep_missing, steep);
  EXPECT_EQ(facing_missing, 0);
}

TEST(CorridorScene, MovingBoxLeavesItsStartingPlace) {
  const CorridorScene scene;
  const auto& m = scene.movingObstacle();
  EXPECT_LT(m.start_frame, m.end_frame);
  EXPECT_LT(m.end_frame, scene.params().frames);
  // Where the box stood at frame 0, the floor is seen once it has gone.
  const auto& k = scene.params().intrinsics;
  auto labelsAround = [&](int frame) {
    const auto r = scene.render(frame);
    int moving = 0, floor = 0;
    for (int v = 0; v < k.height; ++v) {
      for (int u = 0; u < k.width; ++u) {
        const int id = r.labels[static_cast<std::size_t>(v * k.width + u)];
        if (id == 0) continue;
        const Eigen::Vector3d p = r.T_world_camera * perception::backProject(k, u, v, r.exact_depth.at(u, v));
        const bool in_old_footprint = std::abs(p.x() - m.from.x()) < 0.15 && std::abs(p.y() - m.from.y()) < 0.15;
        if (!in_old_footprint) continue;
        if (scene.surface(id).moving) ++moving;
        if (scene.surface(id).kind == SurfaceKind::kFloor && p.z() < 1e-6) ++floor;
      }
    }
    return std::make_pair(moving, floor);
  };
  const auto before = labelsAround(0);
  const auto after = labelsAround(m.end_frame + 2);
  EXPECT_GT(before.first, 500);
  EXPECT_EQ(before.second, 0);
  EXPECT_EQ(after.first, 0);
  EXPECT_GT(after.second, 500);
}

TEST(CorridorScene, CameraIsHeadMountedPitchedDownAndWalksForward) {
  const CorridorScene scene;
  const auto& p = scene.params();
  for (int f = 0; f < p.frames; f += 10) {
    const Eigen::Isometry3d T = scene.cameraPose(f);
    EXPECT_GE(T.translation().z(), 1.2);
    EXPECT_LE(T.translation().z(), 1.5);
    const Eigen::Vector3d forward = T.linear().col(2);
    const double pitch = std::asin(-forward.z()) / kDeg;
    EXPECT_NEAR(pitch, p.pitch_down_deg, 1.5);
    EXPECT_NEAR((T.linear().transpose() * T.linear() - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-12);
  }
  const double speed = (scene.cameraPose(p.frames - 1).translation().x() - scene.cameraPose(0).translation().x()) /
                       ((p.frames - 1) / p.frame_rate_hz);
  EXPECT_NEAR(speed, p.speed_mps, 1e-9);
  EXPECT_THROW((void)scene.cameraPose(p.frames), std::out_of_range);
}

TEST(CorridorScene, RejectsUnusableParameters) {
  CorridorParams p;
  p.frames = 0;
  EXPECT_THROW(CorridorScene{p}, std::invalid_argument);
  p = {};
  p.intrinsics.fx = -1;
  EXPECT_THROW(CorridorScene{p}, std::invalid_argument);
}

}  // namespace

// The rough yard: each field's area ratio is the analytic one (ridges, blocks) or, for the
// stones, the sum over their boxes; the floor and the fields' footprints tile the
// corridor without gap or overlap; every pixel a field shows lies on or over its
// footprint, no higher than its top; the rule gives each field its expected mobility.
TEST(RoughYard, FieldsHaveTheirExactAreaRatiosAndTileTheFloor) {
  CorridorParams p;
  p.layout = Layout::kRoughYard;
  p.frames = 120;
  const CorridorScene scene(p);
  const RoughYardParams& y = p.yard;
  std::map<std::string, const Surface*> by_name;
  for (const Surface& s : scene.surfaces()) by_name[s.name] = &s;
  ASSERT_EQ(by_name.count("pyramids") + by_name.count("ridges along the path") + by_name.count("ridges across the path") +
                by_name.count("blocks") + by_name.count("stones"),
            5u);
  EXPECT_NEAR(by_name["pyramids"]->roughness, 1.5, 1e-9);
  const double ridge = std::sqrt(1 + std::pow(2 * y.ridge_height_m / y.ridge_pitch_m, 2));
  EXPECT_NEAR(by_name["ridges along the path"]->roughness, ridge, 1e-9);
  EXPECT_NEAR(by_name["ridges across the path"]->roughness, ridge, 1e-9);
  EXPECT_NEAR(by_name["blocks"]->roughness, 1 + 4 * y.block_side_m * y.block_height_m / (y.block_pitch_m * y.block_pitch_m), 1e-9);
  const double stones = by_name["stones"]->roughness;
  EXPECT_GT(stones, 1 + 2 * 2 * y.stone_min_side_m * y.stone_min_height_m / (y.stone_pitch_m * y.stone_pitch_m));
  EXPECT_LT(stones, 1 + 2 * 2 * y.stone_max_side_m * y.stone_max_height_m / (y.stone_pitch_m * y.stone_pitch_m));
  for (const auto& [name, s] : by_name) {
    if (s->kind == SurfaceKind::kRough) {
      EXPECT_NEAR(s->expected_mobility, gp::RuleTable::paper().lookup(0.0, s->roughness), 1e-12) << name;
      EXPECT_GT(s->top_m, 0.0) << name;
    }
  }
  // Floor and footprints: the corridor's 11 x 3 m, once.
  const auto area = [](const std::vector<Eigen::Vector3d>& poly) {
    Eigen::Vector3d n = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < poly.size(); ++i) n += poly[i].cross(poly[(i + 1) % poly.size()]);
    return 0.5 * std::abs(n.z());
  };
  double covered = 0;
  for (const Surface& s : scene.surfaces()) {
    if (s.kind != SurfaceKind::kFloor && s.kind != SurfaceKind::kRough) continue;
    for (const auto& poly : s.polygons) covered += area(poly);
  }
  EXPECT_NEAR(covered, 11.0 * 3.0, 1e-9);
  // Pixels of a field lie over its footprint, between 0 and its top.
  const RenderedFrame r = scene.render(80);
  const auto& k = scene.params().intrinsics;
  std::map<int, int> seen;
  for (int v = 0; v < k.height; v += 2) {
    for (int u = 0; u < k.width; u += 2) {
      const int id = r.labels[static_cast<std::size_t>(v * k.width + u)];
      if (id == 0 || scene.surface(id).kind != SurfaceKind::kRough) continue;
      const Surface& s = scene.surface(id);
      const Eigen::Vector3d q = r.T_world_camera * perception::backProject(k, u, v, r.exact_depth.at(u, v));
      const auto& f = s.polygons.front();
      EXPECT_GE(q.x(), f[0].x() - 1e-6);
      EXPECT_LE(q.x(), f[2].x() + 1e-6);
      EXPECT_GE(q.y(), std::min(f[0].y(), f[2].y()) - 1e-6);
      EXPECT_LE(q.y(), std::max(f[0].y(), f[2].y()) + 1e-6);
      EXPECT_GE(q.z(), -1e-6);
      EXPECT_LE(q.z(), s.top_m + 1e-6);
      ++seen[id];
    }
  }
  EXPECT_GE(seen.size(), 3u);  // frame 80 shows the fields beside the walker
}
}  // namespace mobmap::sim
