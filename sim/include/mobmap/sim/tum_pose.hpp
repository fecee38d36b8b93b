#pragma once
// Writing trajectories in the TUM RGB-D format, for tests and the test OpenNI2 driver.

#include <Eigen/Geometry>

#include <ostream>

namespace mobmap::sim {

/// Writes "t tx ty tz qx qy qz qw" (camera to world, 9 decimals) and a newline.
void writeTumPoseLine(std::ostream& out, double t_seconds, const Eigen::Isometry3d& T_world_camera);

}  // namespace mobmap::sim
