#include "undistort.hpp"

#include <cmath>

namespace mobmap::sources {

Undistorter::Undistorter(const perception::PinholeIntrinsics& k, const std::vector<double>& d) : width_(k.width), height_(k.height) {
  const double k1 = d[0], k2 = d[1], p1 = d[2], p2 = d[3], k3 = d.size() > 4 ? d[4] : 0.0;
  source_.resize(static_cast<std::size_t>(k.width) * k.height, -1);
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      // The ray of undistorted pixel (u, v), distorted as the lens does, lands here.
      const double x = (u - k.cx) / k.fx, y = (v - k.cy) / k.fy;
      const double r2 = x * x + y * y;
      const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
      const double xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
      const double yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
      const long us = std::lround(k.fx * xd + k.cx), vs = std::lround(k.fy * yd + k.cy);
      if (us >= 0 && vs >= 0 && us < k.width && vs < k.height) {
        source_[static_cast<std::size_t>(v) * k.width + u] = static_cast<int>(vs * k.width + us);
      }
    }
  }
}

perception::DepthImage Undistorter::apply(const perception::DepthImage& in) const {
  perception::DepthImage out(width_, height_);
  for (std::size_t i = 0; i < source_.size(); ++i) {
    if (source_[i] >= 0) out.depth_m[i] = in.depth_m[static_cast<std::size_t>(source_[i])];
  }
  return out;
}

}  // namespace mobmap::sources
