#pragma once
/// @file trajectory.hpp
/// A timestamped camera trajectory, interpolated as every pose in mobmap is
/// (pose_samples.hpp: linear in position, slerp in rotation).

#include <Eigen/Geometry>

#include <cstddef>
#include <memory>
#include <optional>
#include <vector>

namespace mobmap::mapping {

/// Camera-to-world poses at timestamps (seconds). Not thread-safe for insert();
/// const lookups may run concurrently.
class Trajectory {
 public:
  Trajectory();
  ~Trajectory();
  Trajectory(Trajectory&&) noexcept;
  Trajectory& operator=(Trajectory&&) noexcept;

  /// Adds a pose. Throws std::invalid_argument for a non-finite time or pose.
  void insert(double t_seconds, const Eigen::Isometry3d& T_world_camera);
  [[nodiscard]] std::size_t size() const;

  /// The pose at `t_seconds`: the sample at that time, else interpolated between the
  /// samples around it (poseAt); nullopt when t lies outside the trajectory or those two
  /// samples are more than `max_gap_seconds` apart. Times are kept to the nanosecond.
  [[nodiscard]] std::optional<Eigen::Isometry3d> at(double t_seconds, double max_gap_seconds) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Keyframes of a camera path (camera-to-world poses in order): the first pose, then
/// each pose whose camera has moved at least `min_translation_m` or turned at least
/// `min_rotation_deg` (angle of the relative rotation) since the last keyframe. A limit
/// of 0 is not used. Returns ascending indices into `poses`. std::invalid_argument for
/// a negative or non-finite limit, or for both limits 0.
std::vector<std::size_t> selectKeyframes(const std::vector<Eigen::Isometry3d>& poses, double min_translation_m,
                                         double min_rotation_deg);

}  // namespace mobmap::mapping
