#pragma once
/// @file denoising.hpp
/// Paper step 2, denoising: statistical outlier removal (eq. 1).

#include "mobmap/perception/neighbours.hpp"

#include <vector>

namespace mobmap::perception {

/// Statistical outlier removal (paper eq. 1): mean distance d_i to the k nearest
/// neighbours; keep points with |d_i - mu| <= alpha sigma over the cloud. Returns the
/// mask of kept points. Points without k neighbours within the graph are removed.
/// k defaults to graph.k; a smaller k uses the first k entries of each row.
std::vector<bool> statisticalOutlierMask(const KnnGraph& graph, double alpha, int k = 0);

}  // namespace mobmap::perception
