#include "mobmap/mapping/reachability.hpp"

#include "param_error.hpp"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace mobmap::mapping {
namespace {

/// A start sole's support may lie this far above the start point (a point given on the
/// floor may be a voxel low).
constexpr double kStartSlack = 0.1;

long floorDiv(long a, long b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

}  // namespace

void validate(const ReachParams& p) {
  validate(p.robot);
  if (!(p.start_radius_m >= 0 && p.start_radius_m <= 100)) detail::failParam("ReachParams", "start_radius_m", p.start_radius_m, "must be in [0, 100]");
}

const Place* Reachability::placeBelow(const Eigen::Vector3d& p, double max_drop_m) const {
  if (!columns_ || !p.allFinite() || !(max_drop_m >= 0) || !std::isfinite(max_drop_m)) return nullptr;
  const double res = columns_->resolution();
  // At or below the voxel holding p: its top face may be up to a voxel above p.z.
  const double voxel_top = columns_->centreOf(columns_->keyOf(p.z())) + res / 2;
  const long r = columns_->runBelow(p.x(), p.y(), voxel_top, p.z() - max_drop_m);
  return r < 0 ? nullptr : &places_[static_cast<std::size_t>(r)];
}

const Place* Reachability::placeAt(const octomap::OcTreeKey& key) const {
  if (!columns_) return nullptr;
  const long col = columns_->columnIndex(key[0], key[1]);
  for (std::size_t r = columns_->runBegin(col); r < columns_->runEnd(col); ++r) {
    if (columns_->runs()[r].top == key[2]) return &places_[r];
  }
  return nullptr;
}

std::vector<std::size_t> Reachability::footPlacesNear(double x, double y, double radius_m) const {
  std::vector<std::size_t> out;
  if (!columns_ || lnx_ == 0 || !std::isfinite(x) || !std::isfinite(y) || !(radius_m >= 0)) return out;
  const double cell = lattice_ * columns_->resolution();
  const long ci = floorDiv(columns_->keyOf(x), lattice_) - lx0_, cj = floorDiv(columns_->keyOf(y), lattice_) - ly0_;
  const long rad = static_cast<long>(std::ceil(radius_m / cell)) + 1;
  for (long i = std::max(0L, ci - rad); i <= std::min(lnx_ - 1, ci + rad); ++i) {
    for (long j = std::max(0L, cj - rad); j <= std::min(lny_ - 1, cj + rad); ++j) {
      const auto c = static_cast<std::size_t>(i * lny_ + j);
      for (std::size_t f = feet_offsets_[c]; f < feet_offsets_[c + 1]; ++f) {
        if (std::hypot(feet_[f].x - x, feet_[f].y - y) <= radius_m + 1e-9) out.push_back(f);
      }
    }
  }
  return out;
}

SoleReach Reachability::sole(const Foot& foot, double search_up_m, double search_down_m) const {
  SoleReach out;
  if (!columns_ || !std::isfinite(foot.z) || !(search_up_m >= 0) || !(search_down_m >= 0)) return out;
  // The surface under the sole's centre in the band searched, else the sole's own height.
  const long r = columns_->runBelow(foot.x, foot.y, foot.z + search_up_m, foot.z - search_down_m);
  const double z_ref = r >= 0 ? columns_->topFace(columns_->runs()[static_cast<std::size_t>(r)]) : foot.z;
  RobotParams robot = params_.robot;
  robot.sole_length_m = foot.length, robot.sole_width_m = foot.width;
  out.foothold = evaluateFoothold(*columns_, foot.x, foot.y, foot.yaw, z_ref, robot);
  out.standable = out.foothold.standable();
  if (!out.standable) return out;
  for (const std::size_t f : footPlacesNear(foot.x, foot.y, robot.max_stride_m)) {
    const FootPlace& from = feet_[f];
    if (from.reachable && canStep(*columns_, from.x, from.y, from.z, foot.x, foot.y, out.foothold.z, robot)) {
      out.reachable = true;
      break;
    }
  }
  return out;
}

std::size_t Reachability::memoryBytes() const {
  return sizeof(*this) + places_.capacity() * sizeof(Place) + feet_.capacity() * sizeof(FootPlace) +
         feet_offsets_.capacity() * sizeof(std::uint32_t) + start_feet_.capacity() * sizeof(std::size_t) +
         (columns_ ? columns_->memoryBytes() : 0);
}

Reachability computeReachability(const MobilityOcTree& tree, const Eigen::Vector3d& start, const ReachParams& params,
                                 const Budget& budget) {
  validate(params);
  return computeReachability(std::make_shared<const SurfaceColumns>(tree), start, params, budget);
}

Reachability computeReachability(std::shared_ptr<const SurfaceColumns> columns, const Eigen::Vector3d& start,
                                 const ReachParams& params, const Budget& budget) {
  constexpr const char* kWhat = "computeReachability";
  validate(params);
  if (!start.allFinite()) throw std::invalid_argument("computeReachability: the start point is not finite");
  if (!columns) throw std::invalid_argument("computeReachability: no columns");
  const SurfaceColumns& cols = *columns;
  const double res = cols.resolution();
  const RobotParams& robot = params.robot;
  if (robot.max_step_m < 2 * res - 1e-9) {
    std::ostringstream msg;
    msg << "is " << robot.max_step_m << " (must be at least two voxels, " << 2 * res
        << " m in this map: support heights are known to a voxel)";
    throw util::FieldError("max_step_m", msg.str(), "ReachParams");
  }
  Reachability r;
  r.params_ = params;
  r.columns_ = columns;
  const auto& runs = cols.runs();

  // Places: one per run.
  r.places_.resize(runs.size());
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const long col = static_cast<long>(cols.runColumn(i));
    const long kx = cols.keyX0() + col / cols.columnsY(), ky = cols.keyY0() + col % cols.columnsY();
    Place& p = r.places_[i];
    p.key = octomap::OcTreeKey(static_cast<octomap::key_type>(kx), static_cast<octomap::key_type>(ky),
                               static_cast<octomap::key_type>(runs[i].top));
    p.x = cols.centreOf(kx), p.y = cols.centreOf(ky), p.top_z = cols.topFace(runs[i]);
    p.has_mobility = runs[i].hasMobility();
    p.mobility = p.has_mobility ? runs[i].mobility : 0.0;
    const bool last = i + 1 == runs.size() || cols.runColumn(i + 1) != cols.runColumn(i);
    p.headroom_m = last ? std::numeric_limits<double>::infinity() : cols.bottomFace(runs[i + 1]) - p.top_z;
  }

  // Foot places: every lattice column (key a multiple of the lattice step), every run in
  // it, the eight distinct headings of a symmetric sole.
  const long s = std::max(1L, std::lround(robot.lattice_m / res));
  r.lattice_ = s;
  if (cols.columnsX() > 0) {
    r.lx0_ = floorDiv(cols.keyX0() + s - 1, s), r.ly0_ = floorDiv(cols.keyY0() + s - 1, s);
    r.lnx_ = std::max(0L, floorDiv(cols.keyX0() + cols.columnsX() - 1, s) - r.lx0_ + 1);
    r.lny_ = std::max(0L, floorDiv(cols.keyY0() + cols.columnsY() - 1, s) - r.ly0_ + 1);
  }
  r.feet_offsets_.assign(static_cast<std::size_t>(r.lnx_ * r.lny_) + 1, 0);
  // The surfaces a standable (or reachable) sole rests on.
  std::vector<std::size_t> supports;
  const auto markUnder = [&r](const std::vector<std::size_t>& under, bool reachable) {
    for (const std::size_t run : under) {
      Place& p = r.places_[run];
      if (!p.standable) ++r.standable_, p.standable = true;
      if (reachable && !p.reachable) ++r.reachable_, p.reachable = true;
    }
  };
  for (long i = 0; i < r.lnx_; ++i) {
    budget.check(kWhat);  // a row of lattice columns: at most milliseconds
    for (long j = 0; j < r.lny_; ++j) {
      r.feet_offsets_[static_cast<std::size_t>(i * r.lny_ + j)] = static_cast<std::uint32_t>(r.feet_.size());
      const long kx = (r.lx0_ + i) * s, ky = (r.ly0_ + j) * s;
      const long col = cols.columnIndex(kx, ky);
      for (std::size_t run = cols.runBegin(col); run < cols.runEnd(col); ++run) {
        FootPlace fp;
        fp.x = cols.centreOf(kx), fp.y = cols.centreOf(ky), fp.place = run;
        double z_sum = 0;
        int z_n = 0;
        for (int h = 0; h < kHeadings / 2; ++h) {
          const Foothold f = evaluateFoothold(cols, fp.x, fp.y, headingYaw(h), cols.topFace(runs[run]), robot, &supports);
          if (!f.geometryOk()) continue;
          fp.geometry_ok |= static_cast<std::uint8_t>(1u << h);
          z_sum += f.z, ++z_n;
          if (f.standable()) {
            fp.standable |= static_cast<std::uint8_t>(1u << h);
            fp.min_mobility = std::max(fp.min_mobility, static_cast<float>(f.min_mobility));
            markUnder(supports, false);
          }
        }
        if (!fp.geometry_ok) continue;
        fp.z = z_sum / z_n;
        r.feet_.push_back(fp);
      }
    }
  }
  r.feet_offsets_.back() = static_cast<std::uint32_t>(r.feet_.size());

  // The start soles, chosen by geometry alone (see ReachParams::Start).
  const double level_tol = std::max(0.05, 2 * res);
  const auto near = r.footPlacesNear(start.x(), start.y(), params.start_radius_m);
  const auto dist2 = [&](const FootPlace& f) {
    return (f.x - start.x()) * (f.x - start.x()) + (f.y - start.y()) * (f.y - start.y());
  };
  if (params.start_rule == ReachParams::Start::kNearest) {
    std::optional<std::size_t> ref;
    for (const std::size_t f : near) {
      const FootPlace& fp = r.feet_[f];
      if (fp.z > start.z() + kStartSlack) continue;
      if (!ref || dist2(fp) < dist2(r.feet_[*ref]) - 1e-12 ||
          (dist2(fp) <= dist2(r.feet_[*ref]) + 1e-12 && fp.z > r.feet_[*ref].z)) {
        ref = f;
      }
    }
    if (ref) {
      const FootPlace& c = r.feet_[*ref];
      const double around = std::max(0.5 * robot.sole_length_m, s * res);
      for (const std::size_t f : r.footPlacesNear(c.x, c.y, around)) {
        if (r.feet_[f].isStandable() && std::abs(r.feet_[f].z - c.z) <= level_tol) r.start_feet_.push_back(f);
      }
    }
  } else {
    // The largest level: the most walkable surface, as `info` measures it.
    const std::vector<Level> levels = gatherLevels(walkableBins(cols), res, 1, 0.0);
    double level = 0;
    if (!levels.empty()) {
      level = levels.front().z_m;
      StartLevel sl;
      sl.z_m = level, sl.walkable = levels.front().count, sl.share = levels.front().share;
      const double radius2 = params.start_radius_m * params.start_radius_m;
      for (const Place& p : r.places_) {
        if (!p.has_mobility || p.mobility < kWalkableMobility || std::abs(p.top_z - level) > level_tol) continue;
        const double d2 = (p.x - start.x()) * (p.x - start.x()) + (p.y - start.y()) * (p.y - start.y());
        if (d2 > radius2) continue;
        ++sl.walkable_near;
        sl.standable_near += p.standable;
      }
      r.start_level_ = sl;
    } else {
      // No walkable place: the height with the most sole centres (any heading's geometry
      // passes) within 4 cm.
      const double window = std::max(0.04, res);
      std::vector<double> zs;
      zs.reserve(r.feet_.size());
      for (const FootPlace& f : r.feet_) zs.push_back(f.z);
      std::sort(zs.begin(), zs.end());
      std::size_t best = 0, lo = 0, hi = 0;
      for (std::size_t i = 0; i < zs.size(); ++i) {
        while (zs[lo] < zs[i] - window - 1e-9) ++lo;
        while (hi < zs.size() && zs[hi] <= zs[i] + window + 1e-9) ++hi;
        if (hi - lo > best) best = hi - lo, level = zs[i];
      }
    }
    for (const std::size_t f : near) {
      if (r.feet_[f].isStandable() && std::abs(r.feet_[f].z - level) <= level_tol) r.start_feet_.push_back(f);
    }
  }
  for (const std::size_t f : r.start_feet_) {
    if (!r.start_ || dist2(r.feet_[f]) < dist2(r.feet_[*r.start_]) - 1e-12) r.start_ = f;
  }

  // Walk: breadth first over steps between standable soles.
  std::vector<std::pair<long, long>> offsets;
  const long rad = static_cast<long>(std::floor(robot.max_stride_m / (s * res) + 1e-9));
  for (long di = -rad; di <= rad; ++di) {
    for (long dj = -rad; dj <= rad; ++dj) {
      if ((di || dj) && std::hypot(di, dj) * s * res <= robot.max_stride_m + 1e-9) offsets.emplace_back(di, dj);
    }
  }
  std::deque<std::size_t> queue;
  for (const std::size_t f : r.start_feet_) {
    r.feet_[f].reachable = true;
    queue.push_back(f);
  }
  for (std::size_t popped = 0; !queue.empty(); ++popped) {
    if ((popped & 1023u) == 0) budget.check(kWhat);
    const std::size_t a = queue.front();
    queue.pop_front();
    const FootPlace& from = r.feet_[a];
    const long ci = floorDiv(cols.keyOf(from.x), s) - r.lx0_, cj = floorDiv(cols.keyOf(from.y), s) - r.ly0_;
    for (const auto& [di, dj] : offsets) {
      const long i = ci + di, j = cj + dj;
      if (i < 0 || j < 0 || i >= r.lnx_ || j >= r.lny_) continue;
      const auto c = static_cast<std::size_t>(i * r.lny_ + j);
      for (std::size_t b = r.feet_offsets_[c]; b < r.feet_offsets_[c + 1]; ++b) {
        FootPlace& to = r.feet_[b];
        if (to.reachable || !to.isStandable() || !canStep(cols, from.x, from.y, from.z, to.x, to.y, to.z, robot)) continue;
        to.reachable = true;
        queue.push_back(b);
      }
    }
  }

  // The surfaces under reachable soles.
  for (std::size_t k = 0; k < r.feet_.size(); ++k) {
    if ((k & 1023u) == 0) budget.check(kWhat);
    const FootPlace& f = r.feet_[k];
    if (!f.reachable) continue;
    for (int h = 0; h < kHeadings / 2; ++h) {
      if (!(f.standable & (1u << h))) continue;
      (void)evaluateFoothold(cols, f.x, f.y, headingYaw(h), cols.topFace(runs[f.place]), robot, &supports);
      markUnder(supports, true);
    }
  }
  return r;
}

}  // namespace mobmap::mapping
