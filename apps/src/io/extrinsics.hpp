#pragma once
// `--extrinsics`: the camera's pose in the frame a sequence's poses are given for (a
// robot's base from odometry, a motion-capture body), so that each frame's camera pose is
// T_world_base * T_base_camera.

#include "io/sequence.hpp"

#include <Eigen/Geometry>

#include <memory>
#include <string>

namespace mobmap::app {

/// Parses "x,y,z,qx,qy,qz,qw" (metres; a unit quaternion, within 1e-3) or a YAML file
/// holding one of: rtabmap's `local_transform` (an OpenCV matrix of 3x4 or 4x4 values);
/// `translation` (x, y, z) with `rotation` (x, y, z, w) at its top or under
/// `T_base_camera` / `extrinsics`; or `data` of 12 or 16 row-major values. The
/// rotation must be proper. UsageError (numbers) or IoError (a file) naming the problem.
Eigen::Isometry3d parseExtrinsics(const std::string& spec);

/// The seven numbers "x,y,z,qx,qy,qz,qw" of `T`, as MAP.json records them.
std::string extrinsicsText(const Eigen::Isometry3d& T);

/// `seq` with every pose (load() and pose()) followed by `T_base_camera`.
std::unique_ptr<Sequence> withExtrinsics(std::unique_ptr<Sequence> seq, const Eigen::Isometry3d& T_base_camera);

}  // namespace mobmap::app
