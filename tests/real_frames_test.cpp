// The per-frame pipeline on real Kinect frames from ../shared/data (skipped when the
// folder is absent). Asserts geometric facts of the scenes, not segment counts.
#include "frame_source.hpp"

#include "mobmap/perception/pipeline.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace mobmap {
namespace {

std::string dataFile(const std::string& rel) { return std::string(MOBMAP_SHARED_DATA_DIR) + "/" + rel; }

#define SKIP_WITHOUT(path)                                                              \
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data not found: " << (path)

// Height of a point above the ground plane (n towards the camera, n.x + d = 0).
float heightAbove(const Eigen::Vector4f& plane, const Eigen::Vector3f& p) { return plane.head<3>().dot(p) + plane(3); }

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
  const app::LoadedFrame f = app::loadPcd(path);
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

TEST(RealFrames, MilkCartonCarpetIsAbout0_46MetresAwayAndBottlesAreSeparateObstacles) {
  const std::string path = dataFile("pcl-kinect/milk_cartoon_all_small_clorox.pcd");
  SKIP_WITHOUT(path);
  const app::LoadedFrame f = app::loadPcd(path);
  const auto r = perception::FramePipeline().processOrganized(f.points, f.width, f.height);
  ASSERT_TRUE(r.ground_plane);
  EXPECT_NEAR((*r.ground_plane)(3), 0.46, 0.05);
  EXPECT_GE(r.segments.front().mobility, 0.75);
  // Bottles and the carton rise 10-30 cm above the carpet, as separate segments.
  const auto objects = standingObstacles(r, 0.08f, 100);
  ASSERT_GE(objects.size(), 2u);
  for (const auto& o : objects) EXPECT_LT(o.mobility, 0.5);
}

TEST(RealFrames, CorruptAndMissingPcdFilesGiveErrorsNamingTheFile) {
  const auto dir = std::filesystem::temp_directory_path() / "mobmap-pcd-test";
  std::filesystem::create_directories(dir);
  const std::string missing = (dir / "missing.pcd").string();
  try {
    (void)app::loadPcd(missing);
    FAIL();
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("missing.pcd: no such file"), std::string::npos) << e.what();
  }
  const std::string bad = (dir / "bad.pcd").string();
  std::ofstream(bad) << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 10\nHEIGHT 1\nPOINTS 10\nDATA ascii\n1 2 3\n";
  try {
    (void)app::loadPcd(bad);
    FAIL();
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("bad.pcd"), std::string::npos) << e.what();
  }
  const std::string noxyz = (dir / "noxyz.pcd").string();
  std::ofstream(noxyz) << "VERSION 0.7\nFIELDS a b\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n1 2\n";
  try {
    (void)app::loadPcd(noxyz);
    FAIL();
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("no x, y and z"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace mobmap
