#pragma once
/// @file segmentation.hpp
/// Paper step 6, segmentation: region growing on RGB-N colours (Algorithm 1).

#include "mobmap/perception/neighbours.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <vector>

namespace mobmap::perception {

/// Region growing on colours (paper Algorithm 1): a neighbour joins the region of the
/// point it is reached from if it is within `max_distance_m` and the Euclidean
/// distance of their YCrCb colours is at most `colour_threshold`. Only points with
/// `eligible[i]` take part. Regions smaller than `min_points` are dropped (label -1).
/// With `normals`, a point also needs a normal within `max_deviation_deg` of the mean
/// normal of the region so far: normals estimated across a crease turn gradually from
/// one face to the other, and neighbour-to-neighbour colour steps alone would carry a
/// region round the edge of a box onto its sides. Ignored if `max_deviation_deg` >= 180.
/// Returns a label per point (0, 1, ... in order of seeds) and the number of regions.
std::vector<int> growRegions(const std::vector<Eigen::Vector3f>& points,
                             const std::vector<std::array<std::uint8_t, 3>>& colours, const KnnGraph& graph,
                             const std::vector<bool>& eligible, double colour_threshold, double max_distance_m,
                             int min_points, int* regions, const std::vector<Eigen::Vector3f>* normals = nullptr,
                             double max_deviation_deg = 180.0);

}  // namespace mobmap::perception
