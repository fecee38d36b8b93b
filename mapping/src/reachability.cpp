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

std::uint32_t columnOf(unsigned kx, unsigned ky) { return (static_cast<std::uint32_t>(kx) << 16) | ky; }

bool inTree(long kx, long ky) { return kx >= 0 && ky >= 0 && kx <= 65535 && ky <= 65535; }

// Part of a column: voxels lo..hi (z keys) of one leaf, all with the leaf's mobility.
struct Interval {
  int lo, hi;
  bool has_mobility;
  float mobility;
};

// The key of the voxel holding coordinate c, as OctoMap's coordToKey computes it (but
// not clamped to 16 bits, so callers can tell a point outside the tree).
long keyOf(double c, double res) { return static_cast<long>(std::floor((1.0 / res) * c)) + 32768L; }

// Whole voxels in `metres`, with a little slack so 0.15 / 0.01 counts as 15 (not 14.999...).
int voxels(double metres, double res) { return static_cast<int>(std::floor(metres / res + 1e-6)); }

}  // namespace

void validate(const ReachParams& p) {
  if (!(p.max_step_m >= 0) || !std::isfinite(p.max_step_m)) detail::failParam("ReachParams", "max_step_m", p.max_step_m, "must be finite and >= 0");
  if (!(p.min_mobility >= 0 && p.min_mobility <= 1)) detail::failParam("ReachParams", "min_mobility", p.min_mobility, "must be in [0, 1]");
  if (!(p.clearance_m >= 0) || !std::isfinite(p.clearance_m)) detail::failParam("ReachParams", "clearance_m", p.clearance_m, "must be finite and >= 0");
  if (!(p.max_gap_m >= 0 && p.max_gap_m <= 1)) detail::failParam("ReachParams", "max_gap_m", p.max_gap_m, "must be in [0, 1]");
  if (!(p.start_radius_m >= 0 && p.start_radius_m <= 100)) detail::failParam("ReachParams", "start_radius_m", p.start_radius_m, "must be in [0, 100]");
}

const Place* Reachability::placeBelow(const Eigen::Vector3d& p, double max_drop_m) const {
  if (!p.allFinite() || !(max_drop_m >= 0) || !std::isfinite(max_drop_m) || resolution_ <= 0) return nullptr;
  const long kx = keyOf(p.x(), resolution_), ky = keyOf(p.y(), resolution_), kz = keyOf(p.z(), resolution_);
  const auto* col = columnAt(kx, ky);
  if (!col) return nullptr;
  const Place* best = nullptr;
  for (const std::uint32_t i : *col) {  // lowest first: the last that fits is the highest
    const Place& pl = places_[i];
    if (pl.key[2] > kz) break;
    if (pl.top_z >= p.z() - max_drop_m - 1e-9) best = &pl;
  }
  return best;
}

SoleReach Reachability::sole(const Foot& foot, double search_up_m, double search_down_m) const {
  SoleReach out;  // a default Reachability has resolution 0: soleSamples() then gives none
  for (const SoleSample& s : soleSamples(foot, resolution_)) {
    ++out.samples;
    const Place* p = placeBelow({s.x, s.y, foot.z + search_up_m}, search_up_m + search_down_m);
    if (!p) continue;
    ++out.on_place;
    out.standable += p->standable ? 1 : 0;
    out.reachable += p->reachable ? 1 : 0;
  }
  return out;
}

const std::vector<std::uint32_t>* Reachability::columnAt(long kx, long ky) const {
  if (!inTree(kx, ky)) return nullptr;
  const auto col = columns_.find(columnOf(static_cast<unsigned>(kx), static_cast<unsigned>(ky)));
  return col == columns_.end() ? nullptr : &col->second;
}

const Place* Reachability::placeAt(const octomap::OcTreeKey& key) const {
  const auto* col = columnAt(key[0], key[1]);
  if (!col) return nullptr;
  for (const std::uint32_t i : *col) {
    if (places_[i].key[2] == key[2]) return &places_[i];
  }
  return nullptr;
}

Reachability computeReachability(const MobilityOcTree& tree, const Eigen::Vector3d& start, const ReachParams& params) {
  validate(params);
  if (!start.allFinite()) throw std::invalid_argument("computeReachability: the start point is not finite");
  Reachability r;
  r.params_ = params;
  const double res = tree.getResolution();
  r.resolution_ = res;

  // Every occupied leaf as one interval in each of the columns it covers.
  std::unordered_map<std::uint32_t, std::vector<Interval>> columns;
  std::size_t cells = 0;
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) {
    if (!tree.isNodeOccupied(*it)) continue;
    const int span = static_cast<int>(std::lround(it.getSize() / res));
    const double half = it.getSize() / 2 - res / 2;  // leaf centre to its first voxel's centre
    const octomap::OcTreeKey k0 = tree.coordToKey(octomap::point3d(static_cast<float>(it.getX() - half),
                                                                   static_cast<float>(it.getY() - half),
                                                                   static_cast<float>(it.getZ() - half)));
    cells += static_cast<std::size_t>(span) * static_cast<std::size_t>(span);
    if (cells > (std::size_t{1} << 26)) throw std::length_error("computeReachability: the map has more than 2^26 columns");
    const Interval in{k0[2], k0[2] + span - 1, it->hasMobility(), static_cast<float>(it->hasMobility() ? it->mobility() : 0.0)};
    for (int dx = 0; dx < span; ++dx) {
      for (int dy = 0; dy < span; ++dy) {
        columns[columnOf(static_cast<unsigned>(k0[0] + dx), static_cast<unsigned>(k0[1] + dy))].push_back(in);
      }
    }
  }

  // Runs of adjacent occupied voxels, one place each.
  const int clear_vox = static_cast<int>(std::ceil(params.clearance_m / res - 1e-6));
  for (auto& [col, ivs] : columns) {
    std::sort(ivs.begin(), ivs.end(), [](const Interval& a, const Interval& b) { return a.lo < b.lo; });
    auto& ids = r.columns_[col];
    const unsigned kx = col >> 16, ky = col & 0xffffu;
    std::size_t i = 0;
    while (i < ivs.size()) {
      int lo = ivs[i].lo, hi = ivs[i].hi;
      const Interval* top = &ivs[i];   // holds the run's top voxel
      const Interval* known = nullptr;  // the highest interval with a mobility
      for (; i < ivs.size() && ivs[i].lo <= hi + 1; ++i) {
        if (ivs[i].hi >= hi) hi = ivs[i].hi, top = &ivs[i];
        if (ivs[i].has_mobility && (!known || ivs[i].hi > known->hi)) known = &ivs[i];
      }
      Place pl;
      pl.key = octomap::OcTreeKey(static_cast<octomap::key_type>(kx), static_cast<octomap::key_type>(ky),
                                  static_cast<octomap::key_type>(hi));
      pl.x = tree.keyToCoord(pl.key[0]);
      pl.y = tree.keyToCoord(pl.key[1]);
      pl.top_z = tree.keyToCoord(pl.key[2]) + res / 2;
      const Interval* m = top->has_mobility ? top : known;
      pl.has_mobility = m != nullptr;
      pl.mobility = m ? m->mobility : 0.0;
      pl.headroom_m = i < ivs.size() ? (ivs[i].lo - hi - 1) * res : std::numeric_limits<double>::infinity();
      pl.standable = pl.has_mobility && pl.mobility >= params.min_mobility && (ivs.size() == i || ivs[i].lo - hi - 1 >= clear_vox);
      ids.push_back(static_cast<std::uint32_t>(r.places_.size()));
      r.places_.push_back(pl);
      r.run_bottom_.push_back(static_cast<std::uint16_t>(lo));
      r.standable_ += pl.standable ? 1 : 0;
    }
  }

  // Regions: flood fill from every standable place not yet in one. A hop across empty
  // columns needs every column in between to hold no occupied voxel from a step below
  // the lower place to a step (or the clearance) above the higher one: a wall, an
  // obstacle or a surface too poor to stand on blocks it. The rule is symmetric, so the
  // regions do not depend on where a fill starts.
  // Tops are voxel faces: tops n voxels apart can hide a true step of nearly n + 1
  // voxels (a floor at the bottom of its voxel, a tread at the top of its own). A join
  // needs n + 1 voxels within max_step_m, so the step is surely within it; otherwise a
  // 17 cm riser read as 14 cm (floor noise one voxel up) passed a 15 cm limit.
  const int step_vox = voxels(params.max_step_m, res) - 1;
  if (step_vox < 1) {
    std::ostringstream msg;
    msg << "ReachParams: max_step_m is " << params.max_step_m << " (must be at least two voxels, " << 2 * res
        << " m in this map: tops are known to a voxel, and a floor's tops differ by one)";
    throw std::invalid_argument(msg.str());
  }
  const int gap_vox = voxels(params.max_gap_m, res);
  const auto clearColumn = [&](long kx, long ky, int band_lo, int band_hi) {
    if (!inTree(kx, ky)) return false;
    const auto* col = r.columnAt(kx, ky);
    if (!col) return true;
    for (const std::uint32_t i : *col) {
      if (r.run_bottom_[i] <= band_hi && r.places_[i].key[2] >= band_lo) return false;
    }
    return true;
  };
  std::vector<std::int32_t> region(r.places_.size(), -1);
  std::vector<std::size_t> region_size;
  std::deque<std::uint32_t> queue;
  for (std::size_t seed = 0; seed < r.places_.size(); ++seed) {
    if (!r.places_[seed].standable || region[seed] >= 0) continue;
    const auto label = static_cast<std::int32_t>(region_size.size());
    region_size.push_back(1);
    region[seed] = label;
    queue.push_back(static_cast<std::uint32_t>(seed));
    while (!queue.empty()) {
      const Place& from = r.places_[queue.front()];
      queue.pop_front();
      const int kz = from.key[2];
      for (int dx = -1; dx <= 1; ++dx) {
        for (int dy = -1; dy <= 1; ++dy) {
          if (dx == 0 && dy == 0) continue;
          for (int n = 1; n <= 1 + gap_vox; ++n) {
            const long kx = static_cast<long>(from.key[0]) + n * dx, ky = static_cast<long>(from.key[1]) + n * dy;
            if (!inTree(kx, ky)) break;
            const auto* col = r.columnAt(kx, ky);
            if (!col) continue;  // nothing to land on here; perhaps further on
            for (const std::uint32_t j : *col) {
              const int kz_to = r.places_[j].key[2];
              if (region[j] >= 0 || !r.places_[j].standable || std::abs(kz_to - kz) > step_vox) continue;
              bool clear = true;
              const int band_lo = std::min(kz, kz_to) - step_vox, band_hi = std::max(kz, kz_to) + std::max(step_vox, clear_vox);
              for (int m = 1; m < n && clear; ++m) {
                clear = clearColumn(static_cast<long>(from.key[0]) + m * dx, static_cast<long>(from.key[1]) + m * dy, band_lo, band_hi);
              }
              if (!clear) continue;
              region[j] = label;
              ++region_size[static_cast<std::size_t>(label)];
              queue.push_back(j);
            }
          }
        }
      }
    }
  }

  // The start among the standable places near the start point.
  const long sx = keyOf(start.x(), res), sy = keyOf(start.y(), res);
  const long rad = static_cast<long>(std::ceil(params.start_radius_m / res));
  const double max_top = start.z() + params.max_step_m + 1e-9;
  // kLargestLevel: the height with the most standable places within 4 cm (at least a
  // voxel) of it, the lowest of equals; noise spreads a floor over a few voxels.
  const bool by_level = params.start_rule == ReachParams::Start::kLargestLevel;
  const int level_vox = std::max(1, voxels(0.04, res));
  int level_kz = 0;
  if (by_level) {
    std::vector<std::size_t> below(65537, 0);  // below[k]: standable places with top key < k
    for (const Place& pl : r.places_) below[pl.key[2] + 1u] += pl.standable ? 1 : 0;
    for (std::size_t k = 1; k < below.size(); ++k) below[k] += below[k - 1];
    std::size_t most = 0;
    for (int k = 0; k < 65536; ++k) {
      const std::size_t n = below[static_cast<std::size_t>(std::min(65535, k + level_vox) + 1)] -
                            below[static_cast<std::size_t>(std::max(0, k - level_vox))];
      if (n > most) most = n, level_kz = k;
    }
  }
  // Better: a larger region (on the largest level, if asked), then nearer, then higher.
  std::size_t best_region = 0;
  double best_d2 = std::numeric_limits<double>::infinity(), best_z = -best_d2;
  for (long dx = -rad; dx <= rad; ++dx) {
    for (long dy = -rad; dy <= rad; ++dy) {
      const long kx = sx + dx, ky = sy + dy;
      const auto* col = r.columnAt(kx, ky);
      if (!col) continue;
      for (const std::uint32_t i : *col) {
        const Place& pl = r.places_[i];
        const double d2 = (pl.x - start.x()) * (pl.x - start.x()) + (pl.y - start.y()) * (pl.y - start.y());
        if (!pl.standable || pl.top_z > max_top || d2 > params.start_radius_m * params.start_radius_m + 1e-12) continue;
        if (by_level && std::abs(static_cast<int>(pl.key[2]) - level_kz) > level_vox) continue;
        const std::size_t size = by_level ? region_size[static_cast<std::size_t>(region[i])] : 0;
        const bool better = size > best_region ||
                            (size == best_region && (d2 < best_d2 - 1e-12 || (d2 <= best_d2 + 1e-12 && pl.top_z > best_z)));
        if (better) best_region = size, best_d2 = d2, best_z = pl.top_z, r.start_ = i;
      }
    }
  }
  if (!r.start_) return r;
  const std::int32_t start_region = region[*r.start_];
  for (std::size_t i = 0; i < r.places_.size(); ++i) r.places_[i].reachable = region[i] == start_region;
  r.reachable_ = region_size[static_cast<std::size_t>(start_region)];
  return r;
}

}  // namespace mobmap::mapping
