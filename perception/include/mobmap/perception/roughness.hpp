#pragma once
/// @file roughness.hpp
/// Paper step 7, surface properties: roughness as the ratio of a segment's Delaunay
/// surface area to its projected area (eqs. 8-10). The slope is FramePipeline's.

#include "mobmap/perception/triangulator.hpp"

#include <Eigen/Core>

#include <array>
#include <utility>
#include <vector>

namespace mobmap::perception {

/// 2D Delaunay triangulation of `points`: index triples, counter-clockwise, in no
/// particular order. Duplicate points are triangulated once; collinear points give none;
/// points with a non-finite coordinate are left out.
std::vector<std::array<int, 3>> delaunayTriangles(const std::vector<Eigen::Vector2d>& points,
                                                  Triangulator which = Triangulator::kOwn);

/// Roughness r = A / A' (paper eqs. 8-10) of a segment: 2D Delaunay triangulation of the
/// points projected on `plane`; A sums the triangles' 3D areas, A' the areas of the same
/// triangles in the plane. Triangles with an edge longer than `max_edge_m` (in 3D)
/// bridge gaps and are skipped. Returns {r, A}; r = 1 and A = 0 when fewer than 3 points
/// or no triangle remain (collinear, degenerate).
std::pair<double, double> delaunayRoughness(const std::vector<Eigen::Vector3f>& points,
                                            const std::vector<int>& indices, const Eigen::Vector4f& plane,
                                            double max_edge_m, Triangulator which = Triangulator::kOwn);

}  // namespace mobmap::perception
