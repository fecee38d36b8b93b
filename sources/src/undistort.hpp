#pragma once
// plumb_bob distortion undone for depth images.

#include "mobmap/perception/camera.hpp"

#include <vector>

namespace mobmap::sources {

// Undoes plumb_bob distortion: each pixel of the undistorted image takes the depth of
// the nearest pixel of the distorted one (depth is not interpolated across edges).
class Undistorter {
 public:
  /// `d`: k1, k2, p1, p2[, k3] (at least four).
  Undistorter(const perception::PinholeIntrinsics& k, const std::vector<double>& d);
  [[nodiscard]] perception::DepthImage apply(const perception::DepthImage& in) const;

 private:
  int width_, height_;
  std::vector<int> source_;  // for each undistorted pixel, the recorded pixel it takes (-1: none)
};

}  // namespace mobmap::sources
