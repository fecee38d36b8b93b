#pragma once
// The plane a sole rests on: least squares z = h + ga a + gb b through the top faces of the
// voxels under it, in sole coordinates (a along its heading, b across, from its centre).
// Shared by MobilityMap::footprint() and evaluateFoothold().

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

namespace mobmap::mapping::detail {

/// One supported sample: sole coordinates and the top face it rests on.
struct SupportSample {
  double a, b, top;
};

struct SupportPlane {
  Eigen::Vector3d mean;       ///< of the samples' (a, b, top)
  Eigen::Vector2d gradient;   ///< dz/da, dz/db
  [[nodiscard]] double at(double a, double b) const {
    return mean.z() + gradient.x() * (a - mean.x()) + gradient.y() * (b - mean.y());
  }
  [[nodiscard]] double tiltDeg() const { return std::atan(gradient.norm()) * 180.0 / M_PI; }
};

/// nullopt with fewer than 3 samples or samples on one line (a sole one voxel wide),
/// which leave the plane undetermined.
inline std::optional<SupportPlane> fitSupportPlane(const std::vector<SupportSample>& support) {
  if (support.size() < 3) return std::nullopt;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : support) mean += Eigen::Vector3d(p.a, p.b, p.top);
  mean /= static_cast<double>(support.size());
  Eigen::Matrix2d ab = Eigen::Matrix2d::Zero();
  Eigen::Vector2d abz = Eigen::Vector2d::Zero();
  for (const auto& p : support) {
    const Eigen::Vector2d d(p.a - mean.x(), p.b - mean.y());
    ab += d * d.transpose();
    abz += d * (p.top - mean.z());
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(ab, Eigen::EigenvaluesOnly);
  if (eig.eigenvalues()(0) <= 1e-9 * std::max(1e-12, eig.eigenvalues()(1))) return std::nullopt;
  return SupportPlane{mean, ab.ldlt().solve(abz)};
}

}  // namespace mobmap::mapping::detail
