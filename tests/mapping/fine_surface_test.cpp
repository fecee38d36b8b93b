// The fused fine surface (MapParams::fine_surface): height fields with exact area ratios
// seen by a depth camera from above, fused, and what finalize() then says.
#include "mapping_support.hpp"

#include "mobmap/gp/mobility_model.hpp"

#include <algorithm>
#include <functional>

namespace mobmap::mapping {
namespace {

using Height = std::function<double(double x, double y)>;

constexpr double kBase = 0.005;  // the floor, inside a voxel rather than on its boundary

// Square pyramids (pitch 10 cm, 5.59 cm tall) over [-0.5, 0.5]^2: each facet rises
// 1.118 per unit run, so A/A' = sqrt(1 + 1.118^2) = 1.5.
double pyramids(double x, double y) {
  if (std::abs(x) >= 0.5 || std::abs(y) >= 0.5) return kBase;
  const double p = 0.1, h = 0.0559;
  const double dx = x - (std::floor(x / p) + 0.5) * p, dy = y - (std::floor(y / p) + 0.5) * p;
  return kBase + h * (1 - std::max(std::abs(dx), std::abs(dy)) / (p / 2));
}

// Blocks 8 cm square and 6 cm tall, one in the middle of each 15 cm cell over
// [-0.6, 0.6]^2: A/A' = 1 + 4 x 0.08 x 0.06 / 0.15^2 = 1.853.
double blocks(double x, double y) {
  if (std::abs(x) >= 0.6 || std::abs(y) >= 0.6) return kBase;
  const double p = 0.15;
  const double dx = x - (std::floor(x / p) + 0.5) * p, dy = y - (std::floor(y / p) + 0.5) * p;
  return kBase + (std::abs(dx) < 0.04 && std::abs(dy) < 0.04 ? 0.06 : 0.0);
}

// A floor with a stair's step (17 cm up for x > 0.2) and a 5 cm curb (y > 0.3, x < 0.2).
double stepAndCurb(double x, double y) {
  if (x > 0.2) return kBase + 0.17;
  return kBase + (y > 0.3 ? 0.05 : 0.0);
}

// A depth camera 1 m above the floor looking straight down, at (cx, cy).
struct View {
  perception::DepthImage depth;
  perception::PinholeIntrinsics k;
  perception::FrameResult frame;
  Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();
};

View render(const Height& height, double cx, double cy) {
  View v;
  v.k.width = 320, v.k.height = 240, v.k.fx = v.k.fy = 200, v.k.cx = 160, v.k.cy = 120;
  v.depth = perception::DepthImage(v.k.width, v.k.height);
  Eigen::Matrix3d R;  // camera x = world x, camera y = world -y, camera z (forward) = world -z
  R << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  v.T_world_camera.linear() = R;
  v.T_world_camera.translation() = Eigen::Vector3d(cx, cy, 1.0);
  perception::Segment all;
  all.mobility = 1.0;
  all.variance = 0.002;
  for (int r = 0; r < v.k.height; ++r) {
    for (int c = 0; c < v.k.width; ++c) {
      const Eigen::Vector3d ray = R * Eigen::Vector3d((c - v.k.cx) / v.k.fx, (r - v.k.cy) / v.k.fy, 1.0);
      // The first depth (along the optical axis) where the ray meets the surface: march
      // in 2 mm, then halve the step.
      const auto above = [&](double d) {
        const Eigen::Vector3d p = v.T_world_camera.translation() + d * ray;
        return p.z() > height(p.x(), p.y());
      };
      double d = 0.5;
      while (d < 1.5 && above(d)) d += 0.002;
      double lo = d - 0.002, hi = d;
      for (int i = 0; i < 20; ++i) (above(0.5 * (lo + hi)) ? lo : hi) = 0.5 * (lo + hi);
      v.depth.at(c, r) = static_cast<float>(hi);
      v.frame.points.emplace_back(static_cast<float>((c - v.k.cx) / v.k.fx * hi), static_cast<float>((r - v.k.cy) / v.k.fy * hi),
                                  static_cast<float>(hi));
      v.frame.segment_of_point.push_back(0);
      all.points.push_back(static_cast<int>(v.frame.points.size() - 1));
    }
  }
  v.frame.segments = {all};
  return v;
}

// The map of nine views over a 1.2 m square, fused and finalized.
MobilityMap fused(const Height& height, bool fine) {
  MapParams p;
  p.fine_surface = fine;
  MobilityMap map(p);
  for (const double cy : {-0.4, 0.0, 0.4}) {
    for (const double cx : {-0.4, 0.0, 0.4}) {
      const View v = render(height, cx, cy);
      map.integrate(v.frame, v.T_world_camera, &v.depth, &v.k);
    }
  }
  map.finalize();
  return map;
}

// The rough voxels whose centres lie within `half` of the origin (x and y).
std::vector<RoughVoxel> inside(const MobilityMap& map, double half) {
  std::vector<RoughVoxel> out;
  for (const RoughVoxel& v : map.roughVoxels()) {
    if (std::abs(v.centre.x()) < half && std::abs(v.centre.y()) < half) out.push_back(v);
  }
  return out;
}

TEST(FineSurface, PyramidsReadTheirAreaRatioAndTheModelsMobility) {
  const MobilityMap map = fused(pyramids, true);
  // Away from the field's edge by more than the window: every surface voxel is rough
  // ground (no flat sole fits), its A/A' near 1.5, its slope near 0 and its mobility the
  // model's for the two.
  const std::vector<RoughVoxel> rough = inside(map, 0.5 - 0.14);
  std::size_t surface = 0;
  for (auto it = map.tree().begin_leafs(), end = map.tree().end_leafs(); it != end; ++it) {
    const octomap::point3d c = it.getCoordinate();
    if (map.tree().isNodeOccupied(*it) && std::abs(c.x()) < 0.36 && std::abs(c.y()) < 0.36) ++surface;
  }
  ASSERT_GT(surface, 1000u);
  EXPECT_GE(rough.size(), surface * 9 / 10);
  double ratio = 0;
  const gp::MobilityModel model;
  for (const RoughVoxel& v : rough) {
    ratio += v.roughness / static_cast<double>(rough.size());
    EXPECT_LT(v.slope_deg, 5.0);
    EXPECT_NEAR(v.mobility, std::clamp(model.predict(v.slope_deg, v.roughness).mobility, 0.0, 1.0), 1e-9);
    const PointQuery q = map.query(v.centre);
    ASSERT_TRUE(q.has_mobility);
    EXPECT_NEAR(q.mobility, v.mobility, 1e-3);  // the voxel holds it (14-bit mobility)
  }
  EXPECT_NEAR(ratio, 1.5, 0.08);
  // The floor around the field holds a sole: the frames' score stays.
  EXPECT_TRUE(inside(map, 2.0).size() == inside(map, 0.62).size());
  EXPECT_NEAR(map.query(Eigen::Vector3d(0.8, 0.0, kBase)).mobility, 1.0, 1e-3);
}

TEST(FineSurface, BlocksReadTheSidesNoViewSaw) {
  // From straight above no view sees a block's sides; the height field implies them.
  const MobilityMap map = fused(blocks, true);
  const std::vector<RoughVoxel> rough = inside(map, 0.6 - 0.14);
  ASSERT_GT(rough.size(), 500u);
  double ratio = 0, mobility = 0;
  for (const RoughVoxel& v : rough) {
    ratio += v.roughness / static_cast<double>(rough.size());
    mobility += v.mobility / static_cast<double>(rough.size());
  }
  EXPECT_NEAR(ratio, 1.853, 0.15);
  EXPECT_LT(mobility, 0.25);  // the rule: 1.8 and rougher is 0 on level ground
}

// Whether a voxel centre lies on one of stepAndCurb's levels (its voxel holds the level).
bool onALevel(const Eigen::Vector3d& c) {
  for (const double level : {kBase, kBase + 0.05, kBase + 0.17}) {
    if (std::abs(c.z() - level) < 0.01) return true;
  }
  return false;
}

TEST(FineSurface, AStepAndACurbAreNotRoughGround) {
  // Each side of a step or a curb holds a sole: no voxel on a level is scored as rough
  // ground, and there the map's mobility is the frames' voxel for voxel. (A riser's
  // voxels between the levels may be: a vertical face is 0 either way.)
  const MobilityMap fine = fused(stepAndCurb, true);
  const MobilityMap frames = fused(stepAndCurb, false);
  for (const RoughVoxel& v : fine.roughVoxels()) EXPECT_FALSE(onALevel(v.centre)) << v.centre.transpose();
  EXPECT_GT(fine.roughGroundReport().supported, 1000u);
  std::size_t compared = 0;
  for (auto it = frames.tree().begin_leafs(), end = frames.tree().end_leafs(); it != end; ++it) {
    if (!frames.tree().isNodeOccupied(*it) || !it->hasMobility()) continue;
    if (!onALevel(Eigen::Vector3d(it.getX(), it.getY(), it.getZ()))) continue;
    const PointQuery q = fine.query(Eigen::Vector3d(it.getX(), it.getY(), it.getZ()));
    ASSERT_TRUE(q.has_mobility);
    EXPECT_EQ(q.mobility, it->mobility());
    ++compared;
  }
  EXPECT_GT(compared, 1000u);
}

TEST(FineSurface, TheFusedSurfaceLiesOnTheFloorItSaw) {
  const MobilityMap map = fused(stepAndCurb, true);
  const std::vector<FineSurfacePoint> points = map.fineSurface(1.0);
  ASSERT_GT(points.size(), 1000u);
  std::size_t level = 0;
  for (const FineSurfacePoint& p : points) {
    // Away from the step's and the curb's edges every point is on its level, its
    // normal up.
    if (std::abs(p.point.x() - 0.2) < 0.03 || (std::abs(p.point.y() - 0.3) < 0.03 && p.point.x() < 0.23)) continue;
    EXPECT_NEAR(p.point.z(), stepAndCurb(p.point.x(), p.point.y()), 0.002) << p.point.transpose();
    EXPECT_GT(p.normal.z(), std::cos(2.0 * M_PI / 180)) << p.point.transpose();
    EXPECT_GE(p.views, 1);
    ++level;
  }
  EXPECT_GT(level, 1000u);
  // Without the fine surface, none is kept.
  EXPECT_TRUE(fused(stepAndCurb, false).fineSurface().empty());
  EXPECT_EQ(fused(stepAndCurb, false).fineSurfaceBytes(), 0u);
}

TEST(FineSurface, ThePlyHoldsTheSurfaceAndTheRoughVoxels) {
  const MobilityMap map = fused(pyramids, true);
  const std::string path = tempPath("surface.ply");
  map.saveFineSurfacePly(path);
  std::ifstream in(path, std::ios::binary);
  std::string line, header;
  std::size_t count = 0;
  while (std::getline(in, line) && line != "end_header") {
    header += line + "\n";
    if (line.rfind("element vertex ", 0) == 0) count = std::stoul(line.substr(15));
  }
  EXPECT_NE(header.find("format binary_little_endian 1.0"), std::string::npos);
  EXPECT_NE(header.find("property ushort views\nproperty float roughness\nproperty float mobility"), std::string::npos);
  // Read back: the same points as fineSurface(), and a roughness on exactly the voxels
  // finalize() scored, each the one it measured there.
  std::vector<FineSurfacePoint> expected = map.fineSurface();
  ASSERT_EQ(count, expected.size());
  const auto less = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return std::tie(a.x(), a.y(), a.z()) < std::tie(b.x(), b.y(), b.z());
  };
  std::sort(expected.begin(), expected.end(), [&](const FineSurfacePoint& a, const FineSurfacePoint& b) { return less(a.point, b.point); });
  std::vector<Eigen::Vector3d> read;
  std::size_t rough = 0;
  for (std::size_t i = 0; i < count; ++i) {
    float v[7], roughness = 0, mobility = 0;
    std::uint16_t views = 0;
    in.read(reinterpret_cast<char*>(v), sizeof v);
    in.read(reinterpret_cast<char*>(&views), 2);
    in.read(reinterpret_cast<char*>(&roughness), 4);
    in.read(reinterpret_cast<char*>(&mobility), 4);
    ASSERT_TRUE(in);
    read.emplace_back(v[0], v[1], v[2]);
    EXPECT_NEAR(Eigen::Vector3d(v[3], v[4], v[5]).norm(), 1.0, 1e-5);
    EXPECT_GE(views, 1);
    EXPECT_TRUE(mobility == -1.0f || (mobility >= 0.0f && mobility <= 1.0f));
    if (roughness > 0) {
      ++rough;
      EXPECT_GE(roughness, 1.0f);
    }
  }
  EXPECT_EQ(in.peek(), EOF);
  std::sort(read.begin(), read.end(), less);
  for (std::size_t i = 0; i < count; ++i) EXPECT_LT((read[i] - expected[i].point).norm(), 1e-5);
  // The voxels scored as rough ground that have points of their own carry their A/A'
  // (those scored from their neighbours' surface alone have no point here).
  EXPECT_GT(rough, 1000u);
  EXPECT_LE(rough, map.roughVoxels().size());
}

TEST(FineSurface, ItsParametersAreCheckedByName) {
  const auto message = [](const std::function<void(MapParams&)>& set) {
    MapParams p;
    set(p);
    try {
      validate(p);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(message([](MapParams& p) { p.fine_min_weight = 0; }).find("fine_min_weight"), std::string::npos);
  EXPECT_NE(message([](MapParams& p) { p.fine_max_range_m = -1; }).find("fine_max_range_m"), std::string::npos);
  EXPECT_NE(message([](MapParams& p) { p.fine_window_m = 2; }).find("fine_window_m"), std::string::npos);
  EXPECT_NE(message([](MapParams& p) { p.fine_support_m = 0; }).find("fine_support_m"), std::string::npos);
  EXPECT_NE(message([](MapParams& p) { p.fine_support_length_m = 0.05; }).find("fine_support_length_m"), std::string::npos);
  EXPECT_EQ(message([](MapParams&) {}), "");
}

}  // namespace
}  // namespace mobmap::mapping
