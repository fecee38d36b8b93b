#include "mobmap/perception/camera.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

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

std::vector<bool> unmeasuredPoints(const std::vector<Eigen::Vector3f>& organized) {
  std::vector<bool> out(organized.size(), false);
  // A value at two pixels is no measurement: two rays meet only at the camera.
  struct Key {
    std::uint32_t x, y, z;
    bool operator==(const Key& o) const { return x == o.x && y == o.y && z == o.z; }
  };
  struct Hash {
    std::size_t operator()(const Key& k) const {
      return (static_cast<std::size_t>(k.x) * 0x9E3779B97F4A7C15ull) ^ (static_cast<std::size_t>(k.y) * 0xC2B2AE3D27D4EB4Full) ^ k.z;
    }
  };
  std::unordered_map<Key, std::size_t, Hash> first;  // value -> the first pixel that has it
  first.reserve(organized.size() / 4);
  for (std::size_t i = 0; i < organized.size(); ++i) {
    const Eigen::Vector3f& q = organized[i];
    if (!q.allFinite() || !(q.squaredNorm() > 0.f)) {
      out[i] = true;
      continue;
    }
    Key key{};
    std::memcpy(&key.x, &q.x(), 4);
    std::memcpy(&key.y, &q.y(), 4);
    std::memcpy(&key.z, &q.z(), 4);
    const auto [it, fresh] = first.emplace(key, i);
    if (!fresh) out[i] = out[it->second] = true;
  }
  return out;
}

namespace {

using Projection = Eigen::Matrix<double, 3, 4>;

// Points and their pixels.
struct Correspondences {
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> x;
};

// The projective camera of the points `use` of c by the normalised direct linear
// transform (Hartley), signed so that most of those points lie in front of it.
std::optional<Projection> directLinearTransform(const Correspondences& c, const std::vector<std::size_t>& use) {
  const double n = static_cast<double>(use.size());
  Eigen::Vector3d cX = Eigen::Vector3d::Zero();
  Eigen::Vector2d cx = Eigen::Vector2d::Zero();
  for (const std::size_t i : use) cX += c.X[i], cx += c.x[i];
  cX /= n;
  cx /= n;
  double dX = 0, dx = 0;
  for (const std::size_t i : use) dX += (c.X[i] - cX).norm(), dx += (c.x[i] - cx).norm();
  dX /= n;
  dx /= n;
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
  for (const std::size_t i : use) {
    const Eigen::Vector4d Xn = TX * c.X[i].homogeneous();
    const Eigen::Vector3d xn = Tx * c.x[i].homogeneous();
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
  Projection Pn;
  Pn << sol.segment<4>(0).transpose(), sol.segment<4>(4).transpose(), sol.segment<4>(8).transpose();
  Projection P = Tx.inverse() * Pn * TX;
  std::size_t in_front = 0;
  for (const std::size_t i : use) in_front += P.row(2).dot(c.X[i].homogeneous()) > 0;
  if (2 * in_front < use.size()) P = -P;
  return P;
}

// Squared reprojection error of point i in pixels; infinite behind the camera.
double squaredError(const Projection& P, const Correspondences& c, std::size_t i) {
  const Eigen::Vector3d uvw = P * c.X[i].homogeneous();
  if (!(uvw.z() > 0)) return std::numeric_limits<double>::infinity();
  return (uvw.head<2>() / uvw.z() - c.x[i]).squaredNorm();
}

std::vector<std::size_t> inliersOf(const Projection& P, const Correspondences& c, double max_px) {
  std::vector<std::size_t> in;
  for (std::size_t i = 0; i < c.X.size(); ++i) {
    if (squaredError(P, c, i) <= max_px * max_px) in.push_back(i);
  }
  return in;
}

// P = K [R | t] split into intrinsics and the camera's pose (RQ decomposition).
std::optional<OrganizedCameraFit> splitCamera(const Projection& P, int width, int height) {
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
  K /= K(2, 2);
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
  return fit;
}

}  // namespace

std::optional<OrganizedCameraFit> fitOrganizedCamera(const std::vector<Eigen::Vector3f>& organized, int width, int height) {
  if (width <= 0 || height <= 0 || organized.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height)) {
    throw std::invalid_argument("fitOrganizedCamera: the cloud is not width x height");
  }
  const std::vector<bool> unmeasured = unmeasuredPoints(organized);
  const auto valid = static_cast<std::size_t>(std::count(unmeasured.begin(), unmeasured.end(), false));
  if (valid < 100) return std::nullopt;
  // A grid sample of the measured pixels (every k-th row and column, ~20000 at most).
  const int stride = std::max(1, static_cast<int>(std::sqrt(static_cast<double>(valid) / 20000.0)));
  Correspondences c;
  for (int v = 0; v < height; v += stride) {
    for (int u = 0; u < width; u += stride) {
      const std::size_t i = static_cast<std::size_t>(v) * static_cast<std::size_t>(width) + static_cast<std::size_t>(u);
      if (unmeasured[i]) continue;
      c.X.push_back(organized[i].cast<double>());
      c.x.emplace_back(u, v);
    }
  }
  if (c.X.size() < 100) return std::nullopt;
  std::vector<std::size_t> all(c.X.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = i;
  std::optional<Projection> P = directLinearTransform(c, all);
  std::vector<std::size_t> inliers = P ? inliersOf(*P, c, kCameraInlierPx) : std::vector<std::size_t>{};
  if (inliers.size() < all.size()) {
    // Points off their rays (a driver's placeholders, pixels from elsewhere): RANSAC over
    // 8-point samples, each hypothesis scored on a fixed subset of 500 points, then
    // refitted on the inliers it finds among all.
    std::mt19937 rng(20260);  // the same answer every time
    std::uniform_int_distribution<std::size_t> pick(0, all.size() - 1);
    std::vector<std::size_t> probe(std::min<std::size_t>(500, all.size()));
    for (std::size_t& i : probe) i = pick(rng);
    std::size_t best = 0;
    if (P) {
      for (const std::size_t i : probe) best += squaredError(*P, c, i) <= kCameraInlierPx * kCameraInlierPx;
    }
    std::optional<Projection> best_P = P;
    constexpr int kMaxTries = 2000;
    int needed = kMaxTries;
    for (int trial = 0; trial < needed; ++trial) {
      std::vector<std::size_t> sample(8);
      for (std::size_t& i : sample) i = pick(rng);
      const auto H = directLinearTransform(c, sample);
      if (!H) continue;
      std::size_t hits = 0;
      for (const std::size_t i : probe) hits += squaredError(*H, c, i) <= kCameraInlierPx * kCameraInlierPx;
      if (hits <= best) continue;
      best = hits;
      best_P = H;
      // Enough trials that an all-inlier sample came up with 99.9 % probability.
      const double all_in = std::pow(static_cast<double>(hits) / static_cast<double>(probe.size()), 8.0);
      if (all_in >= 1.0) break;
      const double trials = std::log(1e-3) / std::log1p(-all_in);  // +inf when all_in is tiny
      if (trials < kMaxTries) needed = std::max(trial + 1, static_cast<int>(std::ceil(trials)));
    }
    if (!best_P) return std::nullopt;
    P = best_P;
    inliers = inliersOf(*P, c, kCameraInlierPx);
    for (int round = 0; round < 3 && inliers.size() >= 8; ++round) {  // refit on the inliers until they settle
      const auto refit = directLinearTransform(c, inliers);
      if (!refit) break;
      std::vector<std::size_t> again = inliersOf(*refit, c, kCameraInlierPx);
      if (again.size() < inliers.size()) break;
      const bool settled = again == inliers;
      P = refit;
      inliers = std::move(again);
      if (settled) break;
    }
  }
  if (!P || inliers.size() < 8) return std::nullopt;
  auto fit = splitCamera(*P, width, height);
  if (!fit) return std::nullopt;
  double sse = 0;
  for (const std::size_t i : inliers) sse += squaredError(*P, c, i);
  fit->rms_px = std::sqrt(sse / static_cast<double>(inliers.size()));
  fit->points = c.X.size();
  fit->inlier_share = static_cast<double>(inliers.size()) / static_cast<double>(c.X.size());
  fit->unmeasured = organized.size() - valid;
  return fit;
}

}  // namespace mobmap::perception
