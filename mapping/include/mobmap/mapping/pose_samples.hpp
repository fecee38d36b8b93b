#pragma once
/// @file pose_samples.hpp
/// The one way mobmap finds a pose between timestamped samples: a TUM trajectory's
/// (Trajectory), a TF link's (sources::TfTree) and a sensor trajectory's all go through
/// poseAt(). Between two samples the position is interpolated linearly and the rotation
/// by slerp; the two may be at most a given span apart in time (`max_pose_gap_s`): a
/// frame stamped in a longer gap has no pose.

#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace mobmap::mapping {

/// A pose at a time stamp: nanoseconds (a ROS stamp, or seconds times 1e9, rounded).
struct PoseSample {
  std::int64_t stamp_ns = 0;
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();  ///< unit
};

/// The pose at `stamp_ns` from `samples` sorted by stamp: the sample at that stamp, else
/// interpolated between the last sample before and the first after it, when those are at
/// most `max_gap_ns` apart. nullopt otherwise, and then `why` (when given) says why:
/// "has no sample before the stamp", "... after the stamp", or "has samples around the
/// stamp 0.2 s apart".
[[nodiscard]] std::optional<Eigen::Isometry3d> poseAt(const std::vector<PoseSample>& samples, std::int64_t stamp_ns,
                                                      std::int64_t max_gap_ns, std::string* why = nullptr);

/// Seconds as a stamp in nanoseconds, rounded; std::invalid_argument unless finite and
/// within +-9e9 s (what 64-bit nanoseconds hold).
[[nodiscard]] std::int64_t stampNs(double seconds);

}  // namespace mobmap::mapping
