#pragma once
/// @file trajectory.hpp
/// A timestamped camera trajectory with interpolation (MRPT CPose3DInterpolator:
/// linear in position, slerp in rotation).

#include <Eigen/Geometry>

#include <memory>
#include <optional>

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

  /// The pose at `t_seconds`, interpolated between the samples around it; nullopt when
  /// t lies outside the trajectory or either neighbouring sample is more than
  /// `max_gap_seconds` away.
  [[nodiscard]] std::optional<Eigen::Isometry3d> at(double t_seconds, double max_gap_seconds) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mobmap::mapping
