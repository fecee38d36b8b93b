#include "mobmap/perception/camera.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace mobmap::perception {

void validate(const PinholeIntrinsics& k) {
  constexpr int kMaxSide = 16384;
  auto fail = [](const char* field, double value, const char* rule) {
    std::ostringstream msg;
    msg << "PinholeIntrinsics: " << field << " is " << value << " (" << rule << ")";
    throw std::invalid_argument(msg.str());
  };
  if (k.width <= 0 || k.width > kMaxSide) fail("width", k.width, "must be 1..16384");
  if (k.height <= 0 || k.height > kMaxSide) fail("height", k.height, "must be 1..16384");
  if (!std::isfinite(k.fx) || k.fx <= 0) fail("fx", k.fx, "must be finite and > 0");
  if (!std::isfinite(k.fy) || k.fy <= 0) fail("fy", k.fy, "must be finite and > 0");
  if (!std::isfinite(k.cx)) fail("cx", k.cx, "must be finite");
  if (!std::isfinite(k.cy)) fail("cy", k.cy, "must be finite");
}

std::vector<Eigen::Vector3d> depthToPoints(const DepthImage& depth, const PinholeIntrinsics& k) {
  if (depth.width != k.width || depth.height != k.height) {
    std::ostringstream msg;
    msg << "depthToPoints: depth image is " << depth.width << "x" << depth.height
        << " but the intrinsics are for " << k.width << "x" << k.height;
    throw std::invalid_argument(msg.str());
  }
  std::vector<Eigen::Vector3d> points;
  points.reserve(depth.depth_m.size());
  for (int v = 0; v < depth.height; ++v) {
    for (int u = 0; u < depth.width; ++u) {
      const float z = depth.at(u, v);
      if (z > 0.f && std::isfinite(z)) points.push_back(backProject(k, u, v, z));
    }
  }
  return points;
}

std::optional<PinholeIntrinsics> fitIntrinsics(const std::vector<Eigen::Vector3f>& organized, int width, int height,
                                               double* rms_px) {
  if (width <= 0 || height <= 0 || organized.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height)) {
    throw std::invalid_argument("fitIntrinsics: the cloud is not width x height");
  }
  // Two independent 1-D regressions, pixel coordinate on normalised coordinate.
  struct Line {
    double n = 0, sa = 0, sb = 0, saa = 0, sab = 0, sbb = 0;
    void add(double a, double b) { n += 1, sa += a, sb += b, saa += a * a, sab += a * b, sbb += b * b; }
    // b = f a + c
    [[nodiscard]] std::pair<double, double> fit() const {
      const double det = n * saa - sa * sa;
      if (!(std::abs(det) > 1e-12)) return {0.0, 0.0};
      const double f = (n * sab - sa * sb) / det;
      return {f, (sb - f * sa) / n};
    }
    [[nodiscard]] double sse(double f, double c) const {
      return sbb - 2 * f * sab - 2 * c * sb + f * f * saa + 2 * f * c * sa + c * c * n;
    }
  } lu, lv;
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const Eigen::Vector3f& p = organized[static_cast<std::size_t>(v) * static_cast<std::size_t>(width) + static_cast<std::size_t>(u)];
      if (!p.allFinite() || !(p.z() > 0.f)) continue;
      lu.add(static_cast<double>(p.x()) / p.z(), u);
      lv.add(static_cast<double>(p.y()) / p.z(), v);
    }
  }
  if (lu.n < 100) return std::nullopt;
  const auto [fx, cx] = lu.fit();
  const auto [fy, cy] = lv.fit();
  if (!(fx > 0) || !(fy > 0) || !std::isfinite(cx) || !std::isfinite(cy)) return std::nullopt;
  if (rms_px) *rms_px = std::sqrt(std::max(0.0, (lu.sse(fx, cx) + lv.sse(fy, cy)) / (2 * lu.n)));
  PinholeIntrinsics k;
  k.width = width;
  k.height = height;
  k.fx = fx, k.fy = fy, k.cx = cx, k.cy = cy;
  return k;
}

std::optional<OrganizedCameraFit> fitOrganizedCamera(const std::vector<Eigen::Vector3f>& organized, int width, int height) {
  if (width <= 0 || height <= 0 || organized.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height)) {
    throw std::invalid_argument("fitOrganizedCamera: the cloud is not width x height");
  }
  // A grid sample of the valid pixels (every k-th row and column, ~20000 at most).
  std::size_t valid = 0;
  for (const Eigen::Vector3f& q : organized) valid += q.allFinite() && q.squaredNorm() > 0.f;
  if (valid < 100) return std::nullopt;
  const int stride = std::max(1, static_cast<int>(std::sqrt(static_cast<double>(valid) / 20000.0)));
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> x;
  for (int v = 0; v < height; v += stride) {
    for (int u = 0; u < width; u += stride) {
      const Eigen::Vector3f& q = organized[static_cast<std::size_t>(v) * static_cast<std::size_t>(width) + static_cast<std::size_t>(u)];
      if (!q.allFinite() || !(q.squaredNorm() > 0.f)) continue;
      X.push_back(q.cast<double>());
      x.emplace_back(u, v);
    }
  }
  if (X.size() < 100) return std::nullopt;
  // Hartley's normalisation: both sets centred, at mean distance sqrt(3) and sqrt(2).
  Eigen::Vector3d cX = Eigen::Vector3d::Zero();
  Eigen::Vector2d cx = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < X.size(); ++i) cX += X[i], cx += x[i];
  cX /= static_cast<double>(X.size());
  cx /= static_cast<double>(x.size());
  double dX = 0, dx = 0;
  for (std::size_t i = 0; i < X.size(); ++i) dX += (X[i] - cX).norm(), dx += (x[i] - cx).norm();
  dX /= static_cast<double>(X.size());
  dx /= static_cast<double>(x.size());
  if (!(dX > 1e-12) || !(dx > 1e-12)) return std::nullopt;
  const double sX = std::sqrt(3.0) / dX, sx = std::sqrt(2.0) / dx;
  Eigen::Matrix4d TX = Eigen::Matrix4d::Identity();
  TX.topLeftCorner<3, 3>() *= sX;
  TX.topRightCorner<3, 1>() = -sX * cX;
  Eigen::Matrix3d Tx = Eigen::Matrix3d::Identity();
  Tx.topLeftCorner<2, 2>() *= sx;
  Tx.topRightCorner<2, 1>() = -sx * cx;
  // A^T A of the DLT system, two rows per point: [0, -X, v X] and [X, 0, -u X].
  Eigen::Matrix<double, 12, 12> AtA = Eigen::Matrix<double, 12, 12>::Zero();
  for (std::size_t i = 0; i < X.size(); ++i) {
    const Eigen::Vector4d Xn = TX * X[i].homogeneous();
    const Eigen::Vector3d xn = Tx * x[i].homogeneous();
    Eigen::Matrix<double, 12, 1> r1 = Eigen::Matrix<double, 12, 1>::Zero(), r2 = Eigen::Matrix<double, 12, 1>::Zero();
    r1.segment<4>(4) = -Xn;
    r1.segment<4>(8) = xn.y() * Xn;
    r2.segment<4>(0) = Xn;
    r2.segment<4>(8) = -xn.x() * Xn;
    AtA.selfadjointView<Eigen::Lower>().rankUpdate(r1);
    AtA.selfadjointView<Eigen::Lower>().rankUpdate(r2);
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> eig(AtA.selfadjointView<Eigen::Lower>());
  if (eig.info() != Eigen::Success) return std::nullopt;
  // A second solution almost as good: the points do not pin the camera down.
  if (!(eig.eigenvalues()(1) > 1e-9 * std::max(1.0, eig.eigenvalues()(11)))) return std::nullopt;
  const Eigen::Matrix<double, 12, 1> sol = eig.eigenvectors().col(0);
  Eigen::Matrix<double, 3, 4> Pn;
  Pn << sol.segment<4>(0).transpose(), sol.segment<4>(4).transpose(), sol.segment<4>(8).transpose();
  Eigen::Matrix<double, 3, 4> P = Tx.inverse() * Pn * TX;
  // The points lie in front of the camera: the third row gives their depths' sign.
  std::size_t in_front = 0;
  for (const Eigen::Vector3d& q : X) in_front += P.row(2).dot(q.homogeneous()) > 0;
  if (2 * in_front < X.size()) P = -P;
  const Eigen::Matrix3d M = P.leftCols<3>();
  if (!(std::abs(M.determinant()) > 0)) return std::nullopt;
  // RQ decomposition M = K R (K upper triangular, positive diagonal; R orthonormal),
  // from the QR decomposition of M reversed and transposed.
  Eigen::Matrix3d flip = Eigen::Matrix3d::Zero();
  flip(0, 2) = flip(1, 1) = flip(2, 0) = 1.0;
  const Eigen::HouseholderQR<Eigen::Matrix3d> qr((flip * M).transpose());
  Eigen::Matrix3d Q = qr.householderQ();
  Eigen::Matrix3d Rt = qr.matrixQR().triangularView<Eigen::Upper>();
  Eigen::Matrix3d K = flip * Rt.transpose() * flip;
  Eigen::Matrix3d R = flip * Q.transpose();
  for (int i = 0; i < 3; ++i) {  // make K's diagonal positive
    if (K(i, i) < 0) {
      K.col(i) *= -1.0;
      R.row(i) *= -1.0;
    }
  }
  if (R.determinant() < 0) return std::nullopt;  // a mirrored cloud is no camera's
  const Eigen::Vector3d t = K.triangularView<Eigen::Upper>().solve(P.col(3));
  const double scale = K(2, 2);
  K /= scale;
  OrganizedCameraFit fit;
  fit.intrinsics = PinholeIntrinsics{width, height, K(0, 0), K(1, 1), K(0, 2), K(1, 2)};
  if (!(fit.intrinsics.fx > 0) || !(fit.intrinsics.fy > 0) || !std::isfinite(fit.intrinsics.cx) || !std::isfinite(fit.intrinsics.cy)) {
    return std::nullopt;
  }
  fit.skew = K(0, 1) / K(0, 0);
  // The camera frame: p = R q + t (t solved against K before its scale was divided out,
  // as M = K R was).
  Eigen::Isometry3d T_camera_cloud = Eigen::Isometry3d::Identity();
  T_camera_cloud.linear() = R;
  T_camera_cloud.translation() = t;
  fit.T_cloud_camera = T_camera_cloud.inverse();
  double sse = 0;
  for (std::size_t i = 0; i < X.size(); ++i) {
    const Eigen::Vector3d uvw = P * X[i].homogeneous();
    sse += (uvw.head<2>() / uvw.z() - x[i]).squaredNorm();
  }
  fit.rms_px = std::sqrt(sse / static_cast<double>(X.size()));
  fit.points = X.size();
  return fit;
}

}  // namespace mobmap::perception
