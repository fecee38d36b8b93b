#include "mobmap/mapping/trajectory.hpp"

#include <mrpt/core/Clock.h>
#include <mrpt/math/CMatrixFixed.h>
#include <mrpt/poses/CPose3D.h>
#include <mrpt/poses/CPose3DInterpolator.h>

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace mobmap::mapping {

struct Trajectory::Impl {
  mrpt::poses::CPose3DInterpolator path;
  std::size_t n = 0;
  double first = 0, last = 0;
};

Trajectory::Trajectory() : impl_(std::make_unique<Impl>()) {
  impl_->path.setInterpolationMethod(mrpt::poses::imLinearSlerp);
}
Trajectory::~Trajectory() = default;
Trajectory::Trajectory(Trajectory&&) noexcept = default;
Trajectory& Trajectory::operator=(Trajectory&&) noexcept = default;

void Trajectory::insert(double t, const Eigen::Isometry3d& T) {
  if (!std::isfinite(t) || !T.matrix().allFinite()) {
    throw std::invalid_argument("Trajectory::insert: time and pose must be finite");
  }
  mrpt::math::CMatrixDouble44 m;
  m.asEigen() = T.matrix();
  impl_->path.insert(mrpt::Clock::fromDouble(t), mrpt::poses::CPose3D(m));
  if (impl_->n == 0) impl_->first = impl_->last = t;
  impl_->first = std::min(impl_->first, t);
  impl_->last = std::max(impl_->last, t);
  ++impl_->n;
}

std::size_t Trajectory::size() const { return impl_->n; }

std::optional<Eigen::Isometry3d> Trajectory::at(double t, double max_gap) const {
  if (impl_->n == 0 || !std::isfinite(t) || t < impl_->first || t > impl_->last) return std::nullopt;
  // Both neighbours within max_gap (MRPT checks the span between them against it).
  const auto& path = impl_->path;
  const auto tp = mrpt::Clock::fromDouble(t);
  auto after = path.lower_bound(tp);
  if (after == path.end()) return std::nullopt;
  if (after->first == tp) {
    mrpt::poses::CPose3D exact(after->second);
    Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
    out.matrix() = exact.getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>().asEigen();
    return out;
  }
  if (after == path.begin()) return std::nullopt;
  auto before = std::prev(after);
  const double gap_after = mrpt::Clock::toDouble(after->first) - t;
  const double gap_before = t - mrpt::Clock::toDouble(before->first);
  if (gap_after > max_gap || gap_before > max_gap) return std::nullopt;
  mrpt::poses::CPose3D pose;
  bool valid = false;
  path.interpolate(tp, pose, valid);
  if (!valid) return std::nullopt;
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.matrix() = pose.getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>().asEigen();
  return out;
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
