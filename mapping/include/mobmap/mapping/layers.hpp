#pragma once
/// @file layers.hpp
/// 2.5D layers of a 3D map, one grid per level, as footstep planners and navigation
/// stacks read them (grid_map's elevation, variance, step, slope, traversability). A 3D
/// map can give one correct 2.5D view per level: the floor under a platform the robot
/// walks beneath is a layer of its own.
///
/// A level is a height where walkable surface gathers (gatherLevels(walkableBins())).
/// A level higher than the one below it by less than `clearance_m` (the robot's height)
/// is no level of its own: the robot cannot stand under it, so its surfaces are elevation
/// on the level below (a table top over the floor). Level k's layer holds, in each column,
/// the highest run of occupied voxels whose bottom face lies below z_k + clearance_m (the
/// robot does not fit under it) and whose top face lies at or above the top of level
/// k-1's band (z_{k-1} + clearance_m; nothing for the lowest level). So a staircase rising
/// from the floor is rising elevation on the floor's layer up to the robot's height, and
/// falling elevation on the next level's layer from there; a floor a storey up is not on
/// the floor's layer; a wall reads its top.

#include "mobmap/mapping/footholds.hpp"

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace mobmap::mapping {

class Reachability;

/// One level and the band of surfaces its layer takes.
struct LayerLevel {
  double z_m = 0;          ///< reference height: the level's walkable top faces (map frame)
  double share = 0;        ///< of the map's walkable surface
  double min_top_m = 0;    ///< runs whose top face is below this belong to a lower level (-inf for the lowest)
  double max_bottom_m = 0; ///< runs whose bottom face is at or above this: the robot fits under them (z_m + clearance)
};

/// The levels of a map for a robot `clearance_m` tall, lowest first.
/// std::invalid_argument if clearance_m is not a finite length above 0.
[[nodiscard]] std::vector<LayerLevel> layerLevels(const SurfaceColumns& columns, double clearance_m);

/// Grid cells: --cell from the map's resolution to 100 m.
inline constexpr double kMaxLayerCellM = 100.0;
/// Cells one layer may hold (4096 x 4096; ~60 bytes each while it is made).
inline constexpr std::size_t kMaxLayerCells = 4096u * 4096u;

/// Traversability of a cell for the robot, as a nav2 map_server image encodes it.
enum class Traversable : std::uint8_t { kUnknown = 0, kFree = 1, kOccupied = 2 };

/// A level's layers on a grid of square cells, north up: row 0 is the highest y, column 0
/// the lowest x. Every layer is rows x cols floats, row by row; NaN where unknown.
struct LevelLayers {
  LayerLevel level;
  double cell_m = 0;
  double x_min = 0, y_min = 0;  ///< the grid's lower-left corner (map frame)
  int cols = 0, rows = 0;
  /// The top of the surface in the cell: the highest of its columns' runs (m, map frame).
  std::vector<float> elevation;
  /// Spread of those tops within the cell plus a voxel's quantisation (res^2 / 12), m^2.
  std::vector<float> elevation_variance;
  /// The mobility of the surface giving the elevation (its run's, as footprint() reads
  /// it) and its variance; NaN where that surface has no mobility.
  std::vector<float> mobility;
  std::vector<float> mobility_variance;
  /// Largest height difference to the eight neighbouring cells that are known (m; 0 with
  /// none known).
  std::vector<float> step;
  /// Tilt of the plane fitted to the elevation of the cell and its known neighbours
  /// (degrees; NaN with fewer than three, or all in a line).
  std::vector<float> slope_deg;
  /// Share of the cell's map columns whose surface is on this level (0..1; never NaN).
  std::vector<float> known;
  /// Filled when a Reachability was given: free where most of the cell's surface lies
  /// under a standable sole and the step to its neighbours is one the robot takes
  /// (robot.max_step_m), occupied where not (a box edge, a wall, a steep ramp, a riser
  /// too high), unknown where no surface is known.
  std::vector<Traversable> traversable;

  [[nodiscard]] std::size_t index(int row, int col) const {
    return static_cast<std::size_t>(row) * static_cast<std::size_t>(cols) + static_cast<std::size_t>(col);
  }
  /// Centre of a cell (map frame).
  [[nodiscard]] double cellX(int col) const { return x_min + (col + 0.5) * cell_m; }
  [[nodiscard]] double cellY(int row) const { return y_min + (rows - row - 0.5) * cell_m; }
};

/// The height the walk of `reach` starts at: its start sole's support, else the start
/// level's height; nullopt when it found nowhere to start.
[[nodiscard]] std::optional<double> startHeight(const Reachability& reach);
/// The index of the level nearest `z_m` (the lowest of equally near ones); `levels` must
/// not be empty.
[[nodiscard]] std::size_t nearestLevel(const std::vector<LayerLevel>& levels, double z_m);

/// The names of the float layers, in the order a GeoTIFF's bands take them.
[[nodiscard]] const std::vector<std::string>& layerNames();
/// The float layer of that name (layerNames()).
[[nodiscard]] const std::vector<float>& layerByName(const LevelLayers& layers, const std::string& name);

/// std::invalid_argument naming the problem: a cell not finite, below the columns'
/// resolution (less 1e-9 m) or above kMaxLayerCellM.
void checkLayerCell(double cell_m, double resolution_m);

/// The layers of `level` over the extent of the map's columns, in cells of `cell_m`
/// (checkLayerCell). `reach` (computed on the same map; may be null) gives the
/// traversable layer. std::length_error if the grid would hold more than kMaxLayerCells.
[[nodiscard]] LevelLayers levelLayers(const SurfaceColumns& columns, const LayerLevel& level, double cell_m,
                                      const Reachability* reach = nullptr);

/// A grid its caller places: the lower-left corner (map frame) and the cells along x and y.
struct LayerWindow {
  double x_min = 0, y_min = 0;
  int cols = 0, rows = 0;
};

/// The layers of `level` on the window's grid (a map around a robot), whatever the map's
/// extent: a map column belongs to the cell its centre lies in; cells outside the map are
/// unknown. std::invalid_argument for a bad cell (checkLayerCell), a corner not finite or
/// more than kMaxLayerCells cells.
[[nodiscard]] LevelLayers levelLayers(const SurfaceColumns& columns, const LayerLevel& level, double cell_m,
                                      const LayerWindow& window, const Reachability* reach = nullptr);

}  // namespace mobmap::mapping
