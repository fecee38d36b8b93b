// Roughness at foot scale (perception_params foot_window_m, foot_support_m): surfaces
// too small for a foot are scored by the ground around them; surfaces that hold a foot
// keep their own segment's score.
#include "perception_support.hpp"

#include <functional>

namespace mobmap::perception {
namespace {

// A height field z(x, y) over [0, size)^2 sampled every 2 mm, seen from `range` above
// (camera frame, OpenCV axes: the field faces the camera; gravity along +z).
std::vector<Eigen::Vector3f> field(double size, double range, const std::function<double(double, double)>& z) {
  std::vector<Eigen::Vector3f> cloud;
  const int n = static_cast<int>(size / 0.002);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double x = 0.002 * i + 0.001, y = 0.002 * j + 0.001;
      cloud.emplace_back(static_cast<float>(x - size / 2), static_cast<float>(y - size / 2), static_cast<float>(range - z(x, y)));
    }
  }
  return cloud;
}

PerceptionParams footScale(double window_m) {
  PerceptionParams p;
  p.min_range_m = 0.1;
  p.foot_window_m = window_m;
  return p;
}

// Mean slope and roughness of the segments holding the points within `inner` of the
// field's centre (x, y in the camera frame), weighted by point count.
struct Scored {
  double slope = 0, roughness = 0, rough_share = 0;
  std::size_t points = 0;
};
Scored scoredNear(const FrameResult& r, double inner) {
  Scored s;
  std::size_t rough = 0;
  for (std::size_t i = 0; i < r.points.size(); ++i) {
    if (std::abs(r.points[i].x()) > inner || std::abs(r.points[i].y()) > inner) continue;
    const int seg = r.segment_of_point[i];
    if (seg < 0) continue;
    const Segment& g = r.segments[static_cast<std::size_t>(seg)];
    s.slope += g.slope_deg;
    s.roughness += g.roughness;
    rough += g.is_rough;
    ++s.points;
  }
  if (s.points) {
    s.slope /= static_cast<double>(s.points);
    s.roughness /= static_cast<double>(s.points);
    s.rough_share = static_cast<double>(rough) / static_cast<double>(s.points);
  }
  return s;
}

TEST(FootScale, RidgesNarrowerThanAFootAreLevelRoughGround) {
  // 6 cm triangular ridges at a 12 cm pitch: 45-degree faces 8.5 cm wide (no foot fits
  // on one), A/A' = sqrt(2) exactly, level as a whole.
  const auto ridges = [](double x, double) {
    const double f = std::fmod(x, 0.12) / 0.12;
    return 0.06 * (1.0 - 2.0 * std::abs(f - 0.5));
  };
  const std::vector<Eigen::Vector3f> cloud = field(0.72, 1.0, ridges);
  const Eigen::Vector3f gravity(0, 0, 1);
  const FrameResult paper = FramePipeline(footScale(0)).process(cloud, gravity);
  const FrameResult foot = FramePipeline(footScale(0.15)).process(cloud, gravity);
  const Scored a = scoredNear(paper, 0.2), b = scoredNear(foot, 0.2);
  std::printf("[ info ] ridges: per segment slope %.1f r %.3f; at foot scale slope %.1f r %.3f (exact 0, %.3f)\n", a.slope,
              a.roughness, b.slope, b.roughness, std::sqrt(2.0));
  EXPECT_LT(b.slope, 5.0);  // the ground they make up is level
  EXPECT_EQ(b.rough_share, 1.0);
  // The 30-neighbour normals round each crease off over ~3 cm, so A/A' reads low; well
  // above a flat floor's 1.0, measured 1.20 here.
  EXPECT_GT(b.roughness, 1.15);
  EXPECT_LT(b.roughness, std::sqrt(2.0) + 0.05);
}

TEST(FootScale, ATopThatHoldsAFootKeepsItsScoreAndASmallerOneDoesNot) {
  // A floor with two raised flat tops, 6 cm high: one 30 cm square, one 9.5 cm square (under the 10 cm a foot needs).
  const auto tops = [](double x, double y) {
    const bool big = x > 0.1 && x < 0.4 && y > 0.1 && y < 0.4;
    const bool small = x > 0.5 && x < 0.595 && y > 0.5 && y < 0.595;
    return big || small ? 0.06 : 0.0;
  };
  const std::vector<Eigen::Vector3f> cloud = field(0.8, 1.0, tops);
  const FrameResult r = FramePipeline(footScale(0.15)).process(cloud, Eigen::Vector3f(0, 0, 1));
  std::size_t big = 0, big_kept = 0, small = 0, small_moved = 0, floor = 0, floor_kept = 0;
  for (std::size_t i = 0; i < r.points.size(); ++i) {
    const int seg = r.segment_of_point[i];
    if (seg < 0) continue;
    const Segment& g = r.segments[static_cast<std::size_t>(seg)];
    const double x = r.points[i].x() + 0.4, y = r.points[i].y() + 0.4, z = 1.0 - r.points[i].z();
    if (z > 0.055 && x > 0.12 && x < 0.38 && y > 0.12 && y < 0.38) {
      ++big;
      big_kept += !g.is_rough && g.slope_deg < 2 && g.roughness < 1.05;
    } else if (z > 0.055 && x > 0.5 && x < 0.595 && y > 0.5 && y < 0.595) {
      ++small;
      small_moved += g.is_rough;
    } else if (z < 0.005 && (x < 0.05 || y < 0.05 || x > 0.75 || y > 0.75)) {
      ++floor;  // the floor away from both tops
      floor_kept += g.is_ground && g.roughness < 1.05;
    }
  }
  ASSERT_GT(big, 500u);
  ASSERT_GT(small, 30u);
  ASSERT_GT(floor, 1000u);
  EXPECT_EQ(big_kept, big);
  EXPECT_EQ(small_moved, small);
  EXPECT_EQ(floor_kept, floor);
}

TEST(FootScale, AFloorCutByTheEdgeOfTheViewStillHoldsAFoot) {
  // A level floor seen through a narrow view: a strip 8 cm wide between the image's
  // edges. Beyond the edges the floor is unknown, not absent: it stays one flat segment.
  std::vector<Eigen::Vector3f> cloud;
  for (int i = 0; i < 400; ++i) {
    for (int j = 0; j < 40; ++j) {
      cloud.emplace_back(-0.4f + 0.002f * static_cast<float>(i), -0.04f + 0.002f * static_cast<float>(j), 1.0f);
    }
  }
  const FrameResult r = FramePipeline(footScale(0.15)).process(cloud, Eigen::Vector3f(0, 0, 1));
  std::size_t rough = 0, scored = 0;
  for (std::size_t i = 0; i < r.points.size(); ++i) {
    const int seg = r.segment_of_point[i];
    if (seg < 0) continue;
    ++scored;
    rough += r.segments[static_cast<std::size_t>(seg)].is_rough;
  }
  EXPECT_GT(scored, 0.9 * r.points.size());
  EXPECT_EQ(rough, 0u);
}

TEST(FootScale, TheWindowIsValidated) {
  PerceptionParams p;
  p.foot_window_m = -0.1;
  EXPECT_THROW(validate(p), std::invalid_argument);
  p.foot_window_m = 0.15;
  p.foot_support_m = std::nan("");
  EXPECT_THROW(validate(p), std::invalid_argument);
  // A window so small that its grid's size would overflow is refused by name.
  p.foot_support_m = 0.10;
  for (const double tiny : {1e-9, 0.009}) {
    p.foot_window_m = tiny;
    try {
      validate(p);
      FAIL() << tiny;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("foot_window_m"), std::string::npos) << e.what();
    }
  }
}

// The smallest window and the largest support over points as far apart as the range
// allows, and a segment 1 mm wide and hundreds of metres long: every grid stays within
// its bounds (an overflow shows under the sanitizers, a huge grid as a failed
// allocation), and every point is scored.
TEST(FootScale, TheSmallestWindowOverTheWidestViewStaysWithinItsGrids) {
  PerceptionParams p = footScale(0.01);
  p.max_range_m = 1000;
  p.foot_support_m = 2.0;
  validate(p);
  std::vector<Eigen::Vector3f> cloud;
  // Two rough patches 1.4 km apart (one to each side, both within range) ...
  for (const float side : {-700.0f, 700.0f}) {
    for (int i = 0; i < 40; ++i) {
      for (int j = 0; j < 40; ++j) {
        const float x = side + 0.01f * static_cast<float>(i), y = 0.01f * static_cast<float>(j);
        cloud.emplace_back(x, y, 500.0f + 0.004f * static_cast<float>((i * 7 + j * 13) % 5));
      }
    }
  }
  // ... and a thin strip 300 m long.
  for (int i = 0; i < 30000; ++i) cloud.emplace_back(-150.0f + 0.01f * static_cast<float>(i), 3.0f, 400.0f);
  FramePipeline pipe(p);
  const FrameResult r = pipe.process(cloud, Eigen::Vector3f(0, 0, 1));
  for (const Segment& g : r.segments) {
    EXPECT_TRUE(std::isfinite(g.slope_deg));
    EXPECT_TRUE(std::isfinite(g.roughness));
  }
}

}  // namespace
}  // namespace mobmap::perception
