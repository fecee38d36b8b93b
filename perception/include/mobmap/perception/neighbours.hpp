#pragma once
/// @file neighbours.hpp
/// Exact k-nearest-neighbour search over a point cloud with a hashed uniform grid.

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace mobmap::perception {

/// k nearest neighbours of every point (excluding the point itself), stored flat:
/// the neighbours of point i are indices[i*k .. i*k+count[i]), nearest first, with
/// squared distances in sq_dist; the rest of a row holds index -1 and distance 0.
/// count[i] < k only when the cloud has fewer than k+1 points or the point is
/// isolated beyond `max_radius`.
struct KnnGraph {
  int k = 0;
  std::vector<int> indices;
  std::vector<float> sq_dist;
  std::vector<int> count;
};

/// Builds the exact kNN graph. Points are bucketed into cubic cells of `cell_m`;
/// each point's candidates come from the 3x3x3 cells around it, which is exact as
/// long as the k-th distance is at most `cell_m`; otherwise the search widens ring by
/// ring (each ring adds a guaranteed cell_m of radius) up to `max_radius_m`.
/// Cost is linear in the number of points for surface-like clouds. Points must be
/// finite. Throws std::invalid_argument for k < 1 or non-positive sizes.
KnnGraph buildKnnGraph(const std::vector<Eigen::Vector3f>& points, int k, float cell_m,
                       float max_radius_m);

/// The same graph into `out`, reusing its buffers: a caller that keeps one graph
/// from frame to frame neither allocates nor clears tens of MB per frame.
void buildKnnGraph(const std::vector<Eigen::Vector3f>& points, int k, float cell_m, float max_radius_m,
                   KnnGraph& out);

/// The exact k-NN graph (k <= graph.k) of the points with keep[i], renumbered in
/// their original order, derived from `graph` (the k-NN graph of all `points` built
/// with the same max_radius_m). A kept point's row is the first k kept entries of its
/// old row; only points that lost too many neighbours to the mask are searched again
/// (their number goes to `recomputed`). Equal to buildKnnGraph on the kept points.
KnnGraph restrictKnnGraph(const KnnGraph& graph, const std::vector<Eigen::Vector3f>& points,
                          const std::vector<bool>& keep, int k, float cell_m, float max_radius_m,
                          std::size_t* recomputed = nullptr);

/// The same graph into `out` (not `graph` itself), reusing its buffers.
void restrictKnnGraph(const KnnGraph& graph, const std::vector<Eigen::Vector3f>& points,
                      const std::vector<bool>& keep, int k, float cell_m, float max_radius_m, KnnGraph& out,
                      std::size_t* recomputed = nullptr);

/// The same graph built in `graph` itself, which it replaces (no second buffer of
/// tens of MB for a VGA frame).
void restrictKnnGraphInPlace(KnnGraph& graph, const std::vector<Eigen::Vector3f>& points,
                             const std::vector<bool>& keep, int k, float cell_m, float max_radius_m,
                             std::size_t* recomputed = nullptr);

/// Reference: the same graph by brute force, O(n^2). For tests.
KnnGraph bruteForceKnnGraph(const std::vector<Eigen::Vector3f>& points, int k);

}  // namespace mobmap::perception
