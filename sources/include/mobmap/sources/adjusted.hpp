#pragma once
// Sequences read with a correction: depth in another unit than the input's own
// (`depth_scale`: withDepthScale) and the camera mounted on the body whose poses are
// given (`extrinsics`: withExtrinsics). `mobmap build` and mobmap::builder apply them.

#include "mobmap/sources/frame.hpp"
#include "mobmap/sources/sequence.hpp"

#include <Eigen/Geometry>

#include <memory>
#include <string>
#include <vector>

namespace mobmap::sources {

/// `depth_scale`: the factor that takes depth (or cloud coordinates) read at
/// `from.units_per_m` to a reading at `units_per_m`. util::FieldError (`depth_scale`) unless `units_per_m` is
/// positive and finite.
float depthRescaleFactor(const DepthUnit& from, double units_per_m);

/// Multiplies depth values and cloud points by `factor` (depthRescaleFactor).
void scaleDepth(std::vector<float>& depth_m, std::vector<Eigen::Vector3f>& points, float factor);

/// `f`'s depth (or cloud coordinates, and the camera offset of a cloud in another frame)
/// multiplied by `factor`: read at `units_per_m` instead (depthRescaleFactor gives the
/// factor).
void scaleFrame(Frame& f, float factor, double units_per_m);

/// `seq` with its depth read at `units_per_m` instead of its own unit (depth and cloud
/// coordinates multiplied by own / units_per_m; poses unchanged). `seq` itself when the
/// two agree. util::FieldError (`depth_scale`) unless `units_per_m` is positive and finite.
std::unique_ptr<Sequence> withDepthScale(std::unique_ptr<Sequence> seq, double units_per_m);

/// Reads `f`'s depth (or cloud coordinates) at `units_per_m` instead of the unit it was
/// read in. util::FieldError (`depth_scale`) unless positive and finite.
void rescaleDepth(Frame& f, double units_per_m);

/// Parses "x,y,z,qx,qy,qz,qw" (metres; a unit quaternion, within 1e-3) or a YAML file
/// holding one of: rtabmap's `local_transform` (an OpenCV matrix of 3x4 or 4x4 values);
/// `translation` (x, y, z) with `rotation` (x, y, z, w) at its top or under
/// `T_base_camera` / `extrinsics`; or `data` of 12 or 16 row-major values. The
/// rotation must be proper. util::FieldError (`extrinsics`: numbers) or IoError (a file) naming the problem.
Eigen::Isometry3d parseExtrinsics(const std::string& spec);

/// The seven numbers "x,y,z,qx,qy,qz,qw" of `T`, as MAP.json records them.
std::string extrinsicsText(const Eigen::Isometry3d& T);

/// `seq` with every pose (load() and pose()) followed by `T_base_camera`.
std::unique_ptr<Sequence> withExtrinsics(std::unique_ptr<Sequence> seq, const Eigen::Isometry3d& T_base_camera);

}  // namespace mobmap::sources
