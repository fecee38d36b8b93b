#pragma once
/// @file gravity.hpp
/// Gravity alignment of a data set's world frame and validation of rigid poses.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <optional>
#include <string>
#include <vector>

namespace mobmap::mapping {

/// Rotation R_map_world that maps the data's world frame into the gravity-aligned
/// map frame (z up): R_map_world * gravity_down_world = (0, 0, -1). Among all such
/// rotations it is the smallest one (axis perpendicular to both vectors), so a world
/// frame that is already z-up gives the identity. `gravity_down_world` need not be
/// unit length. Throws std::invalid_argument if it is zero or not finite.
Eigen::Matrix3d gravityAlignment(const Eigen::Vector3d& gravity_down_world);

/// One frame's evidence of "down" in the world frame (the normal of a floor it saw),
/// with a weight (the floor's inlier count, say).
struct DownObservation {
  Eigen::Vector3d down = Eigen::Vector3d::Zero();
  double weight = 1.0;
};

/// The agreement of several DownObservations.
struct DownConsensus {
  Eigen::Vector3d down = Eigen::Vector3d::Zero();  ///< unit: weighted mean of the agreeing ones
  int agreeing = 0;          ///< observations within the angle of the winning one
  double weight_share = 0;   ///< their share of the total weight, in (0, 1]
  double spread_deg = 0;     ///< largest angle between an agreeing observation and `down`
};

/// Finds the direction most of the weight agrees on: each observation in turn gathers
/// those within `max_angle_deg` of it, the heaviest group wins (ties: the first), and
/// its weighted mean is the answer. Observations that are zero, not finite or of
/// non-positive weight are ignored; nullopt if none is left. A wall seen as "the
/// floor" in a few frames cannot outvote the floor of the others.
[[nodiscard]] std::optional<DownConsensus> consensusDown(const std::vector<DownObservation>& observations,
                                                         double max_angle_deg = 5.0);

/// The farthest a pose or a map origin may lie from its world frame's origin, metres:
/// twice round the Earth, so any geographic frame (UTM, ECEF) fits, while a pose in the
/// wrong unit or a corrupt number (1e15 m, where a double no longer resolves a decimetre)
/// is refused instead of mapped wrongly.
inline constexpr double kMaxWorldCoordinateM = 1e8;

/// Tolerances of checkRigid().
struct RigidTolerance {
  double orthonormality = 1e-3;  ///< max |R^T R - I| entry (poses are often printed with 6-7 digits)
  double bottom_row = 1e-6;      ///< max |row 3 - (0,0,0,1)| entry
};

/// Checks that a 4x4 matrix is a rigid transform in metres: finite, R^T R = I, det R = +1,
/// bottom row (0,0,0,1), translation within kMaxWorldCoordinateM. Returns nullopt when it is, otherwise the reason in words
/// ("rotation is not orthonormal (max error 0.2)"), for the caller to put next to the
/// file name and line.
[[nodiscard]] std::optional<std::string> checkRigid(const Eigen::Matrix4d& transform,
                                                    const RigidTolerance& tolerance = {});

/// The nearest proper rotation to `m` (SVD projection), to clean up the rounding in
/// printed poses after checkRigid() accepted them.
Eigen::Matrix3d nearestRotation(const Eigen::Matrix3d& m);

}  // namespace mobmap::mapping
