// Paper step 6 (region growing) and the departures that follow it: rough surfaces joined,
// left-out points adopted.
#include "perception_support.hpp"

namespace mobmap::perception {
namespace {

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

}  // namespace
}  // namespace mobmap::perception
