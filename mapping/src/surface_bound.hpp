#pragma once
// The footstep planner's map-aware heuristic: a lower bound on the horizontal strides'
// sum from a sole to the goal that knows walls, drops and levels (docs/MAPPING.md,
// "Reachability and footsteps").
#include "mobmap/mapping/budget.hpp"
#include "mobmap/mapping/footholds.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace mobmap::mapping::detail {

/// A step's level is the height of its lower sole. swingProblem() lets a step at level L
/// (its higher sole at most m = max_step_m - one voxel above) pass only where, along the
/// centre line sampled at half a voxel, (a) no run rises above L + m + swing_clearance_m
/// with its bottom below L + swingLegTop(), and (b) every column has a top in
/// [L - max_step_m - one voxel, L + m + swing_clearance_m], but for gaps of at most
/// max_gap_m. The samples' columns make an 8-connected, monotone chain of lattice cells
/// (s x s columns, the lattice column first) from one sole's cell to the other's, at most
/// 1.0824 times the stride long in octile steps; each passes (a) at L and lies within
/// `dilate_` cells of a cell with a column that passes (b) at L.
///
/// The graph: a node is a cell with a range of levels (0.1 m buckets; coarser where the
/// map's surfaces span more than ~5.5 m, so that 62 buckets cover them). Moves: to a neighbouring cell at one level where a chain can pass
/// (open columns 8-adjacent, or joined through the two cells beside a corner), costing
/// the cells' distance; between levels at a cell for free, where a sole on a surface of
/// its lattice column can be the higher sole of a step at one level and the lower or
/// higher of the next (window()). Levels joined so are one node. Every footstep sequence
/// maps to a path no longer than 1.0824 times its strides' sum, so the distance to the
/// goal / 1.0824 is an admissible bound on the strides' sum, and a step lowers it by at
/// most its stride (consistent).
///
/// The distances are found from the goal, towards the first start sole (A*: key =
/// distance + octile distance to it), until a node of a start sole is settled and then
/// every node up to `beyond` times its key. A node left unsettled is at least as far as
/// the last key settled minus its octile distance to the start (still consistent: the
/// octile distance changes by at most a move's length). When the search runs out before
/// meeting a start sole, no footstep sequence joins the start and the goal.
class SurfaceBound {
 public:
  /// `roots`: the runs the start soles rest on (at their lattice columns).
  SurfaceBound(const SurfaceColumns& cols, const RobotParams& robot, long s, const Eigen::Vector3d& goal, double z_goal,
               double tolerance, double goal_slack, const std::vector<std::size_t>& roots, double beyond, const Budget& budget);

  /// Lattice steps of 1..4 voxels (a cell's columns fit 16 bits).
  static bool handles(long s) { return s >= 1 && s <= 4; }

  /// Metres: at most the strides' sum of any footstep sequence to the goal from a sole
  /// on `run` (at its lattice column); +inf when none can get there.
  [[nodiscard]] double metres(std::size_t run);
  /// The search ran out before it met the start: no footstep sequence from the start
  /// reaches the goal.
  [[nodiscard]] bool startCutOff() const { return exhausted_ && !met_start_; }
  [[nodiscard]] std::size_t bytes() const;
  [[nodiscard]] std::size_t settledNodes() const { return settled_count_; }

 private:
  struct Cell {
    std::uint64_t nodes = 0;     ///< levels (bit b: bucket b) it has
    std::uint64_t joined = 0;    ///< bit b: level b joined to b - 1 (one node)
    std::uint64_t support = 0;   ///< levels where a swing finds surface near (b), within max_gap_m
    std::uint64_t vertical = 0;  ///< bit b: a sole can go between levels b and b + 1 here
    std::uint32_t first = 0;     ///< its first node in nodes_ (one per run of joined levels)
    std::uint32_t first_open = 0;  ///< its first level's open columns in opens_
  };
  struct Node {
    double dist = 0;
    std::uint8_t closed = 0;
  };
  static constexpr std::uint32_t kUnknown = 0xffffffffu;

  [[nodiscard]] long bucketOf(double z) const;
  [[nodiscard]] long cellIndex(long i, long j) const;
  Cell& cell(long i, long j);
  [[nodiscard]] long nodeOf(const Cell& c, long b) const;   ///< the node of level b (one of c's)
  [[nodiscard]] long startOf(const Cell& c, long b) const;  ///< the lowest level of b's node
  [[nodiscard]] long endOf(const Cell& c, long b) const;    ///< the highest level of b's node
  std::uint32_t openColumns(long i, long j, long b);
  bool moveOpen(long i, long j, int di, int dj, long b);
  [[nodiscard]] std::pair<double, double> window(std::size_t run) const;
  [[nodiscard]] double toStart(long i, long j) const;
  [[nodiscard]] std::pair<long, long> cellOfRun(std::size_t run) const;

  const SurfaceColumns& cols_;
  long s_;
  double cell_m_;
  double m_ = 0, above_ = 0, leg_ = 0, off_top_ = 0, support_lo_ = 0, support_hi_ = 0;
  double z0_ = 0, bucket_m_ = 0.1;
  long nb_ = 0;
  long i0_ = 0, j0_ = 0, ni_ = 0, nj_ = 0, dilate_ = 0;
  std::vector<std::int32_t> cell_of_;  ///< per grid cell, into cells_ (-1: not made yet)
  std::vector<Cell> cells_;
  std::vector<Node> nodes_;
  std::vector<std::uint32_t> opens_;  ///< per level of a made cell, openColumns() (kUnknown: not yet)
  std::vector<std::uint64_t> support_;  ///< per grid cell, Cell::support
  long si_ = 0, sj_ = 0;  ///< the first start sole's cell
  double settled_ = 0;    ///< the last key settled (distance + octile distance to the start)
  bool exhausted_ = false, met_start_ = false;
  std::size_t settled_count_ = 0;
};

}  // namespace mobmap::mapping::detail
