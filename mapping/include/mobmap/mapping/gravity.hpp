#pragma once
/// @file gravity.hpp
/// Gravity alignment of a data set's world frame and validation of rigid poses.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <optional>
#include <string>

namespace mobmap::mapping {

/// Rotation R_map_world that maps the data's world frame into the gravity-aligned
/// map frame (z up): R_map_world * gravity_down_world = (0, 0, -1). Among all such
/// rotations it is the smallest one (axis perpendicular to both vectors), so a world
/// frame that is already z-up gives the identity. `gravity_down_world` need not be
/// unit length. Throws std::invalid_argument if it is zero or not finite.
Eigen::Matrix3d gravityAlignment(const Eigen::Vector3d& gravity_down_world);

/// Tolerances of checkRigid().
struct RigidTolerance {
  double orthonormality = 1e-3;  ///< max |R^T R - I| entry (poses are often printed with 6-7 digits)
  double bottom_row = 1e-6;      ///< max |row 3 - (0,0,0,1)| entry
};

/// Checks that a 4x4 matrix is a rigid transform: finite, R^T R = I, det R = +1,
/// bottom row (0,0,0,1). Returns nullopt when it is, otherwise the reason in words
/// ("rotation is not orthonormal (max error 0.2)"), for the caller to put next to the
/// file name and line.
[[nodiscard]] std::optional<std::string> checkRigid(const Eigen::Matrix4d& transform,
                                                    const RigidTolerance& tolerance = {});

/// The nearest proper rotation to `m` (SVD projection), to clean up the rounding in
/// printed poses after checkRigid() accepted them.
Eigen::Matrix3d nearestRotation(const Eigen::Matrix3d& m);

}  // namespace mobmap::mapping
