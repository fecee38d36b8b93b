#include "top_view.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace mobmap::app {

TopView computeTopView(const mapping::MobilityOcTree& t, const std::vector<Eigen::Vector2d>& also_cover,
                       int max_cells_per_side, double max_z) {
  if (std::isnan(max_z)) throw std::invalid_argument("the height to cut at is not a number");
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) {
    if (!t.isNodeOccupied(*it)) continue;
    x0 = std::min(x0, it.getX()), x1 = std::max(x1, it.getX());
    y0 = std::min(y0, it.getY()), y1 = std::max(y1, it.getY());
  }
  if (x1 < x0) throw std::invalid_argument("the map has no surface voxels");
  for (const Eigen::Vector2d& p : also_cover) {
    if (!p.allFinite()) throw std::invalid_argument("a point to cover is not finite");
    x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x());
    y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
  }
  const double res = t.getResolution();
  // The corner columns' centres (OctoMap's voxel faces lie at multiples of res). A
  // camera position taken as a corner as it is would put voxel centres half way between
  // cells, where rounding sends some columns into their neighbour's cell and leaves
  // empty lines across the picture.
  const auto centre = [res](double c) { return (std::floor(c / res) + 0.5) * res; };
  const double col_x0 = centre(x0), col_y0 = centre(y0);
  const double span_columns = std::max(std::round((centre(x1) - col_x0) / res), std::round((centre(y1) - col_y0) / res)) + 1;
  // Cells of k x k columns when the columns would not fit (a large map, or a camera
  // path far from the surfaces); the count is bounded before it becomes an int.
  double k = 1.0;
  if (max_cells_per_side > 0) k = std::max(1.0, std::ceil(span_columns / max_cells_per_side));
  if (span_columns / k > (1 << 20)) throw std::invalid_argument("the top view would have more than 2^20 cells per side");
  const int per = static_cast<int>(k);
  const auto cells = [&](double first, double last) {
    return static_cast<int>((std::lround((centre(last) - first) / res) + 1 + per - 1) / per);
  };
  TopView v;
  v.columns_per_cell = per;
  v.resolution = res * per;
  v.columns = cells(col_x0, x1);
  v.rows = cells(col_y0, y1);
  v.x0 = col_x0 + (per - 1) * res / 2, v.y0 = col_y0 + (per - 1) * res / 2;
  v.top.assign(static_cast<std::size_t>(v.columns) * static_cast<std::size_t>(v.rows),
               -std::numeric_limits<double>::infinity());
  v.colour.assign(v.top.size(), {255, 255, 255});
  for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) {
    if (!t.isNodeOccupied(*it)) continue;
    // A pruned leaf covers span x span columns.
    const int span = static_cast<int>(std::lround(it.getSize() / res));
    const long col0 = std::lround((it.getX() - it.getSize() / 2 + res / 2 - col_x0) / res);
    const long row0 = std::lround((it.getY() - it.getSize() / 2 + res / 2 - col_y0) / res);
    // Its top face, or under a cut through a pruned block, the top of its highest voxel
    // below the cut (the block's voxels are all alike).
    const double bottom = it.getZ() - it.getSize() / 2;
    double z = it.getZ() + it.getSize() / 2;
    if (z > max_z + 1e-9) {
      const double voxels_below = std::floor((max_z - bottom) / res + 1e-9);
      if (voxels_below < 1) continue;
      z = bottom + voxels_below * res;
    }
    const Rgb colour = voxelColour(*it);
    // The cells its columns fall in (one, unless the leaf is larger than a cell).
    const auto cellOf = [per](long column) { return column >= 0 ? column / per : -((-column + per - 1) / per); };
    const long cx_first = std::max(0L, cellOf(col0)), cx_last = std::min<long>(v.columns - 1, cellOf(col0 + span - 1));
    const long cy_first = std::max(0L, cellOf(row0)), cy_last = std::min<long>(v.rows - 1, cellOf(row0 + span - 1));
    for (long cy = cy_first; cy <= cy_last; ++cy) {
      for (long cx = cx_first; cx <= cx_last; ++cx) {
        const std::size_t i = v.cell(static_cast<int>(cx), static_cast<int>(cy));
        if (z > v.top[i]) {
          v.top[i] = z;
          v.colour[i] = colour;
        }
      }
    }
  }
  return v;
}

}  // namespace mobmap::app
