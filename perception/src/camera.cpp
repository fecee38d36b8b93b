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

}  // namespace mobmap::perception
