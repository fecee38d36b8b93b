#include "mobmap/mapping/footholds.hpp"

#include "mobmap/mapping/foot.hpp"
#include "param_error.hpp"
#include "support_plane.hpp"


#include <algorithm>
#include <iterator>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <stdexcept>

namespace mobmap::mapping {
namespace {

constexpr double kPi = 3.14159265358979323846;
/// Above the swing clearance, how far up something between two soles still meets the
/// leg (unless clearance_m asks for more): a table top 0.7 m above the floor does not.
constexpr double kLegBand = 0.5;
constexpr std::size_t kMaxColumns = std::size_t{1} << 26;

}  // namespace

void validate(const RobotParams& p) {
  const auto positive = [](double v) { return v > 0 && std::isfinite(v); };
  const auto nonNegative = [](double v) { return v >= 0 && std::isfinite(v); };
  if (!(positive(p.sole_length_m) && p.sole_length_m <= 2)) detail::failParam("RobotParams", "sole_length_m", p.sole_length_m, "must be in (0, 2]");
  if (!(positive(p.sole_width_m) && p.sole_width_m <= 2)) detail::failParam("RobotParams", "sole_width_m", p.sole_width_m, "must be in (0, 2]");
  if (!(p.min_mobility >= 0 && p.min_mobility <= 1)) detail::failParam("RobotParams", "min_mobility", p.min_mobility, "must be in [0, 1]");
  if (!(p.max_poor_fraction >= 0 && p.max_poor_fraction < 1)) detail::failParam("RobotParams", "max_poor_fraction", p.max_poor_fraction, "must be in [0, 1)");
  if (!(p.min_support_fraction > 0 && p.min_support_fraction <= 1)) detail::failParam("RobotParams", "min_support_fraction", p.min_support_fraction, "must be in (0, 1]");
  if (!(p.max_tilt_deg >= 0 && p.max_tilt_deg < 80)) detail::failParam("RobotParams", "max_tilt_deg", p.max_tilt_deg, "must be in [0, 80)");
  if (!(nonNegative(p.max_unevenness_m) && p.max_unevenness_m <= 1)) detail::failParam("RobotParams", "max_unevenness_m", p.max_unevenness_m, "must be in [0, 1]");
  if (!(nonNegative(p.clearance_m) && p.clearance_m <= 10)) detail::failParam("RobotParams", "clearance_m", p.clearance_m, "must be in [0, 10]");
  if (!(nonNegative(p.max_step_m) && p.max_step_m <= 2)) detail::failParam("RobotParams", "max_step_m", p.max_step_m, "must be in [0, 2]");
  if (!(positive(p.max_stride_m) && p.max_stride_m <= 3)) detail::failParam("RobotParams", "max_stride_m", p.max_stride_m, "must be in (0, 3]");
  if (!(nonNegative(p.swing_clearance_m) && p.swing_clearance_m <= 2)) detail::failParam("RobotParams", "swing_clearance_m", p.swing_clearance_m, "must be in [0, 2]");
  if (!(nonNegative(p.max_gap_m) && p.max_gap_m <= 3)) detail::failParam("RobotParams", "max_gap_m", p.max_gap_m, "must be in [0, 3]");
  if (!(nonNegative(p.stance_width_m) && p.stance_width_m <= 2)) detail::failParam("RobotParams", "stance_width_m", p.stance_width_m, "must be in [0, 2]");
  if (!(positive(p.lattice_m) && p.lattice_m <= 1)) detail::failParam("RobotParams", "lattice_m", p.lattice_m, "must be in (0, 1]");
}

namespace {
// RobotParams' fields and their names, in declaration order.
struct RobotField {
  const char* name;
  double RobotParams::*field;
};
constexpr RobotField kRobotFields[] = {
    {"sole_length_m", &RobotParams::sole_length_m},
    {"sole_width_m", &RobotParams::sole_width_m},
    {"min_mobility", &RobotParams::min_mobility},
    {"max_poor_fraction", &RobotParams::max_poor_fraction},
    {"min_support_fraction", &RobotParams::min_support_fraction},
    {"max_tilt_deg", &RobotParams::max_tilt_deg},
    {"max_unevenness_m", &RobotParams::max_unevenness_m},
    {"clearance_m", &RobotParams::clearance_m},
    {"max_step_m", &RobotParams::max_step_m},
    {"max_stride_m", &RobotParams::max_stride_m},
    {"swing_clearance_m", &RobotParams::swing_clearance_m},
    {"max_gap_m", &RobotParams::max_gap_m},
    {"stance_width_m", &RobotParams::stance_width_m},
    {"lattice_m", &RobotParams::lattice_m},
};
static_assert(sizeof(RobotParams) == std::size(kRobotFields) * sizeof(double), "every field of RobotParams is in kRobotFields");
}  // namespace

bool operator==(const RobotParams& a, const RobotParams& b) {
  for (const RobotField& f : kRobotFields) {
    if (!(a.*f.field == b.*f.field)) return false;
  }
  return true;
}

bool setRobotParameter(RobotParams& params, const std::string& name, double value) {
  for (const RobotField& f : kRobotFields) {
    if (name == f.name) {
      params.*f.field = value;
      return true;
    }
  }
  return false;
}

const std::vector<std::string>& robotParameterNames() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const RobotField& f : kRobotFields) n.emplace_back(f.name);
    return n;
  }();
  return names;
}

double headingYaw(int heading) { return heading * (2 * kPi / kHeadings); }

const char* toString(FootholdProblem p) {
  switch (p) {
    case FootholdProblem::kNone: return "none";
    case FootholdProblem::kNoSurface: return "too little known surface under the sole";
    case FootholdProblem::kTooSteep: return "too steep";
    case FootholdProblem::kUneven: return "too uneven";
    case FootholdProblem::kObstacle: return "something in the way";
    case FootholdProblem::kLowMobility: return "mobility too low";
  }
  return "none";
}

// ---- SurfaceColumns -------------------------------------------------------------

long SurfaceColumns::runBelow(double x, double y, double z_max, double z_min) const {
  const long col = columnIndex(keyOf(x), keyOf(y));
  for (std::size_t r = runEnd(col); r > runBegin(col); --r) {
    const Run& run = runs_[r - 1];
    if (topFace(run) > z_max + 1e-9) continue;
    return topFace(run) >= z_min - 1e-9 ? static_cast<long>(r - 1) : -1;
  }
  return -1;
}

SurfaceColumns::SurfaceColumns(const MobilityOcTree& tree) : res_(tree.getResolution()), inv_res_(1.0 / res_) {
  const unsigned depth = tree.getTreeDepth();
  struct Leaf {
    octomap::OcTreeKey base;
    int span;
    float mobility, variance;
  };
  std::vector<Leaf> leaves;
  long x0 = 1L << 20, y0 = x0, x1 = -1, y1 = -1;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    if (!tree.isNodeOccupied(*it)) continue;
    Leaf l{it.getIndexKey(), 1 << (depth - it.getDepth()),
           it->hasMobility() ? static_cast<float>(it->mobility()) : std::numeric_limits<float>::quiet_NaN(),
           static_cast<float>(it->hasMobility() ? it->variance() : std::numeric_limits<double>::infinity())};
    x0 = std::min<long>(x0, l.base[0]), y0 = std::min<long>(y0, l.base[1]);
    x1 = std::max<long>(x1, l.base[0] + l.span - 1), y1 = std::max<long>(y1, l.base[1] + l.span - 1);
    leaves.push_back(l);
  }
  if (leaves.empty()) {
    offsets_.assign(1, 0);
    return;
  }
  kx0_ = x0, ky0_ = y0, nx_ = x1 - x0 + 1, ny_ = y1 - y0 + 1;
  if (static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_) > kMaxColumns) {
    throw std::length_error("SurfaceColumns: the map's occupied voxels span more than 2^26 columns");
  }
  // Leaves per column (a pruned leaf covers span x span columns), then intervals in CSR.
  std::vector<std::uint32_t> count(static_cast<std::size_t>(nx_ * ny_) + 1, 0);
  std::size_t total = 0;
  for (const Leaf& l : leaves) {
    total += static_cast<std::size_t>(l.span) * static_cast<std::size_t>(l.span);
    if (total > kMaxColumns) throw std::length_error("SurfaceColumns: the map holds more than 2^26 column intervals");
    for (int dx = 0; dx < l.span; ++dx) {
      for (int dy = 0; dy < l.span; ++dy) ++count[static_cast<std::size_t>(columnIndex(l.base[0] + dx, l.base[1] + dy)) + 1];
    }
  }
  for (std::size_t i = 1; i < count.size(); ++i) count[i] += count[i - 1];
  struct Interval {
    int lo, hi;
    float mobility, variance;
  };
  std::vector<Interval> intervals(total);
  std::vector<std::uint32_t> fill(count.begin(), count.end() - 1);
  for (const Leaf& l : leaves) {
    for (int dx = 0; dx < l.span; ++dx) {
      for (int dy = 0; dy < l.span; ++dy) {
        const auto c = static_cast<std::size_t>(columnIndex(l.base[0] + dx, l.base[1] + dy));
        intervals[fill[c]++] = {l.base[2], l.base[2] + l.span - 1, l.mobility, l.variance};
      }
    }
  }
  // Runs of adjacent intervals, lowest first.
  offsets_.assign(count.size(), 0);
  for (std::size_t c = 0; c + 1 < count.size(); ++c) {
    offsets_[c] = static_cast<std::uint32_t>(runs_.size());
    auto* first = intervals.data() + count[c];
    auto* last = intervals.data() + count[c + 1];
    std::sort(first, last, [](const Interval& a, const Interval& b) { return a.lo < b.lo; });
    for (auto* i = first; i < last;) {
      Run run{i->lo, i->hi, i->mobility, i->variance};
      int known_hi = run.hasMobility() ? i->hi : -1;
      bool top_known = run.hasMobility();
      for (++i; i < last && i->lo <= run.top + 1; ++i) {
        const bool known = i->mobility == i->mobility;
        if (i->hi >= run.top) {
          run.top = i->hi;
          top_known = known;
          if (known) run.mobility = i->mobility, run.variance = i->variance, known_hi = i->hi;
        } else if (known && !top_known && i->hi > known_hi) {
          run.mobility = i->mobility, run.variance = i->variance, known_hi = i->hi;
        }
      }
      runs_.push_back(run);
      run_column_.push_back(static_cast<std::uint32_t>(c));
    }
  }
  offsets_.back() = static_cast<std::uint32_t>(runs_.size());
}

// ---- footholds ----------------------------------------------------------------------

Foothold evaluateFoothold(const SurfaceColumns& cols, double x, double y, double yaw, double z_ref, const RobotParams& robot,
                          std::vector<std::size_t>* supports) {
  Foothold f;
  f.x = x, f.y = y, f.yaw = yaw;
  f.geometry = f.problem = FootholdProblem::kNoSurface;
  if (supports) supports->clear();
  const double res = cols.resolution();
  if (!(res > 0) || !std::isfinite(z_ref)) return f;
  thread_local std::vector<SoleSample> samples;
  soleSamples(Foot{x, y, 0, yaw, robot.sole_length_m, robot.sole_width_m}, res, samples);
  f.samples = static_cast<int>(samples.size());
  if (samples.empty()) return f;
  const double tan_tilt = std::tan(robot.max_tilt_deg * kPi / 180);
  const double band = 0.5 * std::hypot(robot.sole_length_m, robot.sole_width_m) * tan_tilt + robot.max_unevenness_m + res;
  thread_local std::vector<detail::SupportSample> sup;
  thread_local std::vector<std::size_t> sup_run;  // the run each supported sample rests on
  thread_local std::vector<long> sample_col;
  sup.clear();
  sup_run.clear();
  sample_col.clear();
  const auto& runs = cols.runs();
  int known = 0, poor = 0;
  double mob_sum = 0, var_sum = 0, mob_min = 1;
  for (const SoleSample& s : samples) {
    const long col = cols.columnIndex(cols.keyOf(s.x), cols.keyOf(s.y));
    sample_col.push_back(col);
    for (std::size_t r = cols.runEnd(col); r > cols.runBegin(col); --r) {
      const auto& run = runs[r - 1];
      const double top = cols.topFace(run);
      if (top > z_ref + band) continue;
      if (top >= z_ref - band) {
        sup.push_back({s.a, s.b, top});
        sup_run.push_back(r - 1);
        if (run.hasMobility()) {
          ++known;
          mob_sum += run.mobility;
          var_sum += std::isfinite(run.variance) ? run.variance : 0.0;
          mob_min = std::min(mob_min, static_cast<double>(run.mobility));
          poor += run.mobility < robot.min_mobility ? 1 : 0;
        }
      }
      break;
    }
  }
  f.support_fraction = static_cast<double>(known) / static_cast<double>(samples.size());
  f.min_mobility = known ? mob_min : 0.0;
  f.mean_mobility = known ? mob_sum / known : 0.0;
  f.mean_variance = known ? var_sum / known : 0.0;
  f.poor_fraction = known ? static_cast<double>(poor) / known : 0.0;
  if (supports) *supports = sup_run;
  const auto plane = detail::fitSupportPlane(sup);
  if (!plane) return f;
  f.has_plane = true;
  f.z = plane->at(0, 0);
  f.tilt_deg = plane->tiltDeg();
  for (const detail::SupportSample& s : sup) f.unevenness_m = std::max(f.unevenness_m, std::abs(s.top - plane->at(s.a, s.b)));
  // Inside the sole's volume: from just above the tops it may rest on up to the swing
  // clearance (or the robot's clearance) above its plane.
  const double above = std::max(robot.clearance_m, robot.swing_clearance_m);
  bool obstacle = false;
  for (std::size_t i = 0; i < samples.size() && !obstacle; ++i) {
    const double pz = plane->at(samples[i].a, samples[i].b);
    for (std::size_t r = cols.runBegin(sample_col[i]); r < cols.runEnd(sample_col[i]); ++r) {
      if (cols.topFace(runs[r]) > pz + robot.max_unevenness_m + 1e-9 && cols.bottomFace(runs[r]) < pz + above) {
        obstacle = true;
        break;
      }
    }
  }
  if (f.support_fraction + 1e-12 < robot.min_support_fraction) {
    f.geometry = FootholdProblem::kNoSurface;
  } else if (f.tilt_deg > robot.max_tilt_deg) {
    f.geometry = FootholdProblem::kTooSteep;
  } else if (f.unevenness_m > robot.max_unevenness_m + 1e-9) {
    f.geometry = FootholdProblem::kUneven;
  } else if (obstacle) {
    f.geometry = FootholdProblem::kObstacle;
  } else {
    f.geometry = FootholdProblem::kNone;
  }
  f.problem = f.geometry != FootholdProblem::kNone ? f.geometry
              : f.poor_fraction > robot.max_poor_fraction + 1e-12 ? FootholdProblem::kLowMobility
                                                    : FootholdProblem::kNone;
  return f;
}

std::string formatLimit(double value) {
  char buf[64];
  if (std::isfinite(value) && std::abs(value) < 1e15) {
    for (int decimals = 0; decimals <= 17; ++decimals) {
      std::snprintf(buf, sizeof buf, "%.*f", decimals, value);
      if (std::strtod(buf, nullptr) == value) return buf;
    }
  }
  std::snprintf(buf, sizeof buf, "%.17g", value);
  return buf;
}

double swingLegTop(const RobotParams& robot) { return std::max(robot.clearance_m, robot.swing_clearance_m + kLegBand); }

bool stepHeightOk(double za, double zb, const RobotParams& robot, double resolution) {
  return std::abs(za - zb) + resolution <= robot.max_step_m + 1e-9;
}

bool canStep(const SurfaceColumns& cols, double xa, double ya, double za, double xb, double yb, double zb,
             const RobotParams& robot) {
  return std::hypot(xb - xa, yb - ya) <= robot.max_stride_m + 1e-9 && stepHeightOk(za, zb, robot, cols.resolution()) &&
         swingProblem(cols, xa, ya, za, xb, yb, zb, robot) == FootholdProblem::kNone;
}

FootholdProblem swingProblem(const SurfaceColumns& cols, double xa, double ya, double za, double xb, double yb, double zb,
                             const RobotParams& robot) {
  const double res = cols.resolution();
  const double hi = std::max(za, zb), lo = std::min(za, zb);
  const double blocked_above = hi + robot.swing_clearance_m;
  const double leg_top = hi + swingLegTop(robot);
  const double dx = xb - xa, dy = yb - ya, len = std::hypot(dx, dy);
  const double step = res / 2;
  const int n = std::max(1, static_cast<int>(std::ceil(len / step)));
  // Across the swing: the sole's centre line and lines near its two sides.
  const double ox = len > 0 ? -dy / len : 0.0, oy = len > 0 ? dx / len : 0.0;
  const double side = 0.45 * robot.sole_width_m;
  const auto& runs = cols.runs();
  double gap = 0, longest = 0;
  for (const double off : {0.0, -side, side}) {
    long last = -2;
    bool surface = false;
    gap = 0;
    for (int i = 0; i <= n; ++i) {
      const double t = static_cast<double>(i) / n;
      const long col = cols.columnIndex(cols.keyOf(xa + t * dx + off * ox), cols.keyOf(ya + t * dy + off * oy));
      if (col != last) {
        last = col;
        surface = false;
        for (std::size_t r = cols.runBegin(col); r < cols.runEnd(col); ++r) {
          const double top = cols.topFace(runs[r]), bottom = cols.bottomFace(runs[r]);
          if (top > blocked_above + 1e-9 && bottom < leg_top) return FootholdProblem::kObstacle;
          if (top >= lo - robot.max_step_m - res && top <= blocked_above + 1e-9) surface = true;
        }
      }
      if (off != 0.0) continue;
      gap = surface ? 0.0 : gap + len / n;
      longest = std::max(longest, gap);
    }
  }
  return longest > robot.max_gap_m + 1e-9 ? FootholdProblem::kNoSurface : FootholdProblem::kNone;
}

}  // namespace mobmap::mapping
