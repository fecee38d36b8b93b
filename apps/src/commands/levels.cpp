#include "commands/levels.hpp"

#include <algorithm>
#include <cstdlib>

namespace mobmap::app {

std::vector<Level> gatherLevels(std::map<long, std::size_t> bins, double res, std::size_t max_levels, double min_share) {
  std::size_t total = 0;
  for (const auto& b : bins) total += b.second;
  std::vector<Level> levels;
  std::vector<long> taken;
  while (levels.size() < max_levels && !bins.empty()) {
    long peak = 0;
    std::size_t most = 0;
    for (const auto& [b, n] : bins) {
      const long bin = b;  // C++17 lambdas cannot capture a structured binding (clang refuses)
      const bool near = std::any_of(taken.begin(), taken.end(), [bin](long k) { return std::abs(k - bin) <= 3; });
      if (!near && n > most) peak = b, most = n;
    }
    if (most == 0) break;
    Level l;
    double zsum = 0.0;
    for (long b = peak - 1; b <= peak + 1; ++b) {
      const auto it = bins.find(b);
      if (it == bins.end()) continue;
      l.count += it->second;
      zsum += static_cast<double>(it->second) * static_cast<double>(b) * res;
      bins.erase(it);
    }
    l.z_m = zsum / static_cast<double>(l.count);
    l.share = static_cast<double>(l.count) / static_cast<double>(total);
    if (l.share < min_share) break;
    levels.push_back(l);
    taken.push_back(peak);
  }
  return levels;
}

}  // namespace mobmap::app
