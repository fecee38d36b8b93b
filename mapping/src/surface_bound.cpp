#include "surface_bound.hpp"

#include "reach_detail.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <queue>
#include <utility>

namespace mobmap::mapping::detail {
namespace {

constexpr double kOctile = 1.0824;  // 1 / cos(22.5 degrees): octile over Euclidean length, at most
constexpr std::uint64_t kOne = 1;

// Bits lo..hi of a 64-bit mask (clamped to 0..63; none when hi < lo).
std::uint64_t bitRange(long lo, long hi) {
  lo = std::max(lo, 0L), hi = std::min(hi, 63L);
  if (hi < lo) return 0;
  const std::uint64_t upto = hi == 63 ? ~std::uint64_t{0} : (kOne << (hi + 1)) - 1;
  return upto & ~((kOne << lo) - 1);
}

int popcount(std::uint64_t v) { return __builtin_popcountll(v); }

// For 2 x 2-column cells: every state of a block of 2 x 2 cells (4 x 4 columns, bit
// x * 4 + y) and whether open columns join its cell (0, 0) to (1, 1) (main diagonal) or
// its cell (0, 1) to (1, 0) (anti-diagonal), 8-adjacent.
struct BlockTables {
  std::vector<std::uint8_t> main, anti;  // one bit per state
  BlockTables() : main(1u << 13), anti(1u << 13) {
    for (std::uint32_t state = 0; state < (1u << 16); ++state) {
      if (joins(state, 0, 0, 1, 1)) main[state >> 3] |= static_cast<std::uint8_t>(1u << (state & 7u));
      if (joins(state, 0, 1, 1, 0)) anti[state >> 3] |= static_cast<std::uint8_t>(1u << (state & 7u));
    }
  }
  static bool joins(std::uint32_t state, int fx, int fy, int tx, int ty) {
    std::array<bool, 16> seen{};
    std::array<int, 16> queue{};
    int head = 0, tail = 0;
    for (int x = 2 * fx; x < 2 * fx + 2; ++x) {
      for (int y = 2 * fy; y < 2 * fy + 2; ++y) {
        if (state >> (x * 4 + y) & 1u) seen[static_cast<std::size_t>(x * 4 + y)] = true, queue[static_cast<std::size_t>(tail++)] = x * 4 + y;
      }
    }
    while (head < tail) {
      const int q = queue[static_cast<std::size_t>(head++)], x = q / 4, y = q % 4;
      if (x / 2 == tx && y / 2 == ty) return true;
      for (int dx = -1; dx <= 1; ++dx) {
        for (int dy = -1; dy <= 1; ++dy) {
          const int nx = x + dx, ny = y + dy;
          if (nx < 0 || ny < 0 || nx >= 4 || ny >= 4) continue;
          const int n = nx * 4 + ny;
          if (!(state >> n & 1u) || seen[static_cast<std::size_t>(n)]) continue;
          seen[static_cast<std::size_t>(n)] = true;
          queue[static_cast<std::size_t>(tail++)] = n;
        }
      }
    }
    return false;
  }
};

}  // namespace

SurfaceBound::SurfaceBound(const SurfaceColumns& cols, const RobotParams& robot, long s, const Eigen::Vector3d& goal,
                           double z_goal, double tolerance, double goal_slack, const std::vector<std::size_t>& roots, double beyond,
                           const Budget& budget)
    : cols_(cols), s_(s), cell_m_(s * cols.resolution()) {
  const double res = cols.resolution();
  m_ = robot.max_step_m - res;  // the largest rise between successive soles (stepHeightOk)
  above_ = robot.swing_clearance_m;
  leg_ = swingLegTop(robot);
  off_top_ = soleOffTop(robot, res);
  // (b): a step whose lower sole is at `lo` finds surface in a column whose top t lies in
  // [lo - max_step_m - res, lo + m + swing_clearance_m], i.e. lo in [t - support_lo_, t + support_hi_].
  support_lo_ = m_ + above_ + 1e-6;
  support_hi_ = robot.max_step_m + res + 1e-6;
  // A sample without surface lies within max_gap_m (and half a voxel of sampling) of one
  // with it along the centre line: its cell within dilate_ cells of that one's.
  dilate_ = static_cast<long>(std::ceil((robot.max_gap_m + res) / cell_m_)) + 1;
  const long margin = dilate_ + 1;
  i0_ = floorDiv(cols.keyX0(), s_) - margin;
  j0_ = floorDiv(cols.keyY0(), s_) - margin;
  ni_ = floorDiv(cols.keyX0() + cols.columnsX() - 1, s_) + margin - i0_ + 1;
  nj_ = floorDiv(cols.keyY0() + cols.columnsY() - 1, s_) + margin - j0_ + 1;
  double zmin = std::numeric_limits<double>::infinity(), zmax = -zmin;
  for (const auto& r : cols.runs()) zmin = std::min(zmin, cols.topFace(r)), zmax = std::max(zmax, cols.topFace(r));
  if (cols.runs().empty()) zmin = zmax = 0;
  const double below = std::max(support_lo_, off_top_ + m_) + 1e-3, over = std::max(support_hi_, off_top_) + 1e-3;
  bucket_m_ = std::max(0.1, (zmax + over - (zmin - below)) / 62.0);
  z0_ = zmin - below - 0.5 * bucket_m_;
  nb_ = bucketOf(zmax + over) + 1;
  const auto n = static_cast<std::size_t>(ni_) * static_cast<std::size_t>(nj_);
  cell_of_.assign(n, -1);
  // Every cell's levels with surface for a swing (b), then spread over dilate_ cells each
  // way (rows, then columns).
  {
    std::vector<std::uint64_t> raw(n, 0);
    for (long col = 0; col < cols.columnsX() * cols.columnsY(); ++col) {
      if (cols.runBegin(col) == cols.runEnd(col)) continue;
      const long kx = cols.keyX0() + col / cols.columnsY(), ky = cols.keyY0() + col % cols.columnsY();
      std::uint64_t bits = 0;
      for (std::size_t r = cols.runBegin(col); r < cols.runEnd(col); ++r) {
        const double t = cols.topFace(cols.runs()[r]);
        bits |= bitRange(bucketOf(t - support_lo_), bucketOf(t + support_hi_));
      }
      raw[static_cast<std::size_t>(cellIndex(floorDiv(kx, s_), floorDiv(ky, s_)))] |= bits;
    }
    budget.check("planFootsteps");
    std::vector<std::uint64_t> rows(n, 0);
    for (long i = 0; i < ni_; ++i) {
      for (long j = 0; j < nj_; ++j) {
        std::uint64_t v = 0;
        for (long d = std::max(0L, i - dilate_); d <= std::min(ni_ - 1, i + dilate_); ++d) v |= raw[static_cast<std::size_t>(d * nj_ + j)];
        rows[static_cast<std::size_t>(i * nj_ + j)] = v;
      }
    }
    support_.assign(n, 0);
    for (long i = 0; i < ni_; ++i) {
      for (long j = 0; j < nj_; ++j) {
        std::uint64_t v = 0;
        for (long d = std::max(0L, j - dilate_); d <= std::min(nj_ - 1, j + dilate_); ++d) v |= rows[static_cast<std::size_t>(i * nj_ + d)];
        support_[static_cast<std::size_t>(i * nj_ + j)] = v;
      }
    }
  }
  // The start soles' cells and level buckets.
  struct RootCell {
    long i, j, lo, hi;
  };
  std::vector<RootCell> root_cells;
  for (const std::size_t root : roots) {
    const auto [i, j] = cellOfRun(root);
    root_cells.push_back({i, j, bucketOf(window(root).first), bucketOf(window(root).second)});
  }
  // The node of levels b.. of cell (i, j) holds a start sole.
  const auto isRoot = [&](long i, long j, long b) {
    return std::any_of(root_cells.begin(), root_cells.end(), [&](const RootCell& r) {
      return r.i == i && r.j == j && b <= r.hi && endOf(cell(i, j), b) >= r.lo;
    });
  };
  struct Item {
    double key, dist;
    std::uint32_t node;
    std::int32_t i, j, b;
    bool operator>(const Item& o) const { return key > o.key || (key == o.key && dist < o.dist); }
  };
  if (!root_cells.empty()) si_ = root_cells.front().i, sj_ = root_cells.front().j;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
  // Reaches the component of bucket b of cell (i, j) (made, b one of its nodes) at distance d.
  const auto push = [&](long i, long j, long b, double d) {
    const Cell c = cells_[static_cast<std::size_t>(cell_of_[static_cast<std::size_t>(cellIndex(i, j))])];
    const auto k = static_cast<std::uint32_t>(nodeOf(c, b));
    Node& node = nodes_[k];
    if (node.closed || node.dist <= d) return;
    node.dist = d;
    queue.push({d + toStart(i, j), d, k, static_cast<std::int32_t>(i), static_cast<std::int32_t>(j), static_cast<std::int32_t>(startOf(c, b))});
  };
  // The goal: a sole within the tolerance, the last step's lower sole below it by at most m.
  const long r = static_cast<long>(std::ceil(tolerance / cell_m_)) + 1;
  const long gi = floorDiv(cols.keyOf(goal.x()), s_), gj = floorDiv(cols.keyOf(goal.y()), s_);
  for (long i = gi - r; i <= gi + r; ++i) {
    for (long j = gj - r; j <= gj + r; ++j) {
      if (cellIndex(i, j) < 0) continue;
      if (std::hypot(cols.centreOf(i * s_) - goal.x(), cols.centreOf(j * s_) - goal.y()) > tolerance + 1e-9) continue;
      const std::uint64_t nodes = cell(i, j).nodes;
      for (long b = std::max(0L, bucketOf(z_goal - goal_slack - m_)); b <= std::min(nb_ - 1, bucketOf(z_goal + goal_slack)); ++b) {
        if (nodes >> b & 1u) push(i, j, b, 0.0);
      }
    }
  }
  // No goal node (the caller's goal has no sole here): no bound, and no claim either.
  if (queue.empty()) return;
  const double diagonal = cell_m_ * std::sqrt(2.0), side = cell_m_;
  double stop_at = std::numeric_limits<double>::infinity();
  while (!queue.empty()) {
    const Item it = queue.top();
    if (it.key > stop_at) break;
    queue.pop();
    Node& node = nodes_[it.node];
    if (node.closed || it.dist > node.dist) continue;
    node.closed = 1;
    settled_ = it.key;
    if ((++settled_count_ & 4095u) == 0) budget.check("planFootsteps");
    const long i = it.i, j = it.j, b = it.b;
    const double d = it.dist;
    if (!met_start_ && isRoot(i, j, b)) {
      met_start_ = true;
      stop_at = std::max(it.key, 1e-3) * beyond;
    }
    // Across, at each level of the component, to the component of that level next door.
    const Cell c = cells_[static_cast<std::size_t>(cell_of_[static_cast<std::size_t>(cellIndex(i, j))])];
    const long e = endOf(c, b);
    for (long level = b; level <= e; ++level) {
      if (!openColumns(i, j, level)) continue;
      for (int di = -1; di <= 1; ++di) {
        for (int dj = -1; dj <= 1; ++dj) {
          if ((di || dj) && moveOpen(i, j, di, dj, level)) push(i + di, j + dj, level, d + (di && dj ? diagonal : side));
        }
      }
    }
  }
  exhausted_ = queue.empty();
}

long SurfaceBound::bucketOf(double z) const { return static_cast<long>(std::floor((z - z0_) / bucket_m_)); }

long SurfaceBound::cellIndex(long i, long j) const {
  if (i < i0_ || j < j0_ || i >= i0_ + ni_ || j >= j0_ + nj_) return -1;
  return (i - i0_) * nj_ + (j - j0_);
}

// The lattice cell of a run's column.
std::pair<long, long> SurfaceBound::cellOfRun(std::size_t run) const {
  const long c = cols_.runColumn(run);
  return {floorDiv(cols_.keyX0() + c / cols_.columnsY(), s_), floorDiv(cols_.keyY0() + c % cols_.columnsY(), s_)};
}

// The octile distance from cell (i, j) to the first start sole's.
double SurfaceBound::toStart(long i, long j) const {
  const long a = std::abs(i - si_), b = std::abs(j - sj_);
  return cell_m_ * (static_cast<double>(std::max(a, b) - std::min(a, b)) + std::sqrt(2.0) * static_cast<double>(std::min(a, b)));
}

// The levels [lo, hi] of a step from a standable sole on `run` (at its lattice column):
// the sole lies within soleOffTop() of the run's top, the step's lower sole at most m below.
std::pair<double, double> SurfaceBound::window(std::size_t run) const {
  const double top = cols_.topFace(cols_.runs()[run]);
  return {top - off_top_ - m_, top + off_top_};
}

SurfaceBound::Cell& SurfaceBound::cell(long i, long j) {
  const long k = cellIndex(i, j);
  std::int32_t& slot = cell_of_[static_cast<std::size_t>(k)];
  if (slot >= 0) return cells_[static_cast<std::size_t>(slot)];
  Cell c;
  c.support = support_[static_cast<std::size_t>(k)];
  // The levels of a step from a sole here (its lower sole at most m below the sole) and
  // where a sole here may go between levels.
  std::uint64_t feet = 0;
  const long col = cols_.columnIndex(i * s_, j * s_);
  for (std::size_t r = cols_.runBegin(col); r < cols_.runEnd(col); ++r) {
    const auto [lo, hi] = window(r);
    feet |= bitRange(bucketOf(lo), bucketOf(hi));
    // Between buckets b and b + 1 (their boundary zb = z0 + (b + 1) B): a sole at z with
    // both levels in [z - m, z]: zb in [lo, hi].
    c.vertical |= bitRange(static_cast<long>(std::ceil((lo - z0_) / bucket_m_)) - 1, static_cast<long>(std::floor((hi - z0_) / bucket_m_)) - 1);
  }
  c.nodes = c.support | feet;
  // Levels joined by free moves up and down make one node: b and b + 1 both levels here
  // and a sole can go between them.
  c.joined = c.nodes & (c.nodes << 1) & (c.vertical << 1);
  c.first = static_cast<std::uint32_t>(nodes_.size());
  nodes_.resize(nodes_.size() + static_cast<std::size_t>(popcount(c.nodes & ~c.joined)), Node{std::numeric_limits<double>::infinity(), 0});
  c.first_open = static_cast<std::uint32_t>(opens_.size());
  opens_.resize(opens_.size() + static_cast<std::size_t>(popcount(c.nodes)), kUnknown);
  slot = static_cast<std::int32_t>(cells_.size());
  cells_.push_back(c);
  return cells_.back();
}

long SurfaceBound::nodeOf(const Cell& c, long b) const {
  const std::uint64_t upto = b >= 63 ? ~std::uint64_t{0} : (kOne << (b + 1)) - 1;
  return static_cast<long>(c.first) + popcount(c.nodes & ~c.joined & upto) - 1;
}

long SurfaceBound::startOf(const Cell& c, long b) const {
  const std::uint64_t starts = c.nodes & ~c.joined & (b >= 63 ? ~std::uint64_t{0} : (kOne << (b + 1)) - 1);
  return 63 - __builtin_clzll(starts);
}

long SurfaceBound::endOf(const Cell& c, long b) const {
  long e = b;
  while (e + 1 < 64 && (c.joined >> (e + 1) & 1u)) ++e;
  return e;
}

// The columns of cell (i, j) a swing at level bucket b may cross: the cell has surface
// for it near (b), and the column leaves part of the bucket free of (a): a run
// [bottom, top] blocks the levels in (bottom - leg, top - m - swing_clearance_m).
std::uint32_t SurfaceBound::openColumns(long i, long j, long b) {
  if (b < 0 || b >= nb_ || cellIndex(i, j) < 0) return 0;
  const Cell c = cell(i, j);
  if (!(c.support >> b & 1u)) return 0;
  const auto slot = static_cast<std::size_t>(c.first_open) + static_cast<std::size_t>(popcount(c.nodes & ((kOne << b) - 1)));
  if (opens_[slot] != kUnknown) return opens_[slot];
  const double lo = z0_ + b * bucket_m_, hi = lo + bucket_m_;
  std::uint32_t out = 0;
  for (long x = 0; x < s_; ++x) {
    for (long y = 0; y < s_; ++y) {
      const long col = cols_.columnIndex(i * s_ + x, j * s_ + y);  // -1 beside the map: no runs, open
      double free_from = lo;                                       // the lowest level not known blocked
      for (std::size_t r = cols_.runBegin(col); r < cols_.runEnd(col); ++r) {
        // Blocked strictly between; a micron narrower, so rounding never closes a level
        // the swing check lets pass.
        const double a = cols_.bottomFace(cols_.runs()[r]) - leg_ + 1e-6;
        const double e = cols_.topFace(cols_.runs()[r]) - m_ - above_ - 1e-6;
        if (e <= a) continue;
        if (a >= free_from) break;
        free_from = std::max(free_from, e);
        if (free_from > hi) break;
      }
      if (free_from <= hi) out |= 1u << (x * s_ + y);
    }
  }
  opens_[slot] = out;
  return out;
}

// A swing's chain of columns can pass from cell (i, j) to (i + di, j + dj) at level b:
// open columns of the two 8-adjacent (a side), or joined through open columns of the
// 2 x 2 cells around the corner (a diagonal).
bool SurfaceBound::moveOpen(long i, long j, int di, int dj, long b) {
  const std::uint32_t a = openColumns(i, j, b), c = openColumns(i + di, j + dj, b);
  if (!a || !c) return false;
  if (s_ == 1) return true;
  const long bi = std::min(i, i + di), bj = std::min(j, j + dj);
  if (s_ == 2) {
    if (!di || !dj) {
      // Sides: the facing rows (or columns) of the two cells, 8-adjacent.
      std::uint32_t near_a, near_c;
      if (di) {
        near_a = di > 0 ? a >> 2 : a & 3u, near_c = di > 0 ? c & 3u : c >> 2;
      } else {
        near_a = dj > 0 ? ((a >> 1) & 1u) | ((a >> 2) & 2u) : (a & 1u) | ((a >> 1) & 2u);
        near_c = dj > 0 ? (c & 1u) | ((c >> 1) & 2u) : ((c >> 1) & 1u) | ((c >> 2) & 2u);
      }
      return ((near_a | (near_a << 1) | (near_a >> 1)) & near_c & 3u) != 0;
    }
    static const BlockTables tables;
    std::uint32_t state = 0;
    for (long ci = 0; ci < 2; ++ci) {
      for (long cj = 0; cj < 2; ++cj) {
        const std::uint32_t mask = (bi + ci == i && bj + cj == j)             ? a
                                   : (bi + ci == i + di && bj + cj == j + dj) ? c
                                                                              : openColumns(bi + ci, bj + cj, b);
        for (long x = 0; x < 2; ++x) {
          for (long y = 0; y < 2; ++y) {
            if (mask >> (x * 2 + y) & 1u) state |= 1u << ((ci * 2 + x) * 4 + cj * 2 + y);
          }
        }
      }
    }
    const auto& t = (di > 0) == (dj > 0) ? tables.main : tables.anti;
    return t[state >> 3] >> (state & 7u) & 1u;
  }
  // Larger cells: breadth first over the block's open columns.
  const long w = 2 * s_;
  std::array<std::uint8_t, 64> open{}, seen{};
  const auto fill = [&](long ci, long cj, std::uint32_t bits, std::uint8_t mark) {
    for (long x = 0; x < s_; ++x) {
      for (long y = 0; y < s_; ++y) {
        if (bits >> (x * s_ + y) & 1u) open[static_cast<std::size_t>(((ci - bi) * s_ + x) * w + (cj - bj) * s_ + y)] = mark;
      }
    }
  };
  fill(i, j, a, 1);
  fill(i + di, j + dj, c, 2);
  if (di && dj) {
    fill(i + di, j, openColumns(i + di, j, b), 3);
    fill(i, j + dj, openColumns(i, j + dj, b), 3);
  }
  std::array<std::uint8_t, 64> queue{};
  std::size_t head = 0, tail = 0;
  for (std::size_t q = 0; q < static_cast<std::size_t>(w * w); ++q) {
    if (open[q] == 1) seen[q] = 1, queue[tail++] = static_cast<std::uint8_t>(q);
  }
  while (head < tail) {
    const long q = queue[head++], x = q / w, y = q % w;
    for (long dx = -1; dx <= 1; ++dx) {
      for (long dy = -1; dy <= 1; ++dy) {
        const long nx = x + dx, ny = y + dy;
        if (nx < 0 || ny < 0 || nx >= w || ny >= w) continue;
        const auto n = static_cast<std::size_t>(nx * w + ny);
        if (!open[n] || seen[n]) continue;
        if (open[n] == 2) return true;
        seen[n] = 1;
        queue[tail++] = static_cast<std::uint8_t>(n);
      }
    }
  }
  return false;
}

double SurfaceBound::metres(std::size_t run) {
  const auto [i, j] = cellOfRun(run);
  if (cellIndex(i, j) < 0) return 0.0;
  const Cell c = cell(i, j);
  const auto [lo, hi] = window(run);
  double best = std::numeric_limits<double>::infinity();
  bool any = false;
  // A node not settled is at least as far as the last key settled minus its octile
  // distance to the start.
  const double unsettled = exhausted_ ? std::numeric_limits<double>::infinity()
                                      : std::max(0.0, settled_ - toStart(i, j) - 1e-9);
  for (long b = std::max(0L, bucketOf(lo)); b <= std::min(nb_ - 1, bucketOf(hi)); ++b) {
    if (!(c.nodes >> b & 1u)) continue;
    const Node& node = nodes_[static_cast<std::size_t>(nodeOf(c, b))];
    best = std::min(best, node.closed ? node.dist : unsettled);
    any = true;
    b = endOf(c, b);
  }
  if (!any) return 0.0;  // its levels lie outside the graph's (not expected): no bound
  if (!std::isfinite(best)) return best;
  // Rounding of the sums: a millionth less.
  return best * (1.0 - 1e-6) / kOctile;
}

std::size_t SurfaceBound::bytes() const {
  return cell_of_.capacity() * sizeof(std::int32_t) + cells_.capacity() * sizeof(Cell) + nodes_.capacity() * sizeof(Node) +
         opens_.capacity() * sizeof(std::uint32_t) + support_.capacity() * sizeof(std::uint64_t);
}

}  // namespace mobmap::mapping::detail
