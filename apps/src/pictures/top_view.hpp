#pragma once
// The grid behind `export --png`: the highest surface voxel of every map column.

#include "pictures/picture.hpp"

#include "mobmap/mapping/mobility_octree.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace mobmap::app {

/// A grid over the map's columns (x right and y up in the map frame), covering every
/// occupied voxel and every point of `also_cover` (the camera path). A cell is one map
/// column, or k x k columns when the map would not fit in the asked size.
struct TopView {
  double x0 = 0.0, y0 = 0.0;  ///< centre of cell (0, 0) (a column centre when columns_per_cell is 1)
  double resolution = 0.0;    ///< cell side in metres: the map resolution times columns_per_cell
  int columns_per_cell = 1;   ///< k: each cell is k x k map columns and shows the highest of them
  int columns = 0, rows = 0;  ///< cells across (x) and up (y)
  std::vector<double> top;   ///< per cell, row-major from y0 up: the top face's height, -inf if empty
  std::vector<Rgb> colour;   ///< per cell: mobility colour of that voxel, grey if unknown, white if empty
  /// per cell: the finest-level key of the voxel whose top face is `top` (of a pruned
  /// block, its voxel in the cell's first column it covers); meaningless where empty
  std::vector<octomap::OcTreeKey> top_key;
  [[nodiscard]] std::size_t cell(int cx, int cy) const {
    return static_cast<std::size_t>(cy) * static_cast<std::size_t>(columns) + static_cast<std::size_t>(cx);
  }
  [[nodiscard]] bool empty(int cx, int cy) const { return top[cell(cx, cy)] == -std::numeric_limits<double>::infinity(); }
};

/// A surface voxel's colour in the pictures: its mobility on `scale`, or the unknown colour.
inline Rgb voxelColour(const mapping::MobilityOcTreeNode& n, ColourScale scale = ColourScale::kViridis) {
  return mapping::mobilityRgb(n, scale);
}

/// `max_cells_per_side` > 0 picks the smallest k that keeps both sides within it (0: one
/// column per cell). `max_z` (map frame): only voxels whose top face is at or below it
/// are drawn (the floor under a table, a room under its ceiling); the grid still covers
/// every occupied voxel, so pictures cut at different heights line up. Throws
/// std::invalid_argument if the tree has no occupied voxel, a point to cover or max_z
/// is NaN, or the grid would exceed 2^20 cells per side.
TopView computeTopView(const mapping::MobilityOcTree& tree, const std::vector<Eigen::Vector2d>& also_cover = {},
                       int max_cells_per_side = 0, double max_z = std::numeric_limits<double>::infinity(),
                       ColourScale scale = ColourScale::kViridis);

/// UsageError "--max-z Z: no surface voxel has its top at or below it (the lowest top is
/// at z = ...)" when the cut left every cell of `view` empty.
void requireSurfaceBelowCut(const TopView& view, const mapping::MobilityOcTree& tree, double max_z);

/// Height contours of a top view, so that levels (stair treads, a table top, the floor)
/// can be told apart where their mobility colours are alike. The cells' heights are
/// smoothed by a 5x5 median over the cells that hold a surface (one voxel of noise on a
/// floor draws no line; a step and a ramp keep their heights), then cut every interval_m.
struct Contours {
  /// A 1-2-5 step: the finest that gives at most 20 intervals over the smoothed heights,
  /// and no finer than two of the map's voxels. 0 when the view is empty.
  double interval_m = 0;
  double z_min = 0, z_max = 0;  ///< of the smoothed heights
  /// Per cell, between it and its +x / +y neighbour (both holding a surface): 0 no line,
  /// 1 a contour crosses, 2 a major one (a multiple of 5 intervals) does.
  std::vector<std::uint8_t> right, up;
  /// Levels between contours that a height label fits in (largest first, at most 24):
  /// areas whose smoothed heights (10th to 90th percentile) lie within the larger of a
  /// voxel and half an interval, so not the band of a ramp between two contours; the
  /// cell nearest their centroid and their median smoothed height.
  struct Label {
    int cx = 0, cy = 0;
    double z_m = 0;
    std::size_t cells = 0;
  };
  std::vector<Label> labels;
};
/// `voxel_m`: the map's resolution; `min_label_cells`: the fewest cells an area needs for
/// a label.
Contours computeContours(const TopView& view, double voxel_m, std::size_t min_label_cells = 0);

/// What a top-view picture shows besides the cells: a title, the camera path, extra
/// legend entries and one marked point.
struct TopViewPicture {
  std::string title;
  std::vector<Eigen::Vector2d> path;      ///< camera positions, map frame (x, y)
  std::vector<std::size_t> run_starts{0};  ///< indices into path where a run begins (no line into them)
  /// The colour scale the cells were coloured on (computeTopView's), for the legend.
  ColourScale colours = ColourScale::kViridis;
  /// Legend swatches under "unknown", e.g. {dark grey, "not reachable"}.
  std::vector<std::pair<Rgb, std::string>> swatches;
  std::optional<Eigen::Vector2d> mark;     ///< drawn as a black ring, e.g. a start point
  std::string mark_label;                  ///< its legend entry
  /// Closed outlines (map frame x, y corners) drawn two pixels wide over the cells, e.g.
  /// footsteps; each distinct label gets one legend entry in its outline's colour.
  struct Outline {
    std::vector<Eigen::Vector2d> corners;
    Rgb colour{0, 0, 0};
    std::string label;
  };
  std::vector<Outline> outlines;
  /// Height contours over the cells (computeContours), with their interval in the legend.
  bool contours = true;
};

/// Where drawTopView puts the top-left corner of the map area, in picture units.
inline constexpr double kTopViewMapX = 40, kTopViewMapY = 50;

/// The picture of `export --png`, `reach --png` and `plan --png`: the cells (x right, y
/// up), height lines with labels on the levels (none covering another), the camera path,
/// outlines, a scale bar, the mobility legend and the axes. `max_pixels` is the longest
/// side of the map area.
Picture drawTopView(const TopView& view, const TopViewPicture& picture, int max_pixels);

/// What a drawn top view holds, for the "wrote" line: "1530x1336 px, 8 px per 2 cm
/// voxel", or for a cell of k x k voxels "438x300 px, 1 px per 6 cm cell: the highest of
/// 3x3 voxels; --max-pixels for more".
std::string describeTopView(const TopView& view, const Picture& picture, int max_pixels);

}  // namespace mobmap::app
