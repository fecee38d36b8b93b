#include "mobmap/mapping/levels.hpp"

#include "mobmap/mapping/footholds.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>

namespace mobmap::mapping {

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

std::map<long, std::size_t> walkableBins(const SurfaceColumns& columns) {
  std::map<long, std::size_t> bins;
  const double res = columns.resolution();
  for (const SurfaceColumns::Run& run : columns.runs()) {
    if (run.hasMobility() && run.mobility >= kWalkableMobility) ++bins[std::lround(columns.topFace(run) / res)];
  }
  return bins;
}

}  // namespace mobmap::mapping
