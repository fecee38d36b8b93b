// The per-frame pipeline on real Kinect frames from ../shared/data (skipped when the
// folder is absent). Asserts geometric facts of the scenes, not segment counts.
#include "io/dataset.hpp"
#include "io/frame_source.hpp"
#include "mobmap/sources/pcd.hpp"

#include "mobmap/mapping/gravity.hpp"
#include "mobmap/mapping/mobility_map.hpp"

#include "mobmap/perception/pipeline.hpp"
#include "mobmap/perception/stages.hpp"

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>

namespace mobmap {
namespace {

std::string dataFile(const std::string& rel) { return std::string(MOBMAP_SHARED_DATA_DIR) + "/" + rel; }

#define SKIP_WITHOUT(path)                                                              \
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data not found: " << (path)

// Height of a point above the ground plane (n towards the camera, n.x + d = 0).
float heightAbove(const Eigen::Vector4f& plane, const Eigen::Vector3f& p) { return plane.head<3>().dot(p) + plane(3); }

// A least-squares plane through points (normal towards the camera at the origin) and
// the RMS distance of the points from it: the reference surfaces of the real frames,
// fitted here without the pipeline.
struct PlaneFit {
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  double d = 0;
  double rms = 0;
  [[nodiscard]] double height(const Eigen::Vector3d& p) const { return n.dot(p) + d; }
};

PlaneFit fitPlane(const std::vector<Eigen::Vector3d>& pts) {
  PlaneFit fit;
  if (pts.size() < 3) return fit;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : pts) mean += p;
  mean /= static_cast<double>(pts.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : pts) cov += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  fit.n = eig.eigenvectors().col(0);
  if (fit.n.dot(mean) > 0) fit.n = -fit.n;
  fit.d = -fit.n.dot(mean);
  fit.rms = std::sqrt(std::max(0.0, eig.eigenvalues()(0)) / static_cast<double>(pts.size()));
  return fit;
}

// The pixels of an organized frame (depth image or organized cloud) in columns [u0, u1)
// and rows [v0, v1) that measured a point nearer than max_z, and those points.
struct PixelPatch {
  std::vector<std::size_t> pixels;
  std::vector<Eigen::Vector3d> points;
};

PixelPatch patch(const app::Frame& f, int u0, int u1, int v0, int v1, float max_z = 3.f) {
  PixelPatch out;
  const int width = f.depth ? f.depth->width : f.width;
  for (int v = v0; v < v1; ++v)
    for (int u = u0; u < u1; ++u) {
      const std::size_t px = static_cast<std::size_t>(v) * width + u;
      Eigen::Vector3d p;
      if (f.depth) {
        const float z = f.depth->at(u, v);
        if (!(z > 0.f)) continue;
        p = perception::backProject(f.intrinsics, u, v, z);
      } else {
        p = f.points[px].cast<double>();
        if (!p.allFinite()) continue;
      }
      if (!(p.z() < max_z)) continue;
      out.pixels.push_back(px);
      out.points.push_back(p);
    }
  return out;
}

// How many of `pixels` the pipeline kept as a point, and how many of those each segment
// holds (-1: kept but in no segment).
struct PixelSegments {
  std::size_t kept = 0;
  std::map<int, std::size_t> count;
  // The segment holding the most kept pixels, and its share of them.
  [[nodiscard]] std::pair<int, double> dominant() const {
    std::pair<int, std::size_t> best{-1, 0};
    for (const auto& [s, n] : count)
      if (s >= 0 && n > best.second) best = {s, n};
    return {best.first, kept ? static_cast<double>(best.second) / static_cast<double>(kept) : 0.0};
  }
};

PixelSegments segmentsOfPixels(const perception::FrameResult& r, const std::vector<std::size_t>& pixels) {
  PixelSegments out;
  for (std::size_t px : pixels) {
    if (px >= r.point_of_pixel.size()) continue;
    const int i = r.point_of_pixel[px];
    if (i < 0) continue;
    ++out.kept;
    ++out.count[r.segment_of_point[static_cast<std::size_t>(i)]];
  }
  return out;
}

// Both normals oriented towards the camera.
double degreesBetween(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

struct Obstacle {
  Eigen::Vector3f centroid;
  float top = 0;  // highest point above the ground
  double mobility = 0;
};

std::vector<Obstacle> standingObstacles(const perception::FrameResult& r, float min_top, int min_points) {
  std::vector<Obstacle> out;
  for (const auto& s : r.segments) {
    if (s.is_ground || static_cast<int>(s.points.size()) < min_points) continue;
    Obstacle o{s.centroid, 0.f, s.mobility};
    for (int i : s.points) o.top = std::max(o.top, heightAbove(*r.ground_plane, r.points[static_cast<std::size_t>(i)]));
    if (o.top >= min_top) out.push_back(o);
  }
  return out;
}

TEST(RealFrames, FivePeopleFloorIsAbout1_2MetresBelowAndPeopleAreNotTraversable) {
  const std::string path = dataFile("pcl-kinect/five_people.pcd");
  SKIP_WITHOUT(path);
  const app::Frame f = sources::loadPcd(path);
  perception::PerceptionParams p;
  p.max_range_m = 4.0;  // the corridor floor between the people is 2-4 m away
  // No pose in a PCD: the camera is held level, so gravity is roughly +y (OpenCV axes);
  // the ground search accepts planes within 20 degrees of that.
  const auto r = perception::FramePipeline(p).processOrganized(f.points, f.width, f.height, Eigen::Vector3f(0, 1, 0));
  ASSERT_TRUE(r.ground_plane);
  EXPECT_NEAR((*r.ground_plane)(3), 1.24, 0.15);
  const perception::Segment& ground = r.segments.front();
  ASSERT_TRUE(ground.is_ground);
  EXPECT_GE(ground.mobility, 0.75);
  // People: tall non-ground segments, untraversable, spread across the corridor.
  const auto people = standingObstacles(r, 0.8f, 300);
  ASSERT_GE(people.size(), 3u);
  float xmin = 1e9f, xmax = -1e9f;
  for (const auto& o : people) {
    EXPECT_LT(o.mobility, 0.5) << "segment at x " << o.centroid.x();
    xmin = std::min(xmin, o.centroid.x());
    xmax = std::max(xmax, o.centroid.x());
  }
  EXPECT_GT(xmax - xmin, 1.0f);
}

// Without gravity and at the default 3 m range, the corridor's end wall is the largest
// plane (the paper's rule took it for the floor); the upright prior finds the floor,
// a few percent of the points, behind the people.
TEST(RealFrames, FivePeopleWithoutGravityFindsTheFloorNotTheEndWall) {
  const std::string path = dataFile("pcl-kinect/five_people.pcd");
  SKIP_WITHOUT(path);
  const app::Frame f = sources::loadPcd(path);
  const auto r = perception::FramePipeline().processOrganized(f.points, f.width, f.height);
  ASSERT_TRUE(r.ground_plane);
  EXPECT_EQ(r.ground_rule, perception::GroundRule::kUprightPrior);
  EXPECT_NEAR((*r.ground_plane)(3), 1.24, 0.15);
  EXPECT_GT(-(*r.ground_plane)(1), std::cos(20 * M_PI / 180));  // within 20 degrees of the image's up axis
  EXPECT_GE(r.segments.front().mobility, 0.75);
  perception::PerceptionParams paper;
  paper.ground_upright_prior_deg = 0;
  const auto wall = perception::FramePipeline(paper).processOrganized(f.points, f.width, f.height);
  ASSERT_TRUE(wall.ground_plane);
  EXPECT_LT(std::abs((*wall.ground_plane)(1)), 0.2);  // the paper's largest plane: upright, the end wall
}

// The library's Delaunay triangulation against CGAL's on every segment of two real
// frames: the same triangles on each segment's points projected on its plane, and the
// same roughness and area out of the whole pipeline.
TEST(RealFrames, OwnDelaunayTrianglesAreCgalsOnEverySegment) {
  for (const char* name : {"pcl-kinect/five_people.pcd", "pcl-kinect/milk_cartoon_all_small_clorox.pcd"}) {
    const std::string path = dataFile(name);
    SKIP_WITHOUT(path);
    const app::Frame f = sources::loadPcd(path);
    perception::PerceptionParams own, cgal;
    cgal.triangulator = perception::Triangulator::kCgal;
    const auto a = perception::FramePipeline(own).processOrganized(f.points, f.width, f.height);
    const auto b = perception::FramePipeline(cgal).processOrganized(f.points, f.width, f.height);
    ASSERT_EQ(a.segments.size(), b.segments.size()) << name;
    ASSERT_GT(a.segments.size(), 5u) << name;
    std::size_t triangles = 0, same = 0;
    for (std::size_t s = 0; s < a.segments.size(); ++s) {
      const perception::Segment& seg = a.segments[s];
      EXPECT_NEAR(seg.roughness, b.segments[s].roughness, 1e-9) << name << " segment " << s;
      EXPECT_NEAR(seg.area_m2, b.segments[s].area_m2, 1e-9) << name << " segment " << s;
      const Eigen::Vector3d n = seg.normal.cast<double>(), e1 = n.unitOrthogonal(), e2 = n.cross(e1);
      std::vector<Eigen::Vector2d> projected;
      for (int i : seg.points) {
        const Eigen::Vector3d p = a.points[static_cast<std::size_t>(i)].cast<double>();
        projected.emplace_back(e1.dot(p), e2.dot(p));
      }
      auto own_tris = perception::delaunayTriangles(projected, perception::Triangulator::kOwn);
      auto cgal_tris = perception::delaunayTriangles(projected, perception::Triangulator::kCgal);
      for (auto* tris : {&own_tris, &cgal_tris}) {
        for (auto& t : *tris) std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
        std::sort(tris->begin(), tris->end());
      }
      // Where four or more points lie on one circle (these segments hold many: their
      // points are voxel centroids of a lattice-like grid), either diagonal is Delaunay
      // and the two may pick differently. Then: as many triangles, and brute force finds
      // no point inside any of our circumcircles beyond rounding.
      if (own_tris == cgal_tris) {
        ++same;
      } else {
        EXPECT_EQ(own_tris.size(), cgal_tris.size()) << name << " segment " << s;
        int inside = 0;
        for (const auto& t : own_tris) {
          const Eigen::Vector2d &pa = projected[static_cast<std::size_t>(t[0])],
                                &pb = projected[static_cast<std::size_t>(t[1])],
                                &pc = projected[static_cast<std::size_t>(t[2])];
          for (const auto& d : projected) {
            const Eigen::Vector2d ad = pa - d, bd = pb - d, cd = pc - d;
            const double x1 = bd.x() * cd.y() - cd.x() * bd.y(), x2 = ad.x() * cd.y() - cd.x() * ad.y(),
                         x3 = ad.x() * bd.y() - bd.x() * ad.y();
            const double det = ad.squaredNorm() * x1 - bd.squaredNorm() * x2 + cd.squaredNorm() * x3;
            const double scale = ad.squaredNorm() * std::abs(x1) + bd.squaredNorm() * std::abs(x2) +
                                 cd.squaredNorm() * std::abs(x3);
            if (det > 1e-12 * scale) ++inside;
          }
        }
        EXPECT_EQ(inside, 0) << name << " segment " << s;
      }
      triangles += own_tris.size();
    }
    EXPECT_GT(triangles, a.points.size());  // most points are in segments, ~2 triangles each
    EXPECT_GE(same * 10, a.segments.size() * 9) << name << ": " << same << " of " << a.segments.size();
  }
}

TEST(RealFrames, MilkCartonCarpetIsAbout0_46MetresAwayAndBottlesAreSeparateObstacles) {
  const std::string path = dataFile("pcl-kinect/milk_cartoon_all_small_clorox.pcd");
  SKIP_WITHOUT(path);
  const app::Frame f = sources::loadPcd(path);
  const auto r = perception::FramePipeline().processOrganized(f.points, f.width, f.height);
  ASSERT_TRUE(r.ground_plane);
  EXPECT_NEAR((*r.ground_plane)(3), 0.46, 0.05);
  EXPECT_GE(r.segments.front().mobility, 0.75);
  // Bottles and the carton rise 10-30 cm above the carpet, as separate segments.
  const auto objects = standingObstacles(r, 0.08f, 100);
  ASSERT_GE(objects.size(), 2u);
  for (const auto& o : objects) EXPECT_LT(o.mobility, 0.5);
}

TEST(RealFrames, RedkitchenFloorIsWalkableTableTopFlatAndFrontsUntraversable) {
  const std::string dir = dataFile("7scenes-redkitchen");
  SKIP_WITHOUT(dir);
  const app::SevenScenesDirectory d(dir);
  ASSERT_TRUE(d.gravityDown());
  const Eigen::Vector3d g = *d.gravityDown();
  mapping::MobilityMap map(mapping::MapParams{}, mapping::gravityAlignment(g));
  const perception::FramePipeline pipeline;
  for (int n = 40; n <= 100; n += 3) {  // the frames that show most floor (data README)
    const auto depth = d.readDepth(n);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.matrix() = d.readPose(n);
    T.linear() = mapping::nearestRotation(T.linear());
    const auto r = pipeline.process(depth, d.intrinsics(), (T.linear().transpose() * g).cast<float>());
    map.integrate(r, T, &depth, &d.intrinsics());
  }
  map.finalize();
  // Map frame: z up, world origin at 0, so the floor is at z = -1.47 and the table top
  // at -0.77 (data README). Bands of +-5 cm around them; obstacles in between.
  // Vertical surfaces cross every height, so the table top is judged by the top voxel
  // of each column: a column whose highest surface is in the table band is table top.
  int floor = 0, floor_good = 0, table = 0, table_good = 0, middle = 0, middle_bad = 0;
  const auto& t = map.tree();
  std::map<std::pair<int, int>, std::pair<double, double>> top;  // column -> (z, mobility)
  for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) {
    if (!t.isNodeOccupied(*it) || !it->hasMobility()) continue;
    const double z = it.getZ(), m = it->mobility();
    const auto col = std::make_pair(static_cast<int>(std::floor(it.getX() / 0.02)), static_cast<int>(std::floor(it.getY() / 0.02)));
    auto [entry, fresh] = top.try_emplace(col, z, m);
    if (!fresh && z > entry->second.first) entry->second = {z, m};
    if (std::abs(z + 1.47) < 0.05) {
      ++floor;
      floor_good += m >= 0.75;
    } else if (z > -1.30 && z < -0.90) {
      // Upright surfaces (fronts, legs, chair backs) stack voxels in a column; a level
      // one between the bands (a chair seat) is one or, with noise, two layers thick
      // and may be walkable. Upright: three or more occupied voxels in a vertical run.
      const double res = t.getResolution();
      const auto occupied = [&](double dz) {
        const auto* n = t.search(it.getX(), it.getY(), z + dz);
        return n && t.isNodeOccupied(n);
      };
      const bool up = occupied(res), down = occupied(-res);
      if (!(up && down) && !(up && occupied(2 * res)) && !(down && occupied(-2 * res))) continue;
      ++middle;
      middle_bad += m < 0.5;
    }
  }
  for (const auto& [col, zm] : top) {
    if (std::abs(zm.first + 0.77) >= 0.05) continue;
    ++table;
    table_good += zm.second >= 0.75;
  }
  std::printf("[ info ] floor band %d voxels, %.1f %% >= 0.75; table band %d, %.1f %% >= 0.75; upright between %d, %.1f %% < 0.5\n",
              floor, 100.0 * floor_good / std::max(1, floor), table, 100.0 * table_good / std::max(1, table), middle,
              100.0 * middle_bad / std::max(1, middle));
  ASSERT_GT(floor, 2000);
  EXPECT_GT(static_cast<double>(floor_good) / floor, 0.75);  // "mostly mobility >= 0.75"
  ASSERT_GT(table, 500);                                     // a flat surface 0.7 m above the floor
  EXPECT_GT(static_cast<double>(table_good) / table, 0.75);
  ASSERT_GT(middle, 500);
  EXPECT_GT(static_cast<double>(middle_bad) / middle, 0.95);  // upright: fronts, legs, chair backs
}

// The RealSense frames (a person standing on a large floor, no pose, a different
// camera from the Kinect: fx 393). The floor fills the image's bottom rows in both; the
// reference is a least-squares plane through those pixels' back-projected depth,
// computed here without the pipeline. Above the floor there are only the person and
// upright walls, so nothing higher than 30 cm may be called walkable.
TEST(RealFrames, RealSensePersonStandsOnAWalkableFloorAndIsNotTraversable) {
  for (const char* name : {"depth_image_1.png", "depth_image_2.png"}) {
    SCOPED_TRACE(name);
    const std::string path = dataFile(std::string("realsense-person/") + name);
    SKIP_WITHOUT(path);
    const app::Frame f =
        app::loadSingleFrame(path, -1, dataFile("realsense-person/camera-intrinsics.txt"));
    ASSERT_TRUE(f.depth);
    const perception::PinholeIntrinsics& k = f.intrinsics;
    ASSERT_NEAR(k.fx, 393.02, 0.01);

    // Reference floor: rows 420-479, columns 100-599, within 3 m.
    const PixelPatch floor = patch(f, 100, 600, 420, 480);
    ASSERT_GT(floor.pixels.size(), 20000u);
    const PlaneFit ref = fitPlane(floor.points);

    const auto r = app::perceiveFrame(perception::FramePipeline(), f, std::nullopt);
    ASSERT_TRUE(r.ground_plane);
    const Eigen::Vector3d n = r.ground_plane->head<3>().cast<double>();
    EXPECT_LT(degreesBetween(n, ref.n), 2.0) << "ground normal " << n.transpose() << ", reference "
                                             << ref.n.transpose();
    EXPECT_NEAR((*r.ground_plane)(3), ref.d, 0.02);
    const perception::Segment& ground = r.segments.front();
    ASSERT_TRUE(ground.is_ground);
    EXPECT_GE(ground.mobility, 0.9);
    EXPECT_LT(ground.roughness, 1.05);

    // The reference floor pixels are the ground segment's.
    ASSERT_EQ(r.point_of_pixel.size(), f.depth->depth_m.size());
    const PixelSegments on_floor = segmentsOfPixels(r, floor.pixels);
    ASSERT_GT(on_floor.kept, floor.pixels.size() * 9 / 10);
    const std::size_t on_ground = on_floor.count.count(0) ? on_floor.count.at(0) : 0;
    const std::size_t kept = on_floor.kept;
    EXPECT_GT(static_cast<double>(on_ground) / kept, 0.95);

    // Everything more than 30 cm above the floor (the person, the walls) scores < 0.5.
    std::size_t high = 0, high_walkable = 0;
    for (std::size_t i = 0; i < r.points.size(); ++i) {
      if (heightAbove(*r.ground_plane, r.points[i]) < 0.3f) continue;
      ++high;
      const int s = r.segment_of_point[i];
      high_walkable += s >= 0 && r.segments[static_cast<std::size_t>(s)].mobility >= 0.5;
    }
    ASSERT_GT(high, 5000u);
    EXPECT_LT(static_cast<double>(high_walkable) / high, 0.01) << high_walkable << " of " << high;
    // The wall beside the person: the largest other segment, upright. Off its plane, the
    // person, over 1.4 m tall (its points are among those counted above).
    const perception::Segment* wall = nullptr;
    for (const auto& s : r.segments)
      if (!s.is_ground && (!wall || s.points.size() > wall->points.size())) wall = &s;
    ASSERT_NE(wall, nullptr);
    EXPECT_LT(std::abs(wall->normal.dot(r.ground_plane->head<3>())), 0.1f);
    EXPECT_LT(wall->mobility, 0.5);
    std::size_t person = 0;
    float person_top = 0.f;
    for (std::size_t i = 0; i < r.points.size(); ++i) {
      const float h = heightAbove(*r.ground_plane, r.points[i]);
      if (h < 0.3f || std::abs(wall->normal.dot(r.points[i] - wall->centroid)) < 0.1f) continue;
      ++person;
      person_top = std::max(person_top, h);
    }
    std::printf("[ info ] %s: floor %.3f m below, %zu of %zu reference floor pixels on the ground; %zu of %zu points "
                "above 30 cm walkable; person %zu points, %.2f m tall\n",
                name, (*r.ground_plane)(3), on_ground, kept, high_walkable, high, person, person_top);
    EXPECT_GT(person, 2000u);
    EXPECT_GT(person_top, 1.4f);
  }
}

// PCL's three grabber frames (0.25 s apart): a laptop, its lid seen from behind, and a
// box on a table the camera looks down on from 0.71 m at about 45 degrees. No gravity:
// the table is the largest plane. References fitted here on pixel patches picked from
// the image: the table's bottom rows, the middle of the box's top and of the lid's back.
TEST(RealFrames, GrabberTableIsTheGroundBoxTopIsARaisedFlatAndTheLaptopLidIsNotWalkable) {
  const std::string dir = dataFile("pcl-kinect/grabber_sequences");
  SKIP_WITHOUT(dir);
  std::vector<std::string> frames;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.path().extension() == ".pcd") frames.push_back(e.path().string());
  std::sort(frames.begin(), frames.end());
  ASSERT_EQ(frames.size(), 3u);
  for (const std::string& path : frames) {
    SCOPED_TRACE(path);
    const app::Frame f = sources::loadPcd(path);
    ASSERT_EQ(f.width, 640);
    const PixelPatch table = patch(f, 30, 600, 400, 470), box = patch(f, 400, 450, 210, 260),
                     lid = patch(f, 200, 320, 190, 290);
    ASSERT_GT(table.pixels.size(), 30000u);
    ASSERT_GT(box.pixels.size(), 1500u);
    ASSERT_GT(lid.pixels.size(), 9000u);
    const PlaneFit table_ref = fitPlane(table.points), box_ref = fitPlane(box.points), lid_ref = fitPlane(lid.points);
    // Each patch is one flat surface, or it was picked wrongly.
    ASSERT_LT(table_ref.rms, 0.005);
    ASSERT_LT(box_ref.rms, 0.005);
    ASSERT_LT(lid_ref.rms, 0.005);
    double box_height = 0;
    for (const auto& p : box.points) box_height += table_ref.height(p);
    box_height /= static_cast<double>(box.points.size());
    const double lid_tilt = degreesBetween(lid_ref.n, table_ref.n);

    const auto r = perception::FramePipeline().processOrganized(f.points, f.width, f.height);
    ASSERT_TRUE(r.ground_plane);
    EXPECT_LT(degreesBetween(r.ground_plane->head<3>().cast<double>(), table_ref.n), 2.0);
    EXPECT_NEAR((*r.ground_plane)(3), table_ref.d, 0.02);
    EXPECT_NEAR((*r.ground_plane)(3), 0.71, 0.03);  // the data's README
    const perception::Segment& ground = r.segments.front();
    ASSERT_TRUE(ground.is_ground);
    EXPECT_GE(ground.mobility, 0.9);
    const PixelSegments on_table = segmentsOfPixels(r, table.pixels);
    ASSERT_GT(on_table.kept, table.pixels.size() * 9 / 10);
    EXPECT_EQ(on_table.dominant().first, 0);
    EXPECT_GT(on_table.dominant().second, 0.95);

    // The box's top: its own segment (not the ground), level with the table, as high
    // above it as the reference says, and flat enough to stand on (how to get up there is
    // reach's business).
    const auto [box_seg, box_share] = segmentsOfPixels(r, box.pixels).dominant();
    ASSERT_GT(box_seg, 0);
    EXPECT_GT(box_share, 0.9);
    const perception::Segment& top = r.segments[static_cast<std::size_t>(box_seg)];
    EXPECT_LT(top.slope_deg, 3.0);
    EXPECT_NEAR(heightAbove(*r.ground_plane, top.centroid), box_height, 0.01);
    EXPECT_GE(top.mobility, 0.9);

    // The lid's back: another segment, tilted as the reference is, untraversable.
    const auto [lid_seg, lid_share] = segmentsOfPixels(r, lid.pixels).dominant();
    ASSERT_GT(lid_seg, 0);
    EXPECT_NE(lid_seg, box_seg);
    EXPECT_GT(lid_share, 0.9);
    const perception::Segment& back = r.segments[static_cast<std::size_t>(lid_seg)];
    EXPECT_LT(degreesBetween(back.normal.cast<double>(), lid_ref.n), 3.0);
    EXPECT_NEAR(back.slope_deg, lid_tilt, 3.0);
    EXPECT_LT(back.mobility, 0.1);
    std::printf("[ info ] %s: table %.3f m away (reference %.3f); box top %.3f m above it (reference %.3f), "
                "mobility %.2f; lid %.1f degrees (reference %.1f), mobility %.2f\n",
                std::filesystem::path(path).filename().c_str(), (*r.ground_plane)(3), table_ref.d,
                heightAbove(*r.ground_plane, top.centroid), box_height, top.mobility, back.slope_deg, lid_tilt,
                back.mobility);
  }
}

// A mug on a textured table, seen by a stereo camera (no depth in the image's left 140
// columns; the colour there is a red fill). The table is the ground; the mug stands
// 10 cm above it, and none of it may be called walkable.
TEST(RealFrames, StereoMugTableIsTheGroundAndNothingOnTheMugIsWalkable) {
  const std::string path = dataFile("pcl-kinect/table_scene_mug_stereo_textured.pcd");
  SKIP_WITHOUT(path);
  const app::Frame f = sources::loadPcd(path);
  ASSERT_EQ(f.width, 640);
  const PixelPatch table = patch(f, 160, 600, 400, 470);
  ASSERT_GT(table.pixels.size(), 20000u);
  const PlaneFit ref = fitPlane(table.points);
  ASSERT_LT(ref.rms, 0.005);

  const auto r = perception::FramePipeline().processOrganized(f.points, f.width, f.height);
  ASSERT_TRUE(r.ground_plane);
  EXPECT_LT(degreesBetween(r.ground_plane->head<3>().cast<double>(), ref.n), 2.0);
  EXPECT_NEAR((*r.ground_plane)(3), ref.d, 0.02);
  const perception::Segment& ground = r.segments.front();
  ASSERT_TRUE(ground.is_ground);
  EXPECT_GE(ground.mobility, 0.9);
  EXPECT_LT(ground.roughness, 1.05);
  const PixelSegments on_table = segmentsOfPixels(r, table.pixels);
  EXPECT_EQ(on_table.dominant().first, 0);
  EXPECT_GT(on_table.dominant().second, 0.9);

  // The mug: kept points 2-15 cm above the reference table and nearer than 1.2 m.
  std::size_t mug = 0, mug_walkable = 0;
  float mug_top = 0.f;
  for (std::size_t i = 0; i < r.points.size(); ++i) {
    const double h = ref.height(r.points[i].cast<double>());
    if (h < 0.02 || h > 0.15 || r.points[i].norm() > 1.2f) continue;
    ++mug;
    mug_top = std::max(mug_top, static_cast<float>(h));
    const int s = r.segment_of_point[i];
    mug_walkable += s >= 0 && r.segments[static_cast<std::size_t>(s)].mobility >= 0.5;
  }
  std::printf("[ info ] table %.3f m away (reference %.3f); mug %zu points, %.3f m tall, %zu walkable\n",
              (*r.ground_plane)(3), ref.d, mug, mug_top, mug_walkable);
  EXPECT_GT(mug, 100u);
  EXPECT_GT(mug_top, 0.08f);
  EXPECT_EQ(mug_walkable, 0u);
}

TEST(RealFrames, CorruptAndMissingPcdFilesGiveErrorsNamingTheFile) {
  const auto dir = std::filesystem::temp_directory_path() / "mobmap-pcd-test";
  std::filesystem::create_directories(dir);
  const std::string missing = (dir / "missing.pcd").string();
  try {
    (void)sources::loadPcd(missing);
    FAIL();
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("missing.pcd: no such file"), std::string::npos) << e.what();
  }
  const std::string bad = (dir / "bad.pcd").string();
  std::ofstream(bad) << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 10\nHEIGHT 1\nPOINTS 10\nDATA ascii\n1 2 3\n";
  try {
    (void)sources::loadPcd(bad);
    FAIL();
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("bad.pcd"), std::string::npos) << e.what();
  }
  const std::string noxyz = (dir / "noxyz.pcd").string();
  std::ofstream(noxyz) << "VERSION 0.7\nFIELDS a b\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n1 2\n";
  try {
    (void)sources::loadPcd(noxyz);
    FAIL();
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("no x, y and z"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace mobmap
