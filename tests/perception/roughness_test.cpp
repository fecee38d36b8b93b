// Paper step 7: Delaunay triangulation and roughness A / A' against analytic surfaces.
#include "perception_support.hpp"

namespace mobmap::perception {
namespace {

// The insertion order follows the input order within each round (and CGAL, the
// reference, takes row order and any other order by different routes). All must give
// the same triangulation (generic points: no four on a circle) and so the same areas.
TEST(Roughness, RowOrderAndShuffledOrderGiveTheSameTriangulation) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> jitter(-0.003f, 0.003f);
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 60; ++i) {
    for (int j = 0; j < 45; ++j) {
      const float x = 0.01f * i + jitter(rng), y = 0.01f * j + jitter(rng);
      pts.emplace_back(x, y, 0.02f * std::sin(40.f * x) * std::cos(30.f * y) + jitter(rng));
    }
  }
  std::vector<int> rows(pts.size());
  for (std::size_t i = 0; i < rows.size(); ++i) rows[i] = static_cast<int>(i);
  std::vector<int> shuffled = rows;
  std::shuffle(shuffled.begin(), shuffled.end(), rng);
  const Eigen::Vector4f plane(0, 0, 1, 0);
  const auto in_rows = delaunayRoughness(pts, rows, plane, 0.05);
  EXPECT_GT(in_rows.first, 1.05);  // a bumpy surface: the test would notice a lost triangle
  for (const Triangulator who : {Triangulator::kOwn, Triangulator::kCgal}) {
    for (const auto* order : {&rows, &shuffled}) {
      const auto r = delaunayRoughness(pts, *order, plane, 0.05, who);
      EXPECT_NEAR(r.first, in_rows.first, 1e-9);
      EXPECT_NEAR(r.second, in_rows.second, 1e-9);
    }
  }
}

// --- The library's Delaunay triangulation against CGAL and a brute-force check ------

using Triangle = std::array<int, 3>;

// Each triangle rotated to start at its smallest index, the list sorted: two
// triangulations of the same points are equal iff their canonical lists are.
std::vector<Triangle> canonical(std::vector<Triangle> tris) {
  for (auto& t : tris) std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
  std::sort(tris.begin(), tris.end());
  return tris;
}

double twiceSignedArea(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
}

// Brute force, for points whose coordinates are small multiples of a power of two (so
// every product below is exact): every triangle counter-clockwise and not flat, and no
// point strictly inside any triangle's circumcircle (the Delaunay property).
void expectEmptyCircles(const std::vector<Eigen::Vector2d>& pts, const std::vector<Triangle>& tris) {
  int bad = 0;
  for (const auto& t : tris) {
    const Eigen::Vector2d &a = pts[static_cast<std::size_t>(t[0])], &b = pts[static_cast<std::size_t>(t[1])],
                          &c = pts[static_cast<std::size_t>(t[2])];
    if (!(twiceSignedArea(a, b, c) > 0)) ++bad;
    for (const auto& d : pts) {
      const Eigen::Vector2d ad = a - d, bd = b - d, cd = c - d;
      const double det = ad.squaredNorm() * (bd.x() * cd.y() - cd.x() * bd.y()) -
                         bd.squaredNorm() * (ad.x() * cd.y() - cd.x() * ad.y()) +
                         cd.squaredNorm() * (ad.x() * bd.y() - bd.x() * ad.y());
      if (det > 0) ++bad;
    }
  }
  EXPECT_EQ(bad, 0);
}

TEST(Delaunay, OwnTrianglesAreCgalsForGenericPointsInAnyOrder) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  // Scattered points, and a jittered grid (the kind of points segments hold) in row order.
  std::vector<Eigen::Vector2d> scattered(3000), grid;
  for (auto& p : scattered) p = Eigen::Vector2d(u(rng), u(rng));
  for (int r = 0; r < 50; ++r) {
    for (int c = 0; c < 70; ++c) grid.emplace_back(0.01 * (c + jitter(rng)), 0.01 * (r + jitter(rng)));
  }
  for (auto* pts : {&scattered, &grid}) {
    const auto reference = canonical(delaunayTriangles(*pts, Triangulator::kCgal));
    const auto own = canonical(delaunayTriangles(*pts, Triangulator::kOwn));
    ASSERT_GT(reference.size(), pts->size());  // ~2n triangles
    EXPECT_EQ(own, reference);
    // Shuffled: the same triangles under the permutation.
    std::vector<int> perm(pts->size());
    for (std::size_t i = 0; i < perm.size(); ++i) perm[i] = static_cast<int>(i);
    std::shuffle(perm.begin(), perm.end(), rng);
    std::vector<Eigen::Vector2d> shuffled(pts->size());
    for (std::size_t i = 0; i < perm.size(); ++i) shuffled[i] = (*pts)[static_cast<std::size_t>(perm[i])];
    auto back = delaunayTriangles(shuffled, Triangulator::kOwn);
    for (auto& t : back) {
      for (int& v : t) v = perm[static_cast<std::size_t>(v)];
    }
    EXPECT_EQ(canonical(back), reference);
  }
}

TEST(Delaunay, OwnTrianglesAreDelaunayWhereFourPointsShareACircle) {
  // An exact lattice: every unit square's corners lie on one circle, so either diagonal
  // is Delaunay and CGAL's choice is not the only right one. Brute force instead: empty
  // circumcircles, and the triangles tile the rectangle exactly (areas sum to it).
  std::vector<Eigen::Vector2d> lattice;
  for (int r = 0; r <= 30; ++r) {
    for (int c = 0; c <= 40; ++c) lattice.emplace_back(0.25 * c, 0.25 * r);
  }
  std::mt19937 rng(8);
  std::shuffle(lattice.begin(), lattice.end(), rng);
  // Points on one circle (angles whose sines and cosines are exact) and the centre.
  std::vector<Eigen::Vector2d> ring = {{1, 0}, {0, 1}, {-1, 0}, {0, -1}, {0.6, 0.8}, {-0.8, 0.6}, {-0.6, -0.8}, {0.8, -0.6}, {0, 0}};
  for (const auto* pts : {&lattice, &ring}) {
    const auto own = delaunayTriangles(*pts, Triangulator::kOwn);
    expectEmptyCircles(*pts, own);
    double area = 0;
    for (const auto& t : own) {
      area += 0.5 * twiceSignedArea((*pts)[static_cast<std::size_t>(t[0])], (*pts)[static_cast<std::size_t>(t[1])],
                                    (*pts)[static_cast<std::size_t>(t[2])]);
    }
    if (pts == &lattice) {
      EXPECT_EQ(own.size(), 2u * 30 * 40);
      EXPECT_DOUBLE_EQ(area, 10.0 * 7.5);
    } else {
      EXPECT_EQ(own.size(), 8u);  // a fan around the centre
      double polygon = 0;
      for (const auto& t : delaunayTriangles(*pts, Triangulator::kCgal)) {
        polygon += 0.5 * twiceSignedArea((*pts)[static_cast<std::size_t>(t[0])], (*pts)[static_cast<std::size_t>(t[1])],
                                         (*pts)[static_cast<std::size_t>(t[2])]);
      }
      EXPECT_NEAR(area, polygon, 1e-12);
    }
  }
}

TEST(Delaunay, DuplicatesCollinearAndNonFinitePointsAreHandled) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Eigen::Vector2d> pts(500);
  for (auto& p : pts) p = Eigen::Vector2d(u(rng), u(rng));
  const auto reference = canonical(delaunayTriangles(pts, Triangulator::kCgal));
  // Each point twice, and two points with NaN / infinity appended: the same triangles,
  // each over one copy of its points (whichever was inserted first; the other is
  // skipped, as in CGAL), none over the non-finite points.
  std::vector<Eigen::Vector2d> doubled = pts;
  doubled.insert(doubled.end(), pts.begin(), pts.end());
  doubled.emplace_back(std::nan(""), 0.5);
  doubled.emplace_back(0.5, std::numeric_limits<double>::infinity());
  auto own = delaunayTriangles(doubled, Triangulator::kOwn);
  for (auto& t : own) {
    for (int& v : t) {
      EXPECT_LT(v, 1000);
      v %= 500;
    }
  }
  EXPECT_EQ(canonical(own), reference);
  // Collinear points (a line, and a line with a second copy): no triangle.
  std::vector<Eigen::Vector2d> line;
  for (int i = 0; i < 20; ++i) line.emplace_back(0.5 * i, 0.25 * i);
  line.insert(line.end(), line.begin(), line.end());
  EXPECT_TRUE(delaunayTriangles(line, Triangulator::kOwn).empty());
  // Collinear points first, then one off the line: a fan of 19 triangles.
  line.resize(20);
  line.emplace_back(0.0, 3.0);
  const auto fan = delaunayTriangles(line, Triangulator::kOwn);
  EXPECT_EQ(fan.size(), 19u);
  EXPECT_EQ(canonical(fan), canonical(delaunayTriangles(line, Triangulator::kCgal)));
  // Coordinates near the double range (products overflow; the exact predicates decide):
  // a square's corners and its centre, a fan of four.
  const double big = 1e308;
  const std::vector<Eigen::Vector2d> huge = {{-big, 0}, {big, 0}, {0, big}, {0, -big}, {0, 0}};
  EXPECT_EQ(canonical(delaunayTriangles(huge, Triangulator::kOwn)),
            canonical({{0, 3, 4}, {1, 2, 4}, {0, 4, 2}, {1, 4, 3}}));
  // Fewer than three points, and none.
  EXPECT_TRUE(delaunayTriangles({{0, 0}, {1, 1}}, Triangulator::kOwn).empty());
  EXPECT_TRUE(delaunayTriangles({}, Triangulator::kOwn).empty());
}

TEST(Roughness, FlatAndCorrugatedSurfacesMatchTheirExactRatio) {
  // A zigzag z = a * tri(x / P) sampled at its kinks: Delaunay reproduces it exactly,
  // so A/A' = sqrt(1 + (2a / (P/2))^2 ... per facet slope s = a / (P / 2).
  std::vector<Eigen::Vector3f> flat, zig;
  const float step = 0.01f, a = 0.01f, period = 0.04f;
  for (int i = 0; i <= 40; ++i) {
    for (int j = 0; j <= 40; ++j) {
      const float x = i * step, y = j * step;
      flat.emplace_back(x, y, 0.3f * x + 1.f);  // tilted plane
      const float ph = std::fmod(x, period) / period;
      zig.emplace_back(x, y, a * (1 - std::abs(2 * ph - 1)) * 2);
    }
  }
  std::vector<int> idx(flat.size());
  for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = static_cast<int>(i);
  const Eigen::Vector4f tilted = leastSquaresPlane(flat, idx);
  EXPECT_NEAR(delaunayRoughness(flat, idx, tilted, 0.05).first, 1.0, 1e-6);
  const double s = 2 * a / (period / 2);  // facet slope
  const auto [r, area] = delaunayRoughness(zig, idx, Eigen::Vector4f(0, 0, 1, 0), 0.05);
  EXPECT_NEAR(r, std::sqrt(1 + s * s), 1e-4);
  EXPECT_NEAR(area, 0.4 * 0.4 * std::sqrt(1 + s * s), 1e-4);
  // Collinear points: no triangle, r = 1 and no area, not NaN.
  std::vector<Eigen::Vector3f> line = {{0, 0, 0}, {0.01f, 0, 0}, {0.02f, 0, 0}, {0.03f, 0, 0}};
  const auto degenerate = delaunayRoughness(line, {0, 1, 2, 3}, Eigen::Vector4f(0, 0, 1, 0), 0.05);
  EXPECT_EQ(degenerate.first, 1.0);
  EXPECT_EQ(degenerate.second, 0.0);
}

}  // namespace
}  // namespace mobmap::perception
