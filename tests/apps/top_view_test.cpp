// The top view behind `export --png`: one cell per column, cuts, large maps.
#include "io_support.hpp"

#include <random>

namespace mobmap::app {
namespace {

// The top view's grid against the voxels it was drawn from: every occupied column gets
// a cell of its own and shows its highest voxel, whatever the camera path adds.
TEST(TopView, EveryColumnHasItsOwnCellWhereverTheCameraIs) {
  const double res = 0.02;
  mapping::MobilityOcTree tree(res);
  const auto put = [&](double x, double y, double z, double mobility) {
    mapping::MobilityOcTreeNode* n = tree.updateNode(octomap::point3d(x, y, z), true);
    if (mobility >= 0) n->fuse(mobility, 0.01, 100.0);
  };
  // A floor of 12 x 8 columns (voxel centres at odd multiples of 1 cm), a box top on
  // 3 of them 30 cm higher, and one floor voxel never scored.
  for (int i = 0; i < 12; ++i) {
    for (int j = 0; j < 8; ++j) put((i + 0.5) * res, (j + 0.5) * res, -0.01, i == 11 && j == 7 ? -1.0 : 1.0);
  }
  for (int i = 2; i < 5; ++i) put((i + 0.5) * res, 0.5 * res, 0.29, 0.0);
  // A region far from the floor where 2 x 2 x 2 equal voxels are pruned into one leaf.
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j)
      for (int k = 0; k < 2; ++k) put(0.8 + (i + 0.5) * res, 0.8 + (j + 0.5) * res, (k + 0.5) * res, 0.5);
  tree.prune();
  // Camera positions on a column edge (the origin: the case that drew empty lines),
  // inside a column, and far outside the surfaces.
  for (const Eigen::Vector2d& camera : {Eigen::Vector2d(0, 0), Eigen::Vector2d(0.013, 0.007), Eigen::Vector2d(-0.517, 1.309)}) {
    SCOPED_TRACE(camera.transpose());
    const TopView v = computeTopView(tree, {camera});
    const auto cellOf = [&](double x, double y) {
      return std::make_pair(static_cast<int>(std::floor((x - v.x0) / res + 0.5)),
                            static_cast<int>(std::floor((y - v.y0) / res + 0.5)));
    };
    int filled = 0;
    for (int cy = 0; cy < v.rows; ++cy)
      for (int cx = 0; cx < v.columns; ++cx) filled += !v.empty(cx, cy);
    EXPECT_EQ(filled, 12 * 8 + 4);
    for (int i = 0; i < 12; ++i) {
      for (int j = 0; j < 8; ++j) {
        const auto [cx, cy] = cellOf((i + 0.5) * res, (j + 0.5) * res);
        ASSERT_TRUE(cx >= 0 && cy >= 0 && cx < v.columns && cy < v.rows);
        const bool box = j == 0 && i >= 2 && i < 5;
        EXPECT_NEAR(v.top[v.cell(cx, cy)], box ? 0.3 : 0.0, 1e-9) << i << " " << j;
        const Rgb want = box ? mobilityColour(0.0) : (i == 11 && j == 7 ? unknownColour() : mobilityColour(1.0));
        EXPECT_EQ(v.colour[v.cell(cx, cy)], want) << i << " " << j;
      }
    }
    for (const double x : {0.81, 0.83}) {
      for (const double y : {0.81, 0.83}) {
        const auto [cx, cy] = cellOf(x, y);
        EXPECT_EQ(v.colour[v.cell(cx, cy)], mobilityColour(0.5));
      }
    }
    const auto [kx, ky] = cellOf(camera.x(), camera.y());  // the path is inside the picture
    EXPECT_TRUE(kx >= 0 && ky >= 0 && kx < v.columns && ky < v.rows);
  }
  EXPECT_THROW(computeTopView(mapping::MobilityOcTree(res)), std::invalid_argument);
}

// `export --max-z`: the top view cut at a height shows what lies under the cut (the floor
// under a table), and a pruned block straddling the cut shows its highest voxel below it.
TEST(TopView, ACutShowsTheHighestSurfaceBelowIt) {
  const double res = 0.02;
  mapping::MobilityOcTree tree(res);
  const auto put = [&](double x, double y, double z, double mobility) {
    tree.updateNode(octomap::point3d(x, y, z), true)->fuse(mobility, 0.01, 100.0);
  };
  for (int i = 0; i < 6; ++i) put((i + 0.5) * res, 0.5 * res, -0.01, 1.0);  // floor, tops at z = 0
  for (int i = 0; i < 3; ++i) put((i + 0.5) * res, 0.5 * res, 0.71, 0.0);   // a table over half of it, tops at 0.72
  // A 2 x 2 x 2 block of equal voxels, pruned into one leaf spanning z = 0.64 .. 0.68.
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j)
      for (int k = 0; k < 2; ++k) put(0.4 + (i + 0.5) * res, 0.4 + (j + 0.5) * res, 0.64 + (k + 0.5) * res, 0.5);
  tree.prune();
  int pruned = 0;
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) pruned += it.getSize() > 1.5 * res;
  ASSERT_EQ(pruned, 1);
  const auto topAt = [](const TopView& v, double x, double y) {
    const int cx = static_cast<int>(std::floor((x - v.x0) / v.resolution + 0.5));
    const int cy = static_cast<int>(std::floor((y - v.y0) / v.resolution + 0.5));
    return std::make_pair(v.top[v.cell(cx, cy)], v.colour[v.cell(cx, cy)]);
  };
  const TopView all = computeTopView(tree);
  EXPECT_NEAR(topAt(all, 0.01, 0.01).first, 0.72, 1e-9);
  EXPECT_EQ(topAt(all, 0.01, 0.01).second, mobilityColour(0.0));
  EXPECT_NEAR(topAt(all, 0.41, 0.41).first, 0.68, 1e-9);
  // Between the floor and the table: the floor everywhere, the block whole.
  const TopView under = computeTopView(tree, {}, 0, 0.70);
  EXPECT_EQ(under.columns, all.columns);  // the same grid, so cuts line up
  EXPECT_EQ(under.rows, all.rows);
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(topAt(under, (i + 0.5) * res, 0.01).first, 0.0, 1e-9) << i;
    EXPECT_EQ(topAt(under, (i + 0.5) * res, 0.01).second, mobilityColour(1.0)) << i;
  }
  EXPECT_NEAR(topAt(under, 0.41, 0.41).first, 0.68, 1e-9);
  // Through the block: its lower voxels (top 0.66) are below the cut, its upper ones not.
  const TopView through = computeTopView(tree, {}, 0, 0.67);
  EXPECT_NEAR(topAt(through, 0.41, 0.41).first, 0.66, 1e-9);
  EXPECT_NEAR(topAt(through, 0.43, 0.43).first, 0.66, 1e-9);
  EXPECT_EQ(topAt(through, 0.41, 0.41).second, mobilityColour(0.5));
  // A cut inside its lowest voxel leaves nothing of the block; one on a top face keeps it.
  EXPECT_TRUE(std::isinf(topAt(computeTopView(tree, {}, 0, 0.65), 0.41, 0.41).first));
  EXPECT_NEAR(topAt(computeTopView(tree, {}, 0, 0.66), 0.41, 0.41).first, 0.66, 1e-9);
  // Below everything: an empty grid of the same size.
  const TopView none = computeTopView(tree, {}, 0, -0.5);
  EXPECT_EQ(none.columns, all.columns);
  EXPECT_TRUE(std::all_of(none.top.begin(), none.top.end(), [](double z) { return std::isinf(z); }));
  EXPECT_THROW(computeTopView(tree, {}, 0, std::nan("")), std::invalid_argument);
}

// A map with more columns than the picture may have: cells of k x k columns, each
// showing the highest of its voxels, and a far camera path shrinks the map instead of
// asking for a grid of millions of cells.
TEST(TopView, LargeMapsGetCellsOfSeveralColumnsShowingTheHighest) {
  const double res = 0.02;
  mapping::MobilityOcTree tree(res);
  for (int i = 0; i < 150; ++i) {
    for (int j = 0; j < 50; ++j) tree.updateNode(octomap::point3d((i + 0.5) * res, (j + 0.5) * res, -0.01), true)->fuse(1.0, 0.01, 100.0);
  }
  tree.updateNode(octomap::point3d(77.5 * res, 23.5 * res, 0.29), true)->fuse(0.0, 0.01, 100.0);
  const TopView v = computeTopView(tree, {}, 40);
  EXPECT_EQ(v.columns_per_cell, 4);  // 150 columns in at most 40 cells
  EXPECT_DOUBLE_EQ(v.resolution, 4 * res);
  EXPECT_EQ(v.columns, 38);
  EXPECT_EQ(v.rows, 13);
  for (int cy = 0; cy < v.rows; ++cy) {
    for (int cx = 0; cx < v.columns; ++cx) {
      const bool box = cx == 77 / 4 && cy == 23 / 4;
      EXPECT_NEAR(v.top[v.cell(cx, cy)], box ? 0.3 : 0.0, 1e-9) << cx << " " << cy;
      EXPECT_EQ(v.colour[v.cell(cx, cy)], box ? mobilityColour(0.0) : mobilityColour(1.0)) << cx << " " << cy;
    }
  }
  // Cell centres where the camera path is drawn: the box's cell holds the box's column.
  EXPECT_LE(std::abs(v.x0 + 19 * v.resolution - 77.5 * res), v.resolution / 2);
  EXPECT_LE(std::abs(v.y0 + 5 * v.resolution - 23.5 * res), v.resolution / 2);
  // One column per cell when it fits.
  const TopView fine = computeTopView(tree, {}, 150);
  EXPECT_EQ(fine.columns_per_cell, 1);
  EXPECT_EQ(fine.columns, 150);
  // Each cell names the voxel it shows (reach colours cells by it): an occupied voxel
  // whose top face is the cell's top, in one of the cell's columns; also when the floor
  // is pruned into blocks.
  const auto checkTopKeys = [](const mapping::MobilityOcTree& t, const TopView& view) {
    int checked = 0;
    for (int cy = 0; cy < view.rows; ++cy) {
      for (int cx = 0; cx < view.columns; ++cx) {
        if (view.empty(cx, cy)) continue;
        const octomap::OcTreeKey k = view.top_key[view.cell(cx, cy)];
        const auto* n = t.search(k);
        ASSERT_TRUE(n && t.isNodeOccupied(n)) << cx << " " << cy;
        const octomap::point3d c = t.keyToCoord(k);
        EXPECT_NEAR(c.z() + t.getResolution() / 2, view.top[view.cell(cx, cy)], 1e-6) << cx << " " << cy;
        EXPECT_LE(std::abs(c.x() - (view.x0 + cx * view.resolution)), view.resolution / 2 + 1e-6) << cx << " " << cy;
        EXPECT_LE(std::abs(c.y() - (view.y0 + cy * view.resolution)), view.resolution / 2 + 1e-6) << cx << " " << cy;
        ++checked;
      }
    }
    EXPECT_EQ(checked, view.columns * view.rows);  // the map fills its grid
  };
  checkTopKeys(tree, v);
  checkTopKeys(tree, fine);
  mapping::MobilityOcTree pruned(tree);
  for (int i = 0; i < 150; ++i) {  // a floor two voxels thick, all alike, prunes into 2 x 2 x 2 blocks and larger
    for (int j = 0; j < 50; ++j) {
      for (const float z : {-0.01f, -0.03f}) pruned.setNodeValue(octomap::point3d((i + 0.5) * res, (j + 0.5) * res, z), 1.0f)->setMobility(1.0, 100.0, 1);
    }
  }
  pruned.updateInnerOccupancy();
  pruned.prune();
  ASSERT_LT(pruned.getNumLeafNodes(), tree.getNumLeafNodes() / 3);
  checkTopKeys(pruned, computeTopView(pruned, {}, 40));
  checkTopKeys(pruned, computeTopView(pruned, {}, 150));
  // A camera 10 km away (500,001 columns from the first): 501 columns per cell, and the
  // map is still drawn.
  const TopView far = computeTopView(tree, {Eigen::Vector2d(1e4, 0.0)}, 1000);
  EXPECT_EQ(far.columns_per_cell, 501);
  EXPECT_LE(far.columns, 1000);
  EXPECT_NEAR(far.top[far.cell(0, 0)], 0.3, 1e-9);  // the whole map in one cell: the box is its highest
  EXPECT_THROW(computeTopView(tree, {Eigen::Vector2d(std::nan(""), 0.0)}, 1000), std::invalid_argument);
}

// Heights in the pictures: a floor with one voxel of noise under 10 % of its columns (across
// a contour level, so only the smoothing keeps lines off it) and
// four stair treads 17 cm apart, 30 cm deep. Contours cross between every two treads and
// between floor and first tread, never inside the noisy floor or a tread away from the
// risers; each level gets
// one height label within a voxel of its top; the drawn picture is dark along the lines.
TEST(TopView, ContoursAndLabelsTellStairTreadsApartAndIgnoreFloorNoise) {
  const double res = 0.02;
  mapping::MobilityOcTree tree(res);
  std::mt19937 rng(6);
  std::uniform_real_distribution<double> u(0, 1);
  // Columns i in [0, 100) along x: floor below x = 0.8, then treads every 15 columns.
  const auto level = [](int i) { return i < 40 ? 0 : std::min(4, (i - 40) / 15 + 1); };
  for (int i = 0; i < 100; ++i) {
    for (int j = 0; j < 40; ++j) {
      const int l = level(i);
      // Tops at 0.04 + 0.17 l (to a voxel); noise lifts a floor top to 0.06, across the
      // 0.05 m contour.
      int top_k = 1 + static_cast<int>(std::lround(0.17 * l / res));
      if (l == 0 && u(rng) < 0.1) top_k = 2;
      for (int k = 0; k <= top_k; ++k) {
        tree.updateNode(octomap::point3d((i + 0.5) * res, (j + 0.5) * res, (k + 0.5) * res), true)->fuse(k == top_k ? 1.0 : 0.0, 0.01, 100.0);
      }
    }
  }
  const TopView view = computeTopView(tree);
  ASSERT_EQ(view.columns, 100);
  ASSERT_EQ(view.rows, 40);
  const Contours c = computeContours(view, res, 100);
  EXPECT_DOUBLE_EQ(c.interval_m, 0.05);  // 0.68 m of heights: 14 intervals, and no finer than 2 voxels
  for (int cy = 0; cy < view.rows; ++cy) {
    for (int cx = 0; cx + 1 < view.columns; ++cx) {
      const std::size_t i = view.cell(cx, cy);
      // The smoothing reaches 2 cells: within that of a riser a line may stray.
      const bool boundary = level(cx) != level(cx + 1);
      bool near_riser = false;
      for (int d = -2; d <= 3; ++d) near_riser = near_riser || (cx + d >= 1 && cx + d < 100 && level(cx + d) != level(cx + d - 1));
      if (boundary) {
        EXPECT_NE(c.right[i], 0) << cx << " " << cy;
      } else if (!near_riser) {
        EXPECT_EQ(c.right[i], 0) << cx << " " << cy;
        if (cy + 1 < view.rows) {
          EXPECT_EQ(c.up[i], 0) << cx << " " << cy;
        }
      }
    }
  }
  // One label per level, at its height.
  ASSERT_EQ(c.labels.size(), 5u);
  std::vector<double> z;
  for (const auto& l : c.labels) {
    z.push_back(l.z_m);
    EXPECT_NEAR(static_cast<double>(l.cells), (l.z_m < 0.1 ? 40 : 15) * 40, 0.05 * (l.z_m < 0.1 ? 40 : 15) * 40);
  }
  std::sort(z.begin(), z.end());
  for (int l = 0; l <= 4; ++l) EXPECT_NEAR(z[static_cast<std::size_t>(l)], 0.04 + 0.17 * l, res) << l;
  // Drawn: the cells just right of each riser are dark along their left edge; a floor
  // cell's interior keeps its colour.
  TopViewPicture pic;
  const Picture canvas = drawTopView(view, pic, 400);
  const int ppv = 4;  // 100 columns in 400 pixels
  ASSERT_EQ(describeTopView(view, canvas, 400).find("4 px per 2 cm voxel") != std::string::npos, true);
  const ImageRgb image = canvas.toImage();
  const auto get = [&](int x, int y) {
    return image.pixels[static_cast<std::size_t>(y) * static_cast<std::size_t>(image.width) + static_cast<std::size_t>(x)];
  };
  const int mx = static_cast<int>(kTopViewMapX), my = static_cast<int>(kTopViewMapY);
  for (const int riser : {40, 55, 70, 85}) {
    const Rgb edge = get(mx + riser * ppv, my + 20 * ppv + 1);
    EXPECT_LT(static_cast<int>(edge[0]) + edge[1] + edge[2], 3 * 100) << riser;
  }
  const Rgb inside = get(mx + 10 * ppv + 1, my + 20 * ppv + 1);
  EXPECT_EQ(inside, view.colour[view.cell(10, view.rows - 1 - 20)]);
}

// Labels on levels, not slopes: a floor, a 5 degree ramp (2 cm voxels make it a
// staircase of 23 cm plateaus), a landing, a 15 degree ramp and a top landing; beside
// them a lone 5-degree wedge on a 1 cm plinth that drops back to the floor at its high
// end: its top 13 columns have the same voxel top, above a height line, with lower
// ground on both sides, so a plane through the heights around them is nearly level. Each of
// the three level areas gets one label at its height; no label lands on a ramp; and in
// the drawn picture no two texts (labels, legend, title, scale) overlap.
TEST(TopView, HeightLabelsMarkLevelsNotRampsAndNoTwoTextsOverlap) {
  const double res = 0.02;
  mapping::MobilityOcTree tree(res);
  // Columns i in [0, 150) along x: floor, ramp, landing, ramp, landing, 30 columns each.
  const double rise5 = 0.6 * std::tan(5 * M_PI / 180), rise15 = 0.6 * std::tan(15 * M_PI / 180);
  const auto height = [&](int i) {
    const double x = (i + 0.5) * res;
    if (i < 30) return 0.0;
    if (i < 60) return (x - 0.6) * std::tan(5 * M_PI / 180);
    if (i < 90) return rise5;
    if (i < 120) return rise5 + (x - 1.8) * std::tan(15 * M_PI / 180);
    return rise5 + rise15;
  };
  const auto flat = [](int i) { return i < 30 || (i >= 60 && i < 90) || i >= 120; };
  // The wedge: rows 45-79, columns 30-59, rising 5 degrees along x from 1 cm; floor around it.
  const auto wedge = [&](int i, int j) { return j >= 45 && i >= 30 && i < 60; };
  const auto heightAt = [&](int i, int j) {
    if (j < 40) return height(i);
    return wedge(i, j) ? 0.01 + ((i + 0.5) * res - 0.6) * std::tan(5 * M_PI / 180) : 0.0;
  };
  for (int i = 0; i < 150; ++i) {
    for (int j = 0; j < 80; ++j) {
      const int top_k = static_cast<int>(std::floor(heightAt(i, j) / res + 1e-9));
      for (int k = 0; k <= top_k; ++k) {
        tree.updateNode(octomap::point3d((i + 0.5) * res, (j + 0.5) * res, (k + 0.5) * res), true)->fuse(1.0, 0.01, 100.0);
      }
    }
  }
  const TopView view = computeTopView(tree);
  ASSERT_EQ(view.columns, 150);
  ASSERT_EQ(view.rows, 80);
  const Contours c = computeContours(view, res, 100);
  int floor_labels = 0, landing_labels = 0, top_labels = 0;
  const auto topOf = [&](double z) { return (std::floor(z / res + 1e-9) + 1) * res; };  // a level's voxel tops
  for (const Contours::Label& l : c.labels) {
    EXPECT_FALSE(wedge(l.cx, l.cy)) << "a label on the wedge, at column " << l.cx << ", z " << l.z_m;
    EXPECT_TRUE(l.cy >= 40 || flat(l.cx)) << "a label on a ramp, at column " << l.cx << ", z " << l.z_m;
    floor_labels += std::abs(l.z_m - topOf(0)) < 1e-9;
    landing_labels += std::abs(l.z_m - topOf(rise5)) < 1e-9;
    top_labels += std::abs(l.z_m - topOf(rise5 + rise15)) < 1e-9;
  }
  // One floor: left of the ramps, around the wedge (with its low end) and right of it.
  EXPECT_EQ(floor_labels, 1);
  EXPECT_EQ(landing_labels, 1);
  EXPECT_EQ(top_labels, 1);
  TopViewPicture pic;
  pic.title = "Ramps between landings";
  pic.path = {{0.1, 0.1}, {2.9, 0.7}};
  pic.mark = Eigen::Vector2d(1.5, 0.4);
  pic.mark_label = "goal";
  for (const int max_pixels : {200, 600, 1400}) {
    const Picture picture = drawTopView(view, pic, max_pixels);
    const auto& texts = picture.texts();
    std::size_t labels = 0;
    for (const PlacedText& t : texts) labels += t.text.size() > 2 && t.text.substr(t.text.size() - 2) == " m" && t.text[0] != 'h';
    EXPECT_GE(labels, 1u) << max_pixels;
    for (std::size_t a = 0; a < texts.size(); ++a) {
      EXPECT_TRUE(texts[a].box.inside({0, 0, static_cast<double>(picture.width()), static_cast<double>(picture.height())}))
          << texts[a].text;
      for (std::size_t b = a + 1; b < texts.size(); ++b) {
        EXPECT_FALSE(texts[a].box.intersects(texts[b].box)) << max_pixels << ": '" << texts[a].text << "' and '" << texts[b].text << "'";
      }
    }
  }
}

}  // namespace
}  // namespace mobmap::app
