// Undistorter against a depth image distorted by the plumb_bob model itself: each
// undistorted pixel gets back the depth seen along its own ray, to within the nearest
// pixel's step.
#include "undistort.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace mobmap::sources {
namespace {

TEST(Undistorter, UndoesPlumbBobToTheNearestPixel) {
  const perception::PinholeIntrinsics k{160, 120, 150.0, 150.0, 79.5, 59.5};
  const std::vector<double> d = {-0.25, 0.08, 0.002, -0.001, -0.01};
  // The true (undistorted) depth: a plane seen at a slant, in metres.
  auto truth = [](double u, double v) { return 1.0 + 0.004 * u + 0.002 * v; };
  // The recorded image: pixel (ud, vd) sees the ray of the undistorted point that the
  // lens moves there, found by inverting the model (fixed-point iteration).
  perception::DepthImage recorded(k.width, k.height);
  for (int vd = 0; vd < k.height; ++vd) {
    for (int ud = 0; ud < k.width; ++ud) {
      const double xd = (ud - k.cx) / k.fx, yd = (vd - k.cy) / k.fy;
      double x = xd, y = yd;
      for (int it = 0; it < 50; ++it) {
        const double r2 = x * x + y * y;
        const double radial = 1.0 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
        const double dx = 2.0 * d[2] * x * y + d[3] * (r2 + 2.0 * x * x);
        const double dy = d[2] * (r2 + 2.0 * y * y) + 2.0 * d[3] * x * y;
        x = (xd - dx) / radial;
        y = (yd - dy) / radial;
      }
      recorded.at(ud, vd) = static_cast<float>(truth(k.fx * x + k.cx, k.fy * y + k.cy));
    }
  }
  const perception::DepthImage out = Undistorter(k, d).apply(recorded);
  int filled = 0;
  double worst = 0.0;
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      if (out.at(u, v) == 0.f) continue;
      ++filled;
      worst = std::max(worst, std::abs(out.at(u, v) - truth(u, v)));
    }
  }
  // Nearest pixel: at most about a pixel's step of the plane (0.004 + 0.002 per pixel).
  EXPECT_LT(worst, 0.0065);
  EXPECT_GT(filled, k.width * k.height * 9 / 10);  // barrel distortion leaves only the corners empty
  // Without distortion it is the identity.
  const perception::DepthImage same = Undistorter(k, {0, 0, 0, 0, 0}).apply(recorded);
  EXPECT_EQ(same.depth_m, recorded.depth_m);
}

}  // namespace
}  // namespace mobmap::sources
