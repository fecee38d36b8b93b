#pragma once
// The grid behind `export --png`: the highest surface voxel of every map column.

#include "canvas.hpp"

#include "mobmap/mapping/mobility_octree.hpp"

#include <Eigen/Core>

#include <limits>
#include <vector>

namespace mobmap::app {

/// One cell per map column (resolution x resolution, x right and y up in the map frame),
/// covering every occupied voxel and every point of `also_cover` (the camera path).
struct TopView {
  double x0 = 0.0, y0 = 0.0;  ///< centre of cell (0, 0): a column centre of the map
  double resolution = 0.0;
  int columns = 0, rows = 0;
  std::vector<double> top;   ///< per cell, row-major from y0 up: the top face's height, -inf if empty
  std::vector<Rgb> colour;   ///< per cell: mobility colour of that voxel, grey if unknown, white if empty
  [[nodiscard]] std::size_t cell(int cx, int cy) const {
    return static_cast<std::size_t>(cy) * static_cast<std::size_t>(columns) + static_cast<std::size_t>(cx);
  }
  [[nodiscard]] bool empty(int cx, int cy) const { return top[cell(cx, cy)] == -std::numeric_limits<double>::infinity(); }
};

/// Colour of unknown mobility (a surface seen, never scored).
inline constexpr Rgb kUnknownGrey{150, 150, 150};

/// A surface voxel's colour in the pictures: its mobility, or grey when unknown.
inline Rgb voxelColour(const mapping::MobilityOcTreeNode& n) {
  return n.hasMobility() ? mobilityColour(n.mobility()) : kUnknownGrey;
}

/// Throws std::invalid_argument if the tree has no occupied voxel.
TopView computeTopView(const mapping::MobilityOcTree& tree, const std::vector<Eigen::Vector2d>& also_cover = {});

}  // namespace mobmap::app
