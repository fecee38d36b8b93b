#include "mobmap/mapping/trajectory.hpp"

#include "mobmap/mapping/pose_samples.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace mobmap::mapping {

struct Trajectory::Impl {
  std::vector<PoseSample> samples;  // by stamp; equal stamps in the order inserted
};

Trajectory::Trajectory() : impl_(std::make_unique<Impl>()) {}
Trajectory::~Trajectory() = default;
Trajectory::Trajectory(Trajectory&&) noexcept = default;
Trajectory& Trajectory::operator=(Trajectory&&) noexcept = default;

void Trajectory::insert(double t, const Eigen::Isometry3d& T) {
  if (!std::isfinite(t) || !T.matrix().allFinite()) {
    throw std::invalid_argument("Trajectory::insert: time and pose must be finite");
  }
  const PoseSample sample{stampNs(t), T.translation(), Eigen::Quaterniond(T.linear()).normalized()};
  auto& v = impl_->samples;
  // In order (a trajectory file's usual case) it is appended; else put in its place.
  const auto at = std::upper_bound(v.begin(), v.end(), sample.stamp_ns,
                                   [](std::int64_t stamp, const PoseSample& s) { return stamp < s.stamp_ns; });
  v.insert(at, sample);
}

std::size_t Trajectory::size() const { return impl_->samples.size(); }

std::optional<Eigen::Isometry3d> Trajectory::at(double t, double max_gap) const {
  if (!(std::abs(t) <= 9e9) || !(max_gap >= 0)) return std::nullopt;
  return poseAt(impl_->samples, stampNs(t), stampNs(std::min(max_gap, 9e9)));
}

std::vector<std::size_t> selectKeyframes(const std::vector<Eigen::Isometry3d>& poses, double min_translation_m,
                                         double min_rotation_deg) {
  const auto check = [](double v, const char* what) {
    if (!std::isfinite(v) || v < 0) {
      std::ostringstream msg;
      msg << "keyframes: " << what << " must be >= 0, got " << v;
      throw std::invalid_argument(msg.str());
    }
  };
  check(min_translation_m, "the minimum translation (m)");
  check(min_rotation_deg, "the minimum rotation (degrees)");
  if (min_translation_m == 0 && min_rotation_deg == 0) {
    throw std::invalid_argument("keyframes: at least one of the minimum translation and rotation must be > 0");
  }
  std::vector<std::size_t> keep;
  if (poses.empty()) return keep;
  keep.push_back(0);
  const double min_rotation_rad = min_rotation_deg * M_PI / 180.0;
  for (std::size_t i = 1; i < poses.size(); ++i) {
    const Eigen::Isometry3d& last = poses[keep.back()];
    const bool moved = min_translation_m > 0 && (poses[i].translation() - last.translation()).norm() >= min_translation_m;
    // Angle of R_last^T R_i (through a quaternion: accurate for small angles too).
    const double angle = Eigen::AngleAxisd(last.linear().transpose() * poses[i].linear()).angle();
    const bool turned = min_rotation_deg > 0 && angle >= min_rotation_rad;
    if (moved || turned) keep.push_back(i);
  }
  return keep;
}

}  // namespace mobmap::mapping
