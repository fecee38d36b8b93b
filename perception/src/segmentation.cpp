// Paper step 6: region growing on RGB-N colours (Algorithm 1).

#include "mobmap/perception/segmentation.hpp"

#include "graph_walk.hpp"
#include "mobmap/perception/rgbn.hpp"

#include <algorithm>
#include <cmath>
#include <deque>

namespace mobmap::perception {

std::vector<int> growRegions(const std::vector<Eigen::Vector3f>& points,
                             const std::vector<std::array<std::uint8_t, 3>>& colours, const KnnGraph& g,
                             const std::vector<bool>& eligible, double colour_threshold, double max_distance_m,
                             int min_points, int* regions, const std::vector<Eigen::Vector3f>* normals,
                             double max_deviation_deg) {
  const std::size_t n = points.size();
  if (normals && normals->size() != n) throw std::invalid_argument("growRegions: normals size differs from points");
  const bool gate = normals && max_deviation_deg < 180.0;
  const float min_cos = static_cast<float>(std::cos(max_deviation_deg * M_PI / 180.0));
  std::vector<Eigen::Vector3f> ycc(n);
  for (std::size_t i = 0; i < n; ++i) ycc[i] = rgbToYCrCb(colours[i]);
  const float max_d2 = static_cast<float>(max_distance_m * max_distance_m);
  const float thr2 = static_cast<float>(colour_threshold * colour_threshold);
  // -1: not yet reached, -2: in a region below min_points, -3: not eligible. One test
  // of the label then rejects a neighbour.
  std::vector<int> label(n);
  for (std::size_t i = 0; i < n; ++i) label[i] = eligible[i] ? -1 : -3;
  // The queue ends up holding the region's members, in the order they were reached.
  std::vector<int> queue;
  int next = 0;
  for (std::size_t seed = 0; seed < n; ++seed) {
    if (label[seed] != -1) continue;
    queue.clear();
    queue.push_back(static_cast<int>(seed));
    label[seed] = next;
    Eigen::Vector3f normal_sum = Eigen::Vector3f::Zero();
    Eigen::Vector3f mean_dir = Eigen::Vector3f::Zero();
    for (std::size_t head = 0; head < queue.size(); ++head) {
      const int i = queue[head];
      prefetchRow(g, queue, head + 6);
      if (gate) {
        normal_sum += (*normals)[static_cast<std::size_t>(i)];
        mean_dir = normal_sum.normalized();
      }
      forNeighboursWithin(g, static_cast<std::size_t>(i), max_d2, [&](std::size_t nb) {
        if (label[nb] != -1) return;
        if ((ycc[static_cast<std::size_t>(i)] - ycc[nb]).squaredNorm() > thr2) return;
        if (gate && (*normals)[nb].dot(mean_dir) < min_cos) return;
        label[nb] = next;
        queue.push_back(static_cast<int>(nb));
      });
    }
    if (static_cast<int>(queue.size()) < min_points) {
      for (int i : queue) label[static_cast<std::size_t>(i)] = -2;  // visited, too small
    } else {
      ++next;
    }
  }
  for (auto& l : label) l = l < 0 ? -1 : l;
  if (regions) *regions = next;
  return label;
}

}  // namespace mobmap::perception
