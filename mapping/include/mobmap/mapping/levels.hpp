#pragma once
/// @file levels.hpp
/// Heights where surfaces gather (floors, landings, table tops): `info`'s walkable
/// levels, the level `reach` starts on when the robot's footing was never seen, and
/// where the surfaces out of reach lie.

#include <cstddef>
#include <map>
#include <vector>

namespace mobmap::mapping {

/// A surface is walkable, for counting levels, at this mobility or more.
constexpr double kWalkableMobility = 0.75;

class SurfaceColumns;

struct Level {
  double z_m = 0.0;     ///< count-weighted mean of the bins it took
  std::size_t count = 0;
  double share = 0.0;   ///< of all counted
};

/// `bins`: round(height / res) -> count. The fullest bin not within 3 bins of a level
/// already taken starts a level (the lowest of equally full bins), which takes the bins
/// next to it (noise spreads a floor over two), until the levels left hold under
/// `min_share` of the total. At most `max_levels`, fullest first.
std::vector<Level> gatherLevels(std::map<long, std::size_t> bins, double res, std::size_t max_levels = 4,
                                double min_share = 0.05);

/// The walkable surfaces of a map, binned for gatherLevels(): round(top face / res) ->
/// count, over the top voxel of every run of occupied voxels in every column (a floor a
/// few voxels thick counts once per column) whose mobility is kWalkableMobility or more.
/// What `mobmap info` lists as walkable levels, and how Start::kLargestLevel (see
/// reachability.hpp) measures a level.
std::map<long, std::size_t> walkableBins(const SurfaceColumns& columns);

}  // namespace mobmap::mapping
