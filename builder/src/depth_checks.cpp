#include "mobmap/builder/depth_checks.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

namespace mobmap::builder {

std::optional<LowZeroBits> lowZeroBits(const perception::DepthImage& depth, const DepthUnit& unit) {
  if (unit.cloud || unit.units_per_m < 2.0) return std::nullopt;
  std::size_t valid = 0;
  std::array<std::size_t, 5> zero{};  // zero[k]: values whose k low bits are all zero
  for (std::size_t i = 0; i < depth.depth_m.size(); i += 7) {  // a sample is enough to see the pattern
    const float d = depth.depth_m[i];
    if (!(d > 0.f) || !std::isfinite(d)) continue;
    const long v = std::lround(static_cast<double>(d) * unit.units_per_m);
    if (v <= 0 || v > 65535) return std::nullopt;  // not 16-bit values
    ++valid;
    for (int k = 1; k <= 4; ++k) zero[static_cast<std::size_t>(k)] += (v & ((1L << k) - 1)) == 0;
  }
  if (valid < 1000) return std::nullopt;
  for (int k = 4; k >= 2; --k) {
    const double share = static_cast<double>(zero[static_cast<std::size_t>(k)]) / static_cast<double>(valid);
    if (share >= 0.9) return LowZeroBits{k, share};
  }
  return std::nullopt;
}

std::optional<std::string> depthUnitProblem(const perception::RangeReport& r, const DepthUnit& unit,
                                            const std::optional<LowZeroBits>& bits) {
  constexpr std::size_t kMinValid = 100;  // fewer: nothing to judge by
  if (r.valid_points < kMinValid) return std::nullopt;
  const double median = r.median_range_m;
  if (median >= kPlausibleMedianMin && median <= kPlausibleMedianMax) return std::nullopt;
  char text[400];
  std::snprintf(text, sizeof text,
                "the depth looks like it is in another unit: read at %g units per metre, the median depth is %.3g m "
                "(depth cameras see about 0.3 to 10 m), and %.2f %% of the points lie within the range",
                unit.units_per_m, median,
                100.0 * static_cast<double>(r.valid_points - r.beyond_max_range - r.nearer_than_min_range) /
                    static_cast<double>(r.valid_points));
  std::string out = text;
  const double raw_median = median * unit.units_per_m;
  if (bits) {
    // The stored values say more than their median: 2^bits times the unit reads them.
    const double scale = unit.units_per_m * static_cast<double>(1 << bits->bits);
    std::snprintf(text, sizeof text,
                  "; %.1f %% of its values are multiples of %d (their %d low bits are zero): `depth_scale` %g puts the "
                  "median at %.2f m",
                  100.0 * bits->share, 1 << bits->bits, bits->bits, scale, raw_median / scale);
    out += text;
    if (bits->bits == 3 && unit.units_per_m == 1000.0) {
      out += ", and `depth_format` sunrgbd decodes SUN RGB-D's depth PNGs, which store millimetres rotated left by 3 "
             "bits (the same reading for depth under 8.19 m)";
    }
    return out;
  }
  // Every common unit that puts the median where depth cameras usually have it, the
  // nearest to 2 m first: the median alone cannot always tell 5000 from 10000.
  std::vector<std::pair<double, double>> fits;  // (distance from 2 m in log scale, units per metre)
  for (const double candidate : {1000.0, 5000.0, 10000.0, 100.0, 1.0}) {
    const double m = raw_median / candidate;
    if (candidate == unit.units_per_m || m < 0.4 || m > 8.0) continue;
    fits.emplace_back(std::abs(std::log(m / 2.0)), candidate);
  }
  std::sort(fits.begin(), fits.end());
  if (fits.empty()) return out + "; no common unit (`depth_scale` 1000, 5000, 10000, 100 or 1) puts it between 0.4 and 8 m";
  for (std::size_t i = 0; i < fits.size(); ++i) {
    const double candidate = fits[i].second;
    std::snprintf(text, sizeof text, "%s%g (%s) puts the median at %.2f m", i == 0 ? "; `depth_scale` " : ", ", candidate,
                  candidate == 1000.0   ? "millimetres"
                  : candidate == 5000.0 ? "TUM's unit"
                  : candidate == 10000.0 ? "tenths of a millimetre"
                  : candidate == 100.0  ? "centimetres"
                                        : "metres",
                  raw_median / candidate);
    out += text;
  }
  return out;
}

double rangeToSuggest(double range_m) { return std::ceil(range_m * 2.0 - 1e-9) / 2.0; }

std::optional<std::string> rangeCutProblem(const perception::RangeReport& r) {
  if (r.valid_points == 0 || r.shareBeyond() <= 0.5) return std::nullopt;
  char text[300];
  std::snprintf(text, sizeof text,
                "%.0f %% of the frame's points lie beyond `max_range_m` %g m and were left out (median range %.2f m); "
                "`max_range_m` %g keeps 95 %% of them",
                100.0 * r.shareBeyond(), r.max_range_m, r.median_range_m, rangeToSuggest(r.range_p95_m));
  return std::string(text);
}

std::optional<std::string> floorCutProblem(const perception::RangeReport& r, std::optional<double> ground_distance_m) {
  if (!r.lowest || r.lowest->share_beyond <= 0.5) return std::nullopt;
  const auto& low = *r.lowest;
  if (low.below_camera_m < 0.3) return std::nullopt;  // the lowest points are not below the camera: no floor in view
  if (ground_distance_m && *ground_distance_m > low.below_camera_m - 0.15) return std::nullopt;  // that is the ground found
  char text[400];
  std::snprintf(text, sizeof text,
                "the lowest surface in view, likely the floor, lies %.2f m below the camera (along %s) and %.0f %% of it "
                "beyond `max_range_m` %g m, so it was left out; `max_range_m` %g keeps it",
                low.below_camera_m,
                r.down_from_gravity ? "gravity" : r.down_from_ground ? "the ground's normal" : "the camera's +y axis", 100.0 * low.share_beyond,
                r.max_range_m, rangeToSuggest(low.range_p95_m));
  std::string out = text;
  if (ground_distance_m) {
    char g[120];
    std::snprintf(g, sizeof g, " (the ground taken instead lies %.2f m below the camera)", *ground_distance_m);
    out += g;
  }
  return out;
}

std::vector<std::string> DepthCheckTally::add(const std::string& label, const perception::RangeReport& r,
                                              std::optional<double> ground_distance_m, const DepthUnit& unit,
                                              const std::optional<LowZeroBits>& bits) {
  ++frames_;
  valid_ += r.valid_points;
  beyond_ += r.beyond_max_range;
  max_range_m_ = r.max_range_m;
  std::vector<std::string> out;
  if (const auto unit_problem = depthUnitProblem(r, unit, bits)) {
    if (unit_frames_++ == 0) {
      out.push_back("warning: " + label + ": " + *unit_problem);
      unit_problem_ = *unit_problem;
    }
    return out;  // the range is not the problem then
  }
  if (const auto cut = rangeCutProblem(r)) {
    if (cut_frames_++ == 0) out.push_back("note: " + label + ": " + *cut);
    cut_suggest_m_ = std::max(cut_suggest_m_, rangeToSuggest(r.range_p95_m));
  }
  if (const auto floor = floorCutProblem(r, ground_distance_m)) {
    if (floor_frames_++ == 0) out.push_back("note: " + label + ": " + *floor);
    floor_suggest_m_ = std::max(floor_suggest_m_, rangeToSuggest(r.lowest->range_p95_m));
  }
  return out;
}

std::vector<std::string> DepthCheckTally::summary() const {
  std::vector<std::string> out;
  if (frames_ == 0) return out;
  char text[300];
  std::snprintf(text, sizeof text, "range: %.1f %% of the %zu valid points lay beyond `max_range_m` %g m",
                valid_ ? 100.0 * static_cast<double>(beyond_) / static_cast<double>(valid_) : 0.0, valid_, max_range_m_);
  out.emplace_back(text);
  if (unit_frames_ > 0) {
    std::snprintf(text, sizeof text, "warning: in %d of %zu frames the depth read implausibly for a depth camera (`depth_scale`)",
                  unit_frames_, frames_);
    out.emplace_back(text);
  }
  // A frame now and then that sees past the range is normal in a sequence (other frames
  // see the same floor nearer): a warning when it is a quarter of them or more.
  const auto level = [&](int n) { return 4 * static_cast<std::size_t>(n) >= frames_ ? "warning" : "note"; };
  if (cut_frames_ > 0) {
    std::snprintf(text, sizeof text,
                  "%s: in %d of %zu frames most points lay beyond `max_range_m` %g m; `max_range_m` %g keeps 95 %% of "
                  "them in every such frame",
                  level(cut_frames_), cut_frames_, frames_, max_range_m_, cut_suggest_m_);
    out.emplace_back(text);
  }
  if (floor_frames_ > 0) {
    std::snprintf(text, sizeof text,
                  "%s: in %d of %zu frames the lowest surface in view (likely the floor) lay beyond `max_range_m` %g m; "
                  "`max_range_m` %g keeps it",
                  level(floor_frames_), floor_frames_, frames_, max_range_m_, floor_suggest_m_);
    out.emplace_back(text);
  }
  return out;
}

}  // namespace mobmap::builder
