#pragma once
/// @file reduction.hpp
/// Paper step 1, data reduction: the voxel grid. (The range crop is FramePipeline's.)

#include <Eigen/Core>

#include <vector>

namespace mobmap::perception {

/// Voxel-grid reduction: the centroid of the points in each occupied cubic voxel of
/// `voxel_m` (grid aligned to the origin), in order of first occurrence.
/// `voxel_of_point` (optional) receives the output index of each input point.
/// A centroid is the mean of its points summed in input order in double precision.
std::vector<Eigen::Vector3f> voxelReduce(const std::vector<Eigen::Vector3f>& points, float voxel_m,
                                         std::vector<int>* voxel_of_point = nullptr);

}  // namespace mobmap::perception
