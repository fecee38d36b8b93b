// 2.5D layers per level against the analytic voxel scene: the levels a robot of a given
// height sees, each cell against a column search in the octree, steps at every riser
// and none on the floor, a floor under a platform as a level of its own, bad input.
#include "mobmap/mapping/layers.hpp"
#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/mapping/reachability.hpp"
#include "voxel_scene.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>

namespace mobmap::mapping {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The highest run of occupied voxels in the column of (x, y) with its bottom face below
// `max_bottom` and its top face at or above `min_top`, found voxel by voxel in the tree:
// {top face, top voxel's mobility (or the highest one's below it in the run)}; NaN if none.
std::pair<double, double> columnSearch(const MobilityOcTree& t, double x, double y, double min_top, double max_bottom) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const auto occupied = [&](int k) {
    const auto* n = t.search(x, y, (k + 0.5) * kRes);
    return n != nullptr && t.isNodeOccupied(n) ? n : nullptr;
  };
  for (int k = 200; k >= -5; --k) {
    if (!occupied(k)) continue;
    int bottom = k;
    while (occupied(bottom - 1)) --bottom;
    const double top_face = (k + 1) * kRes, bottom_face = bottom * kRes;
    if (top_face < min_top) return {nan, nan};
    if (bottom_face < max_bottom) {
      double mobility = nan;
      for (int m = k; m >= bottom; --m) {
        if (occupied(m)->hasMobility()) {
          mobility = occupied(m)->mobility();
          break;
        }
      }
      return {top_face, mobility};
    }
    k = bottom;  // below this run
  }
  return {nan, nan};
}

// The layer cell holding (x, y).
std::size_t cellAt(const LevelLayers& l, double x, double y) {
  const int col = static_cast<int>(std::floor((x - l.x_min) / l.cell_m));
  const int row = l.rows - 1 - static_cast<int>(std::floor((y - l.y_min) / l.cell_m));
  EXPECT_TRUE(col >= 0 && col < l.cols && row >= 0 && row < l.rows) << x << ", " << y;
  return l.index(row, col);
}

TEST(Layers, ARobotOneMetreTallSeesOneLevelWithTheTableAsElevation) {
  const Scene s;
  const SurfaceColumns columns(s.tree);
  const auto levels = layerLevels(columns, 1.0);
  ASSERT_EQ(levels.size(), 1u);
  EXPECT_NEAR(levels[0].z_m, 0.02, 1e-4);
  EXPECT_EQ(levels[0].min_top_m, -kInf);
  const LevelLayers l = levelLayers(columns, levels[0], kRes);
  // Every cell is the column search's answer.
  int known = 0;
  for (int row = 0; row < l.rows; ++row) {
    for (int col = 0; col < l.cols; ++col) {
      const std::size_t at = l.index(row, col);
      const auto [top, mobility] = columnSearch(s.tree, l.cellX(col), l.cellY(row), levels[0].min_top_m, levels[0].max_bottom_m);
      SCOPED_TRACE("cell at " + std::to_string(l.cellX(col)) + ", " + std::to_string(l.cellY(row)));
      ASSERT_EQ(std::isnan(l.elevation[at]), std::isnan(top));
      if (std::isnan(top)) {
        EXPECT_EQ(l.known[at], 0.0f);
        continue;
      }
      ++known;
      EXPECT_FLOAT_EQ(l.elevation[at], static_cast<float>(top));
      EXPECT_FLOAT_EQ(l.mobility[at], static_cast<float>(mobility));
      EXPECT_EQ(l.known[at], 1.0f);
      EXPECT_NEAR(l.elevation_variance[at], kRes * kRes / 12, 1e-9);
    }
  }
  EXPECT_GT(known, 15000);
  // The table top is elevation over the floor; treads and the ledge rise from it.
  EXPECT_FLOAT_EQ(l.elevation[cellAt(l, 0.5, 1.5)], 0.72f);
  EXPECT_FLOAT_EQ(l.elevation[cellAt(l, 1.1, 0.3)], 0.12f);
  EXPECT_FLOAT_EQ(l.elevation[cellAt(l, 1.7, 0.3)], 0.32f);
  EXPECT_FLOAT_EQ(l.elevation[cellAt(l, 2.5, 0.3)], 0.32f);
  // The hole is unknown; the wall reads its top and a mobility of 0.
  EXPECT_TRUE(std::isnan(l.elevation[cellAt(l, 0.41, 1.0)]));
  EXPECT_FLOAT_EQ(l.elevation[cellAt(l, 2.21, 1.5)], 1.0f);
  EXPECT_FLOAT_EQ(l.mobility[cellAt(l, 2.21, 1.5)], 0.0f);
}

TEST(Layers, StepsMarkEveryRiserAndEdgeAndNotTheFloorOrTreads) {
  const Scene s;
  const SurfaceColumns columns(s.tree);
  const LevelLayers l = levelLayers(columns, layerLevels(columns, 1.0)[0], kRes);
  // Along y = 0.3 across the stairs: 0.1 m at each riser's two cells, 0 elsewhere on the floor and treads.
  for (int i = 30; i < 110; ++i) {
    const double x = (i + 0.5) * kRes;
    const std::size_t at = cellAt(l, x, 0.31);
    const bool riser = i == 49 || i == 50 || i == 64 || i == 65 || i == 79 || i == 80 || i == 99 || i == 100;
    SCOPED_TRACE("x = " + std::to_string(x));
    if (riser) {
      EXPECT_GE(l.step[at], 0.1f - 1e-6f);
    } else {
      EXPECT_EQ(l.step[at], 0.0f);
      EXPECT_NEAR(l.slope_deg[at], 0.0, 1e-3);
    }
  }
  // The table's edge: 0.70 m.
  EXPECT_NEAR(l.step[cellAt(l, 0.21, 1.5)], 0.70, 1e-6);
  EXPECT_NEAR(l.step[cellAt(l, 0.19, 1.5)], 0.70, 1e-6);
  // Open floor.
  EXPECT_EQ(l.step[cellAt(l, 1.5, 1.2)], 0.0f);
}

TEST(Layers, AFloorUnderAPlatformTheRobotFitsUnderIsALevelOfItsOwn) {
  Scene s;
  // A platform two voxels thick, top 1.22 m, over the floor at x in [1.0, 2.0), y in [0.8, 1.6).
  for (int i = 50; i < 100; ++i)
    for (int j = 40; j < 80; ++j)
      for (int k = 59; k <= 60; ++k) put(s.tree, i, j, k, k == 60 ? 1.0 : 0.0);
  const SurfaceColumns columns(s.tree);
  const auto levels = layerLevels(columns, 1.0);
  ASSERT_EQ(levels.size(), 2u);
  EXPECT_NEAR(levels[0].z_m, 0.02, 1e-4);
  EXPECT_NEAR(levels[1].z_m, 1.22, 1e-4);
  EXPECT_NEAR(levels[1].min_top_m, levels[0].max_bottom_m, 1e-12);
  const LevelLayers floor = levelLayers(columns, levels[0], kRes), platform = levelLayers(columns, levels[1], kRes);
  // Under the platform: the floor on the floor's level, the platform on its own.
  EXPECT_FLOAT_EQ(floor.elevation[cellAt(floor, 1.5, 1.2)], 0.02f);
  EXPECT_FLOAT_EQ(platform.elevation[cellAt(platform, 1.5, 1.2)], 1.22f);
  // The platform's level spans the platform alone (the room's 1 m wall tops lie in the floor's band).
  EXPECT_NEAR(platform.x_min, 1.0, 1e-9);
  EXPECT_NEAR(platform.y_min, 0.8, 1e-9);
  EXPECT_EQ(platform.cols, 50);
  EXPECT_EQ(platform.rows, 40);
  // Each level is a column search with its band.
  for (const auto* l : {&floor, &platform}) {
    for (int row = 0; row < l->rows; row += 3) {
      for (int col = 0; col < l->cols; col += 3) {
        const auto [top, mobility] = columnSearch(s.tree, l->cellX(col), l->cellY(row), l->level.min_top_m, l->level.max_bottom_m);
        const float e = l->elevation[l->index(row, col)];
        ASSERT_EQ(std::isnan(e), std::isnan(top)) << l->cellX(col) << ", " << l->cellY(row);
        if (!std::isnan(top)) {
          EXPECT_FLOAT_EQ(e, static_cast<float>(top));
        }
      }
    }
  }
  // A robot 1.5 m tall does not fit under it: one level, the platform as elevation.
  const auto tall = layerLevels(columns, 1.5);
  ASSERT_EQ(tall.size(), 1u);
  const LevelLayers one = levelLayers(columns, tall[0], kRes);
  EXPECT_FLOAT_EQ(one.elevation[cellAt(one, 1.5, 1.2)], 1.22f);
}

TEST(Layers, CoarseCellsTakeTheHighestSurfaceAndCountWhatIsKnown) {
  const Scene s;
  const SurfaceColumns columns(s.tree);
  const LayerLevel level = layerLevels(columns, 1.0)[0];
  const LevelLayers fine = levelLayers(columns, level, kRes), coarse = levelLayers(columns, level, 0.1);
  EXPECT_NEAR(coarse.x_min, fine.x_min, 1e-9);
  // A 10 cm cell holds 5 x 5 columns: the hole's two columns leave 60 % of its cell known.
  EXPECT_FLOAT_EQ(coarse.known[cellAt(coarse, 0.45, 1.05)], 0.6f);
  EXPECT_FLOAT_EQ(coarse.elevation[cellAt(coarse, 0.45, 1.05)], 0.02f);
  // Every coarse cell's elevation is the highest of its fine cells; its variance their spread.
  for (int row = 0; row < coarse.rows; ++row) {
    for (int col = 0; col < coarse.cols; ++col) {
      float highest = std::numeric_limits<float>::quiet_NaN();
      double sum = 0, sum2 = 0;
      int n = 0;
      for (int a = 0; a < 5; ++a)
        for (int b = 0; b < 5; ++b) {
          const double x = coarse.cellX(col) + (a - 2) * kRes, y = coarse.cellY(row) + (b - 2) * kRes;
          if (x < fine.x_min || y < fine.y_min || x > fine.x_min + fine.cols * kRes || y > fine.y_min + fine.rows * kRes) continue;
          const float e = fine.elevation[cellAt(fine, x, y)];
          if (std::isnan(e)) continue;
          if (std::isnan(highest) || e > highest) highest = e;
          sum += e, sum2 += static_cast<double>(e) * e, ++n;
        }
      const std::size_t at = coarse.index(row, col);
      ASSERT_EQ(std::isnan(coarse.elevation[at]), n == 0);
      if (n == 0) continue;
      EXPECT_FLOAT_EQ(coarse.elevation[at], highest);
      EXPECT_NEAR(coarse.elevation_variance[at], sum2 / n - (sum / n) * (sum / n) + kRes * kRes / 12, 1e-6);
    }
  }
}

TEST(Layers, AWindowAroundARobotHoldsTheSameCellsAsTheWholeMap) {
  const Scene s;
  const SurfaceColumns columns(s.tree);
  const LayerLevel level = layerLevels(columns, 1.0)[0];
  for (const double cell : {kRes, 0.1}) {
    const LevelLayers whole = levelLayers(columns, level, cell);
    // A 1.2 x 0.8 m window on the whole map's grid, reaching 0.4 m past its west edge.
    LayerWindow w;
    w.x_min = whole.x_min - 0.4;
    w.y_min = whole.y_min + 0.5;
    w.cols = static_cast<int>(std::lround(1.2 / cell));
    w.rows = static_cast<int>(std::lround(0.8 / cell));
    const LevelLayers part = levelLayers(columns, level, cell, w);
    ASSERT_EQ(part.cols, w.cols);
    ASSERT_EQ(part.rows, w.rows);
    int compared = 0;
    for (int row = 0; row < part.rows; ++row) {
      for (int col = 0; col < part.cols; ++col) {
        const double x = part.cellX(col), y = part.cellY(row);
        const std::size_t at = part.index(row, col);
        if (x < whole.x_min) {  // beyond the map: unknown
          EXPECT_TRUE(std::isnan(part.elevation[at]));
          EXPECT_EQ(part.known[at], 0.0f);
          continue;
        }
        const std::size_t w_at = cellAt(whole, x, y);
        for (const std::string& name : layerNames()) {
          const float a = layerByName(part, name)[at], b = layerByName(whole, name)[w_at];
          // Step and slope look at neighbours: the window's edge cells see fewer.
          if ((name == "step" || name == "slope_deg") && (row == 0 || col == 0 || row == part.rows - 1 || col == part.cols - 1)) continue;
          if (std::isnan(b)) {
            EXPECT_TRUE(std::isnan(a)) << name << " at " << x << ", " << y;
          } else {
            EXPECT_NEAR(a, b, 1e-5) << name << " at " << x << ", " << y;
          }
        }
        ++compared;
      }
    }
    EXPECT_GT(compared, part.cols * part.rows / 2);
  }
  LayerWindow bad;
  bad.x_min = std::nan("");
  bad.cols = bad.rows = 10;
  EXPECT_THROW((void)levelLayers(columns, level, kRes, bad), std::invalid_argument);
}

TEST(Layers, TraversableIsFreeWhereASoleStandsAndOccupiedWhereNot) {
  const Scene s;
  auto columns = std::make_shared<const SurfaceColumns>(s.tree);
  const Reachability reach = computeReachability(columns, Eigen::Vector3d(1.5, 1.2, 0.1), ReachParams{});
  const LevelLayers l = levelLayers(*columns, layerLevels(*columns, 1.0)[0], kRes, &reach);
  ASSERT_EQ(l.traversable.size(), l.elevation.size());
  for (int row = 0; row < l.rows; ++row) {
    for (int col = 0; col < l.cols; ++col) {
      const std::size_t at = l.index(row, col);
      const Place* p = reach.placeBelow(Eigen::Vector3d(l.cellX(col), l.cellY(row), l.elevation[at]), 0.01);
      if (std::isnan(l.elevation[at])) {
        EXPECT_EQ(l.traversable[at], Traversable::kUnknown);
        continue;
      }
      ASSERT_NE(p, nullptr);
      const bool free = p->standable && l.step[at] <= reach.params().robot.max_step_m;
      EXPECT_EQ(l.traversable[at] == Traversable::kFree, free) << l.cellX(col) << ", " << l.cellY(row);
    }
  }
  EXPECT_EQ(l.traversable[cellAt(l, 1.5, 1.2)], Traversable::kFree);       // open floor
  EXPECT_EQ(l.traversable[cellAt(l, 2.21, 1.5)], Traversable::kOccupied);  // the wall
  EXPECT_EQ(l.traversable[cellAt(l, 0.41, 1.0)], Traversable::kUnknown);   // the hole
  // The table top carries soles, but its edge is 0.7 m high: an island no step reaches.
  EXPECT_EQ(l.traversable[cellAt(l, 0.5, 1.5)], Traversable::kFree);
  EXPECT_EQ(l.traversable[cellAt(l, 0.21, 1.5)], Traversable::kOccupied);
  EXPECT_EQ(l.traversable[cellAt(l, 0.19, 1.5)], Traversable::kOccupied);
}

TEST(Layers, BadSettingsAreRefusedWithAReason) {
  const Scene s;
  const SurfaceColumns columns(s.tree);
  const LayerLevel level = layerLevels(columns, 1.0)[0];
  for (double cell : {0.01, 0.0, -1.0, 1e9, std::nan("")}) {
    EXPECT_THROW((void)levelLayers(columns, level, cell), std::invalid_argument) << cell;
  }
  for (double clearance : {0.0, -1.0, std::nan(""), kInf}) {
    EXPECT_THROW((void)layerLevels(columns, clearance), std::invalid_argument) << clearance;
  }
  // A map 100 m long at the resolution: more cells than one layer may hold.
  MobilityOcTree wide(kRes);
  put(wide, 0, 0, 0, 1.0);
  put(wide, 5000, 5000, 0, 1.0);
  const SurfaceColumns far(wide);
  LayerLevel all;
  all.min_top_m = -kInf;
  all.max_bottom_m = kInf;
  EXPECT_THROW((void)levelLayers(far, all, kRes), std::length_error);
  EXPECT_NO_THROW((void)levelLayers(far, all, 1.0));
}

}  // namespace
}  // namespace mobmap::mapping
