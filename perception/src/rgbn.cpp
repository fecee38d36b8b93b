// Paper step 4: RGB-N colours (eq. 5) and the YCrCb conversion region growing compares them in.

#include "mobmap/perception/rgbn.hpp"

#include <algorithm>
#include <cmath>

namespace mobmap::perception {

namespace {

// std::lround(x) cast to 8 bits for x in [0, 255] (and NaN), inline: the library call
// was ~0.4 % of a `mobmap build`. x - trunc(x) is exact there; checked equal to lround
// on every float from 0 to 255.
inline std::uint8_t roundColour(float x) {
  if (!(x >= 0.f)) return 0;  // NaN: lround's LONG_MIN, whose low byte is 0
  const int t = static_cast<int>(x);
  return static_cast<std::uint8_t>(t + (x - static_cast<float>(t) >= 0.5f));
}

}  // namespace

std::vector<std::array<std::uint8_t, 3>> normalColours(const std::vector<Eigen::Vector3f>& normals) {
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  Eigen::Vector3f hi = -lo;
  for (const auto& nrm : normals) {
    if (nrm.isZero()) continue;
    lo = lo.cwiseMin(nrm);
    hi = hi.cwiseMax(nrm);
  }
  std::vector<std::array<std::uint8_t, 3>> out(normals.size(), {0, 0, 0});
  for (std::size_t i = 0; i < normals.size(); ++i) {
    if (normals[i].isZero()) continue;
    for (int c = 0; c < 3; ++c) {
      const float range = hi(c) - lo(c);
      const float t = range > 1e-6f ? (normals[i](c) - lo(c)) / range : 0.5f;  // eq. 5
      out[i][static_cast<std::size_t>(c)] = roundColour(255.f * std::clamp(t, 0.f, 1.f));
    }
  }
  return out;
}

Eigen::Vector3f rgbToYCrCb(const std::array<std::uint8_t, 3>& rgb) {
  const float r = rgb[0], g = rgb[1], b = rgb[2];
  const float y = 0.299f * r + 0.587f * g + 0.114f * b;
  return {y, 128.f + 0.713f * (r - y), 128.f + 0.564f * (b - y)};
}

}  // namespace mobmap::perception
