#pragma once
/// @file normals.hpp
/// Paper step 3, normals by PCA of each point's neighbourhood (eqs. 2-4).

#include "mobmap/perception/neighbours.hpp"

#include <Eigen/Core>

#include <vector>

namespace mobmap::perception {

/// PCA normals (paper eqs. 2-3): eigenvector of the smallest eigenvalue of the
/// neighbourhood covariance (the point and its graph neighbours), oriented towards
/// `viewpoint` (eq. 4). Curvature = lambda_min / (sum of eigenvalues). Points with
/// fewer than 3 neighbours get a zero normal and curvature 1. If `projected` is given
/// it receives each point moved onto its neighbourhood's least-squares plane.
/// Fast path: with `near` (a unit vector per point not far from the answer, such as the
/// previous smoothing pass's normal or the direction to the camera), the eigenvector is
/// found by inverse iteration from it (multiplying by the covariance's adjugate, which
/// amplifies the smallest eigenvector by lambda_1 / lambda_0 per step, ~100 on a noisy
/// surface) until a step moves it by under 1e-5 rad, instead of the closed-form
/// eigen-decomposition; tests bound the difference. Points whose
/// `near` is zero, whose iteration does not converge in 8 steps, or whose smallest
/// eigenvalue exceeds a quarter of the sum (no plane) use the exact solver.
void estimateNormals(const std::vector<Eigen::Vector3f>& points, const KnnGraph& graph,
                     const Eigen::Vector3f& viewpoint, std::vector<Eigen::Vector3f>& normals,
                     std::vector<float>& curvature, std::vector<Eigen::Vector3f>* projected = nullptr,
                     const std::vector<Eigen::Vector3f>* near = nullptr);

/// For the points listed in `which` only: `projected[i]` = point i moved onto the
/// least-squares plane of itself and its first `max_neighbours` graph neighbours (the
/// nearest, graph rows being sorted), as estimateNormals' `projected` with a
/// narrower neighbourhood. Other entries are left as they are. `projected` must have
/// one entry per point.
void projectOntoLocalPlanes(const std::vector<Eigen::Vector3f>& points, const KnnGraph& graph, int max_neighbours,
                            const std::vector<int>& which, std::vector<Eigen::Vector3f>& projected);

}  // namespace mobmap::perception
