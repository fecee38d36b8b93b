// The C++ reference for the Python query benchmark (python_query_bench.py): reads points
// as 'x y z' lines, queries each in a map with MobilityMap::query, and prints the median
// of 5 passes in milliseconds.
//   point_query_bench MAP.ot POINTS.txt

#include "mobmap/mapping/mobility_map.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <vector>

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: point_query_bench MAP.ot POINTS.txt\n");
    return 2;
  }
  const mobmap::mapping::MobilityMap map = mobmap::mapping::openMap(argv[1]);
  std::ifstream in(argv[2]);
  std::vector<Eigen::Vector3d> points;
  double x = 0, y = 0, z = 0;
  while (in >> x >> y >> z) points.emplace_back(x, y, z);
  std::vector<double> ms;
  double sink = 0;
  for (int pass = 0; pass < 5; ++pass) {
    const auto t0 = std::chrono::steady_clock::now();
    for (const Eigen::Vector3d& p : points) {
      const auto q = map.query(p);
      sink += q.has_mobility ? q.mobility : 0.0;
    }
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(ms.begin(), ms.end());
  std::printf("%zu points: median %.2f ms (checksum %.3f)\n", points.size(), ms[2], sink / 5);
  return 0;
}
