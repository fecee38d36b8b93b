#include "mobmap/mapping/gravity.hpp"

#include <Eigen/SVD>

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
  return std::nullopt;
}

Eigen::Matrix3d nearestRotation(const Eigen::Matrix3d& m) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  return svd.matrixU() * d * svd.matrixV().transpose();
}

}  // namespace mobmap::mapping
