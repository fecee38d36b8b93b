#include "mobmap/mapping/reachability.hpp"

#include "param_error.hpp"
#include "reach_detail.hpp"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <mutex>
#include <sstream>
#include <stdexcept>

namespace mobmap::mapping {
using detail::floorDiv;

void validate(const ReachParams& p) {
  validate(p.robot);
  if (!(p.start_radius_m >= 0 && p.start_radius_m <= 100)) detail::failParam("ReachParams", "start_radius_m", p.start_radius_m, "must be in [0, 100]");
}

const Place* Reachability::placeBelow(const Eigen::Vector3d& p, double max_drop_m) const {
  if (!standing_ || !p.allFinite() || !(max_drop_m >= 0) || !std::isfinite(max_drop_m)) return nullptr;
  const SurfaceColumns& cols = columns();
  const double res = cols.resolution();
  // At or below the voxel holding p: its top face may be up to a voxel above p.z.
  const double voxel_top = cols.centreOf(cols.keyOf(p.z())) + res / 2;
  const long r = cols.runBelow(p.x(), p.y(), voxel_top, p.z() - max_drop_m);
  return r < 0 ? nullptr : &places_[static_cast<std::size_t>(r)];
}

const Place* Reachability::placeAt(const octomap::OcTreeKey& key) const {
  if (!standing_) return nullptr;
  const SurfaceColumns& cols = columns();
  const long col = cols.columnIndex(key[0], key[1]);
  for (std::size_t r = cols.runBegin(col); r < cols.runEnd(col); ++r) {
    if (cols.runs()[r].top == key[2]) return &places_[r];
  }
  return nullptr;
}

std::vector<std::size_t> Standability::footPlacesNear(double x, double y, double radius_m) const {
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

std::vector<std::size_t> Reachability::footPlacesNear(double x, double y, double radius_m) const {
  return standing_ ? standing_->footPlacesNear(x, y, radius_m) : std::vector<std::size_t>{};
}

SoleReach Reachability::sole(const Foot& foot, double search_up_m, double search_down_m) const {
  SoleReach out;
  if (!standing_ || !std::isfinite(foot.z) || !(search_up_m >= 0) || !(search_down_m >= 0)) return out;
  const SurfaceColumns& cols = columns();
  // The surface under the sole's centre in the band searched, else the sole's own height.
  const long r = cols.runBelow(foot.x, foot.y, foot.z + search_up_m, foot.z - search_down_m);
  const double z_ref = r >= 0 ? cols.topFace(cols.runs()[static_cast<std::size_t>(r)]) : foot.z;
  RobotParams robot = params_.robot;
  robot.sole_length_m = foot.length, robot.sole_width_m = foot.width;
  out.foothold = evaluateFoothold(cols, foot.x, foot.y, foot.yaw, z_ref, robot);
  out.standable = out.foothold.standable();
  if (!out.standable) return out;
  for (const std::size_t f : footPlacesNear(foot.x, foot.y, robot.max_stride_m)) {
    const FootPlace& from = feet_[f];
    if (from.reachable && canStep(cols, from.x, from.y, from.z, foot.x, foot.y, out.foothold.z, robot)) {
      out.reachable = true;
      break;
    }
  }
  return out;
}

std::size_t Standability::memoryBytes() const {
  return sizeof(*this) + places_.capacity() * sizeof(Place) + feet_.capacity() * sizeof(FootPlace) +
         feet_offsets_.capacity() * sizeof(std::uint32_t) + support_masks_.capacity() * sizeof(std::uint64_t);
}

std::size_t Reachability::memoryBytes() const {
  return sizeof(*this) + places_.capacity() * sizeof(Place) + feet_.capacity() * sizeof(FootPlace) +
         start_feet_.capacity() * sizeof(std::size_t) +
         (standing_ ? standing_->memoryBytes() + standing_->columns().memoryBytes() : 0);
}

Reachability computeReachability(const MobilityOcTree& tree, const Eigen::Vector3d& start, const ReachParams& params,
                                 const Budget& budget) {
  validate(params);
  return computeReachability(std::make_shared<const SurfaceColumns>(tree), start, params, budget);
}

namespace {

constexpr const char* kWhat = "computeReachability";

/// max_step_m of at least two voxels of `cols` (support heights are known to a voxel).
void checkStepAgainstVoxels(const SurfaceColumns& cols, const RobotParams& robot, const char* context) {
  const double res = cols.resolution();
  if (robot.max_step_m < 2 * res - 1e-9) {
    std::ostringstream msg;
    msg << "is " << robot.max_step_m << " (must be at least two voxels, " << 2 * res
        << " m in this map: support heights are known to a voxel)";
    throw util::FieldError("max_step_m", msg.str(), context);
  }
}

}  // namespace

Reachability computeReachability(std::shared_ptr<const SurfaceColumns> columns, const Eigen::Vector3d& start,
                                 const ReachParams& params, const Budget& budget) {
  validate(params);
  if (!start.allFinite()) throw std::invalid_argument("computeReachability: the start point is not finite");
  if (!columns) throw std::invalid_argument("computeReachability: no columns");
  checkStepAgainstVoxels(*columns, params.robot, "ReachParams");
  return computeReachability(computeStandability(std::move(columns), params.robot, budget), start, params, budget);
}

FootPlace detail::judgeFootPlace(const SurfaceColumns& cols, long kx, long ky, std::size_t run, const RobotParams& robot,
                                 std::vector<std::size_t>* standable_supports) {
  thread_local std::vector<std::size_t> supports;
  FootPlace fp;
  fp.x = cols.centreOf(kx), fp.y = cols.centreOf(ky), fp.place = run;
  double z_sum = 0;
  int z_n = 0;
  const double top = cols.topFace(cols.runs()[run]);
  for (int h = 0; h < kHeadings / 2; ++h) {
    const Foothold f = evaluateFoothold(cols, fp.x, fp.y, headingYaw(h), top, robot, standable_supports ? &supports : nullptr);
    if (!f.geometryOk()) continue;
    fp.geometry_ok |= static_cast<std::uint8_t>(1u << h);
    z_sum += f.z, ++z_n;
    if (!f.standable()) continue;
    fp.standable |= static_cast<std::uint8_t>(1u << h);
    fp.min_mobility = std::max(fp.min_mobility, static_cast<float>(f.min_mobility));
    if (standable_supports) standable_supports->insert(standable_supports->end(), supports.begin(), supports.end());
  }
  if (z_n) fp.z = z_sum / z_n;
  return fp;
}

std::shared_ptr<const Standability> computeStandability(std::shared_ptr<const SurfaceColumns> columns, const RobotParams& robot,
                                                        const Budget& budget) {
  validate(robot);
  if (!columns) throw std::invalid_argument("computeStandability: no columns");
  const SurfaceColumns& cols = *columns;
  checkStepAgainstVoxels(cols, robot, "RobotParams");
  const double res = cols.resolution();
  auto out = std::make_shared<Standability>();
  Standability& r = *out;
  r.robot_ = robot;
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
  // A sole's samples lie within half its diagonal of its centre: their columns within
  // this many of the centre's.
  r.mask_reach_ = static_cast<long>(std::ceil(0.5 * std::hypot(robot.sole_length_m, robot.sole_width_m) / res)) + 1;
  const long side = 2 * r.mask_reach_ + 1;
  r.mask_words_ = static_cast<std::size_t>((side * side + 63) / 64);
  std::vector<std::uint64_t> mask(r.mask_words_);
  // The surfaces a standable sole rests on.
  std::vector<std::size_t> supports;
  for (long i = 0; i < r.lnx_; ++i) {
    budget.check(kWhat);  // a row of lattice columns: at most milliseconds
    for (long j = 0; j < r.lny_; ++j) {
      r.feet_offsets_[static_cast<std::size_t>(i * r.lny_ + j)] = static_cast<std::uint32_t>(r.feet_.size());
      const long kx = (r.lx0_ + i) * s, ky = (r.ly0_ + j) * s;
      const long col = cols.columnIndex(kx, ky);
      for (std::size_t run = cols.runBegin(col); run < cols.runEnd(col); ++run) {
        supports.clear();
        const FootPlace fp = detail::judgeFootPlace(cols, kx, ky, run, robot, &supports);
        if (!fp.geometry_ok) continue;
        std::fill(mask.begin(), mask.end(), 0);
        for (const std::size_t under : supports) {
          Place& p = r.places_[under];
          if (!p.standable) ++r.standable_, p.standable = true;
          const long c = cols.runColumn(under);
          const long dx = cols.keyX0() + c / cols.columnsY() - kx + r.mask_reach_;
          const long dy = cols.keyY0() + c % cols.columnsY() - ky + r.mask_reach_;
          if (dx < 0 || dy < 0 || dx >= side || dy >= side) throw std::logic_error("computeStandability: a support outside the sole's reach");
          const auto bit = static_cast<std::size_t>(dx * side + dy);
          mask[bit / 64] |= std::uint64_t{1} << (bit % 64);
        }
        r.feet_.push_back(fp);
        r.support_masks_.insert(r.support_masks_.end(), mask.begin(), mask.end());
      }
    }
  }
  r.feet_offsets_.back() = static_cast<std::uint32_t>(r.feet_.size());
  return out;
}

Reachability computeReachability(std::shared_ptr<const Standability> standing, const Eigen::Vector3d& start,
                                 const ReachParams& params, const Budget& budget) {
  validate(params);
  if (!start.allFinite()) throw std::invalid_argument("computeReachability: the start point is not finite");
  if (!standing) throw std::invalid_argument("computeReachability: no standability");
  if (standing->robot() != params.robot) {
    throw std::invalid_argument("computeReachability: the soles were judged for another robot than `robot`");
  }
  const Standability& st = *standing;
  const SurfaceColumns& cols = st.columns();
  const double res = cols.resolution();
  const RobotParams& robot = params.robot;
  const auto& runs = cols.runs();
  Reachability r;
  r.params_ = params;
  r.standing_ = standing;
  r.places_ = st.places_;
  r.feet_ = st.feet_;
  const long s = st.lattice_;

  // The start soles, chosen by geometry alone (see ReachParams::Start).
  const double level_tol = std::max(0.05, 2 * res);
  const auto near = r.footPlacesNear(start.x(), start.y(), params.start_radius_m);
  const auto dist2 = [&](const FootPlace& f) {
    return (f.x - start.x()) * (f.x - start.x()) + (f.y - start.y()) * (f.y - start.y());
  };
  if (params.start_rule == ReachParams::Start::kNearest) {
    r.start_feet_ = detail::nearestStartFeet(
        start, near, std::max(0.5 * robot.sole_length_m, s * res), level_tol,
        [&](double x, double y, double radius) { return st.footPlacesNear(x, y, radius); },
        [&](std::size_t f) -> const FootPlace& { return r.feet_[f]; });
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
  const auto offsets = detail::strideOffsets(robot, s, res);
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
    const long ci = floorDiv(cols.keyOf(from.x), s) - st.lx0_, cj = floorDiv(cols.keyOf(from.y), s) - st.ly0_;
    for (const auto& [di, dj] : offsets) {
      const long i = ci + di, j = cj + dj;
      if (i < 0 || j < 0 || i >= st.lnx_ || j >= st.lny_) continue;
      const auto c = static_cast<std::size_t>(i * st.lny_ + j);
      for (std::size_t b = st.feet_offsets_[c]; b < st.feet_offsets_[c + 1]; ++b) {
        FootPlace& to = r.feet_[b];
        if (to.reachable || !to.isStandable() || !canStep(cols, from.x, from.y, from.z, to.x, to.y, to.z, robot)) continue;
        to.reachable = true;
        queue.push_back(b);
      }
    }
  }

  // The surfaces under reachable soles: in each column a standable sole of the foot
  // place rests on, the surface evaluateFoothold() found there.
  const double band = detail::supportBand(robot, res);
  const long side = 2 * st.mask_reach_ + 1;
  for (std::size_t k = 0; k < r.feet_.size(); ++k) {
    if ((k & 1023u) == 0) budget.check(kWhat);
    const FootPlace& f = r.feet_[k];
    if (!f.reachable) continue;
    const double z_ref = cols.topFace(runs[f.place]);
    const long kx = cols.keyOf(f.x) - st.mask_reach_, ky = cols.keyOf(f.y) - st.mask_reach_;
    const std::uint64_t* mask = st.support_masks_.data() + k * st.mask_words_;
    for (std::size_t w = 0; w < st.mask_words_; ++w) {
      for (std::uint64_t bits = mask[w]; bits; bits &= bits - 1) {
        const long bit = static_cast<long>(w * 64) + __builtin_ctzll(bits);
        const long col = cols.columnIndex(kx + bit / side, ky + bit % side);
        for (std::size_t run = cols.runEnd(col); run > cols.runBegin(col); --run) {
          const double top = cols.topFace(runs[run - 1]);
          if (top > z_ref + band) continue;
          if (top >= z_ref - band) {
            Place& p = r.places_[run - 1];
            if (!p.reachable) ++r.reachable_, p.reachable = true;
          }
          break;
        }
      }
    }
  }
  return r;
}

// ---- ReachCache ---------------------------------------------------------------------

struct ReachCache::Impl {
  struct Entry {
    const SurfaceColumns* columns = nullptr;  ///< the map, by identity (the value keeps it alive)
    RobotParams robot;
    /// For a walk: its params and start; for standability none.
    std::optional<std::pair<ReachParams, Eigen::Vector3d>> walk;
    std::shared_ptr<const Standability> standing;
    std::shared_ptr<const Reachability> reach;
    std::size_t bytes = 0;
    std::uint64_t used = 0;
  };
  std::size_t max_bytes;
  mutable std::mutex mutex;
  std::vector<Entry> entries;
  std::uint64_t clock = 0;
  Stats stats;

  static bool sameWalk(const std::pair<ReachParams, Eigen::Vector3d>& w, const ReachParams& p, const Eigen::Vector3d& start) {
    return w.first.robot == p.robot && w.first.start_radius_m == p.start_radius_m && w.first.start_rule == p.start_rule &&
           w.second == start;
  }

  Entry* find(const SurfaceColumns* columns, const RobotParams& robot, const ReachParams* walk, const Eigen::Vector3d* start) {
    for (Entry& e : entries) {
      if (e.columns != columns || e.robot != robot || e.walk.has_value() != (walk != nullptr)) continue;
      if (walk && !sameWalk(*e.walk, *walk, *start)) continue;
      e.used = ++clock;
      return &e;
    }
    return nullptr;
  }

  // Under the lock: keeps `e` (unless an equal entry came meanwhile), then drops the least
  // recently used others while the bytes pass the bound.
  void insert(Entry e) {
    e.used = ++clock;
    entries.push_back(std::move(e));
    std::size_t bytes = 0;
    for (const Entry& k : entries) bytes += k.bytes;
    while (bytes > max_bytes && entries.size() > 1) {
      auto oldest = std::min_element(entries.begin(), entries.end() - 1,
                                     [](const Entry& a, const Entry& b) { return a.used < b.used; });
      bytes -= oldest->bytes;
      entries.erase(oldest);
      ++stats.evictions;
    }
  }
};

ReachCache::ReachCache(std::size_t max_bytes) : impl_(std::make_unique<Impl>()) { impl_->max_bytes = max_bytes; }
ReachCache::~ReachCache() = default;

std::shared_ptr<const Standability> ReachCache::standability(const std::shared_ptr<const SurfaceColumns>& columns,
                                                             const RobotParams& robot, const Budget& budget) {
  if (!columns) throw std::invalid_argument("ReachCache: no columns");
  {
    const std::lock_guard<std::mutex> lock(impl_->mutex);
    if (Impl::Entry* e = impl_->find(columns.get(), robot, nullptr, nullptr)) {
      ++impl_->stats.hits;
      return e->standing;
    }
    ++impl_->stats.misses;
  }
  auto standing = computeStandability(columns, robot, budget);
  const std::lock_guard<std::mutex> lock(impl_->mutex);
  if (Impl::Entry* e = impl_->find(columns.get(), robot, nullptr, nullptr)) return e->standing;
  Impl::Entry e;
  e.columns = columns.get(), e.robot = robot, e.standing = standing;
  e.bytes = standing->memoryBytes() + columns->memoryBytes();
  impl_->insert(std::move(e));
  return standing;
}

std::shared_ptr<const Reachability> ReachCache::findReachability(const std::shared_ptr<const SurfaceColumns>& columns,
                                                                 const Eigen::Vector3d& start, const ReachParams& params) const {
  if (!columns) return nullptr;
  const std::lock_guard<std::mutex> lock(impl_->mutex);
  const Impl::Entry* e = impl_->find(columns.get(), params.robot, &params, &start);
  return e ? e->reach : nullptr;
}

std::shared_ptr<const Reachability> ReachCache::reachability(const std::shared_ptr<const SurfaceColumns>& columns,
                                                             const Eigen::Vector3d& start, const ReachParams& params,
                                                             const Budget& budget) {
  validate(params);
  if (!columns) throw std::invalid_argument("ReachCache: no columns");
  if (!start.allFinite()) throw std::invalid_argument("computeReachability: the start point is not finite");
  checkStepAgainstVoxels(*columns, params.robot, "ReachParams");
  {
    const std::lock_guard<std::mutex> lock(impl_->mutex);
    if (Impl::Entry* e = impl_->find(columns.get(), params.robot, &params, &start)) {
      ++impl_->stats.hits;
      return e->reach;
    }
  }
  auto reach = std::make_shared<const Reachability>(computeReachability(standability(columns, params.robot, budget), start, params, budget));
  const std::lock_guard<std::mutex> lock(impl_->mutex);
  ++impl_->stats.misses;
  if (Impl::Entry* e = impl_->find(columns.get(), params.robot, &params, &start)) return e->reach;
  Impl::Entry e;
  e.columns = columns.get(), e.robot = params.robot, e.walk = std::make_pair(params, start), e.reach = reach;
  // Its own copies only: what it shares is counted with its standability.
  e.bytes = reach->memoryBytes() - reach->standability()->memoryBytes() - columns->memoryBytes();
  impl_->insert(std::move(e));
  return reach;
}

ReachCache::Stats ReachCache::stats() const {
  const std::lock_guard<std::mutex> lock(impl_->mutex);
  Stats s = impl_->stats;
  s.entries = impl_->entries.size();
  for (const Impl::Entry& e : impl_->entries) s.bytes += e.bytes;
  return s;
}

void ReachCache::clear() {
  const std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->entries.clear();
}

}  // namespace mobmap::mapping
