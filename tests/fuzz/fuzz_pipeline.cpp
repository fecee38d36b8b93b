// libFuzzer target: the per-frame pipeline on arbitrary small clouds. Bytes become
// points (three int16 per point, millimetres, so coincident, collinear, coplanar and
// scattered clouds all occur) plus a flags byte: with or without a gravity vector, and
// as an organized cloud or not. The pipeline must return a result whose every number
// is finite and in range, or throw std::invalid_argument; never crash or hang.
#include "mobmap/perception/pipeline.hpp"

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <vector>

namespace {

void require(bool ok) {
  if (!ok) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::uint8_t flags = data[0];
  std::vector<Eigen::Vector3f> points;
  for (std::size_t i = 1; i + 6 <= size && points.size() < 2048; i += 6) {
    std::int16_t v[3];
    std::memcpy(v, data + i, sizeof v);
    Eigen::Vector3f p(v[0] * 1e-3f, v[1] * 1e-3f, v[2] * 1e-3f);
    if ((flags & 4) && v[0] == -32768) p.x() = std::numeric_limits<float>::quiet_NaN();  // missing pixels
    points.push_back(p);
  }
  static const mobmap::perception::FramePipeline pipeline = [] {
    mobmap::perception::PerceptionParams p;
    p.ground_min_points = 20;  // small clouds may still have a "floor"
    p.min_segment_points = 5;
    return mobmap::perception::FramePipeline(p);
  }();
  std::optional<Eigen::Vector3f> gravity;
  if (flags & 1) gravity = Eigen::Vector3f(0, 1, 0);
  try {
    mobmap::perception::FrameResult r;
    if ((flags & 2) && points.size() >= 4) {
      const int w = 2 + (flags >> 4) % 8;
      const int h = static_cast<int>(points.size()) / w;
      points.resize(static_cast<std::size_t>(w * h));
      r = pipeline.processOrganized(points, w, h, gravity);
      require(r.point_of_pixel.size() == points.size());
    } else {
      r = pipeline.process(points, gravity);
    }
    require(r.normals.size() == r.points.size() && r.segment_of_point.size() == r.points.size());
    for (const auto& p : r.points) require(p.allFinite());
    for (const auto& s : r.segments) {
      require(std::isfinite(s.slope_deg) && s.slope_deg >= 0 && s.slope_deg <= 180.0 + 1e-9);
      require(std::isfinite(s.roughness) && s.roughness >= 1.0 - 1e-6);
      require(std::isfinite(s.mobility) && s.mobility >= 0 && s.mobility <= 1);
      require(std::isfinite(s.variance) && s.variance >= 0);
      require(s.normal.allFinite() && s.centroid.allFinite());
      for (int i : s.points) require(i >= 0 && static_cast<std::size_t>(i) < r.points.size());
    }
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
