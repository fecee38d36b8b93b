#include "top_view.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace mobmap::app {

TopView computeTopView(const mapping::MobilityOcTree& t, const std::vector<Eigen::Vector2d>& also_cover) {
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) {
    if (!t.isNodeOccupied(*it)) continue;
    x0 = std::min(x0, it.getX()), x1 = std::max(x1, it.getX());
    y0 = std::min(y0, it.getY()), y1 = std::max(y1, it.getY());
  }
  if (x1 < x0) throw std::invalid_argument("the map has no surface voxels");
  for (const Eigen::Vector2d& p : also_cover) {
    x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x());
    y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
  }
  TopView v;
  const double res = t.getResolution();
  v.resolution = res;
  // The corners are the centres of the corner columns (OctoMap's voxel faces lie at
  // multiples of res). A camera position taken as a corner as it is would put voxel
  // centres half way between cells, where rounding sends some columns into their
  // neighbour's cell and leaves empty lines across the picture.
  const auto centre = [res](double c) { return (std::floor(c / res) + 0.5) * res; };
  v.x0 = centre(x0), v.y0 = centre(y0);
  v.columns = static_cast<int>(std::lround((centre(x1) - v.x0) / res)) + 1;
  v.rows = static_cast<int>(std::lround((centre(y1) - v.y0) / res)) + 1;
  v.top.assign(static_cast<std::size_t>(v.columns) * static_cast<std::size_t>(v.rows),
               -std::numeric_limits<double>::infinity());
  v.colour.assign(v.top.size(), {255, 255, 255});
  for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) {
    if (!t.isNodeOccupied(*it)) continue;
    // A pruned leaf covers span x span columns.
    const int span = static_cast<int>(std::lround(it.getSize() / res));
    const int cx0 = static_cast<int>(std::lround((it.getX() - it.getSize() / 2 + res / 2 - v.x0) / res));
    const int cy0 = static_cast<int>(std::lround((it.getY() - it.getSize() / 2 + res / 2 - v.y0) / res));
    const double z = it.getZ() + it.getSize() / 2;
    const Rgb colour = voxelColour(*it);
    for (int dy = 0; dy < span; ++dy) {
      for (int dx = 0; dx < span; ++dx) {
        const int cx = cx0 + dx, cy = cy0 + dy;
        if (cx < 0 || cy < 0 || cx >= v.columns || cy >= v.rows) continue;
        const std::size_t i = v.cell(cx, cy);
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
