#include "mobmap/mapping/pose_samples.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace mobmap::mapping {

std::optional<Eigen::Isometry3d> poseAt(const std::vector<PoseSample>& samples, std::int64_t stamp_ns, std::int64_t max_gap_ns,
                                        std::string* why) {
  const auto pose = [](const Eigen::Vector3d& t, const Eigen::Quaterniond& q) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = q.toRotationMatrix();
    T.translation() = t;
    return T;
  };
  const auto after = std::lower_bound(samples.begin(), samples.end(), stamp_ns,
                                      [](const PoseSample& s, std::int64_t stamp) { return s.stamp_ns < stamp; });
  if (after != samples.end() && after->stamp_ns == stamp_ns) return pose(after->t, after->q);
  if (after == samples.begin() || after == samples.end()) {
    if (why) *why = std::string("has no sample ") + (after == samples.begin() ? "before" : "after") + " the stamp";
    return std::nullopt;
  }
  const PoseSample& a = *(after - 1);
  const PoseSample& b = *after;
  if (b.stamp_ns - a.stamp_ns > max_gap_ns) {
    if (why) {
      char text[64];
      std::snprintf(text, sizeof text, "%.3f", static_cast<double>(b.stamp_ns - a.stamp_ns) * 1e-9);
      *why = std::string("has samples around the stamp ") + text + " s apart";
    }
    return std::nullopt;
  }
  const double w = static_cast<double>(stamp_ns - a.stamp_ns) / static_cast<double>(b.stamp_ns - a.stamp_ns);
  return pose((1.0 - w) * a.t + w * b.t, a.q.slerp(w, b.q));
}

std::int64_t stampNs(double seconds) {
  if (!(std::abs(seconds) <= 9e9)) throw std::invalid_argument("a time stamp must be finite and within +-9e9 s");
  return static_cast<std::int64_t>(std::llround(seconds * 1e9));
}

}  // namespace mobmap::mapping
