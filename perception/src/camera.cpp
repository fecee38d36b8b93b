#include "mobmap/perception/camera.hpp"

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

}  // namespace mobmap::perception
