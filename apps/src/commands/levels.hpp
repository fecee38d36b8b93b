#pragma once
// Heights where surfaces gather (floors, landings, table tops): `info`'s walkable
// levels and `reach`'s unreachable ones.

#include <cstddef>
#include <map>
#include <vector>

namespace mobmap::app {

struct Level {
  double z_m = 0.0;     ///< count-weighted mean of the bins it took
  std::size_t count = 0;
  double share = 0.0;   ///< of all counted
};

/// `bins`: round(height / res) -> count. The fullest bin not within 3 bins of a level
/// already taken starts a level, which takes the bins next to it (noise spreads a floor
/// over two), until the levels left hold under `min_share` of the total. At most
/// `max_levels`, fullest first.
std::vector<Level> gatherLevels(std::map<long, std::size_t> bins, double res, std::size_t max_levels = 4,
                                double min_share = 0.05);

}  // namespace mobmap::app
