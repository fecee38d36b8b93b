#include "mobmap/mapping/gravity.hpp"

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace mobmap::mapping {

Eigen::Matrix3d gravityAlignment(const Eigen::Vector3d& gravity_down_world) {
  const double norm = gravity_down_world.norm();
  if (!gravity_down_world.allFinite() || norm < 1e-9) {
    std::ostringstream msg;
    msg << "gravityAlignment: gravity vector (" << gravity_down_world.transpose()
        << ") must be finite and non-zero";
    throw std::invalid_argument(msg.str());
  }
  // FromTwoVectors picks the minimal rotation and handles the antiparallel case.
  return Eigen::Quaterniond::FromTwoVectors(gravity_down_world / norm, Eigen::Vector3d(0, 0, -1))
      .toRotationMatrix();
}

std::optional<DownConsensus> consensusDown(const std::vector<DownObservation>& observations, double max_angle_deg) {
  std::vector<DownObservation> valid;
  double total = 0.0;
  for (const DownObservation& o : observations) {
    const double n = o.down.stableNorm();
    if (!o.down.allFinite() || !(n > 0.0) || !std::isfinite(n) || !(o.weight > 0.0) || !std::isfinite(o.weight)) continue;
    valid.push_back({o.down / n, o.weight});
    total += o.weight;
  }
  if (valid.empty()) return std::nullopt;
  const double cos_max = std::cos(max_angle_deg * M_PI / 180.0);
  std::size_t best = 0;
  double best_weight = -1.0;
  for (std::size_t i = 0; i < valid.size(); ++i) {
    double w = 0.0;
    for (const DownObservation& o : valid) {
      if (o.down.dot(valid[i].down) >= cos_max) w += o.weight;
    }
    if (w > best_weight) best_weight = w, best = i;
  }
  DownConsensus c;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const DownObservation& o : valid) {
    if (o.down.dot(valid[best].down) < cos_max) continue;
    sum += o.weight * o.down;
    ++c.agreeing;
  }
  c.down = sum.normalized();  // members lie within a small cap: the sum is far from zero
  c.weight_share = best_weight / total;
  for (const DownObservation& o : valid) {
    if (o.down.dot(valid[best].down) < cos_max) continue;
    c.spread_deg = std::max(c.spread_deg, std::acos(std::clamp(o.down.dot(c.down), -1.0, 1.0)) * 180.0 / M_PI);
  }
  return c;
}

std::optional<std::string> checkRigid(const Eigen::Matrix4d& transform,
                                      const RigidTolerance& tolerance) {
  if (!transform.allFinite()) return std::string("matrix contains NaN or infinity");
  const Eigen::RowVector4d bottom = transform.row(3) - Eigen::RowVector4d(0, 0, 0, 1);
  if (bottom.cwiseAbs().maxCoeff() > tolerance.bottom_row) {
    std::ostringstream msg;
    msg << "bottom row is (" << transform.row(3) << "), not (0 0 0 1)";
    return msg.str();
  }
  const Eigen::Matrix3d r = transform.topLeftCorner<3, 3>();
  const double ortho = (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (ortho > tolerance.orthonormality) {
    std::ostringstream msg;
    msg << "rotation is not orthonormal (max |R^T R - I| entry " << ortho << ")";
    return msg.str();
  }
  if (r.determinant() < 0.0) return std::string("rotation is a reflection (det R < 0)");
  if (transform.topRightCorner<3, 1>().cwiseAbs().maxCoeff() > kMaxWorldCoordinateM) {
    std::ostringstream msg;
    msg << "translation (" << transform.topRightCorner<3, 1>().transpose() << ") lies farther than " << kMaxWorldCoordinateM
        << " m from the origin: not metres";
    return msg.str();
  }
  return std::nullopt;
}

Eigen::Matrix3d nearestRotation(const Eigen::Matrix3d& m) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  return svd.matrixU() * d * svd.matrixV().transpose();
}

}  // namespace mobmap::mapping
