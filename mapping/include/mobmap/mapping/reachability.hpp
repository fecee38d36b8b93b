#pragma once
/// @file reachability.hpp
/// Which surfaces of a map a legged robot can walk to from where it stands, foot by foot:
/// a place to stand is a whole sole that the surface under it carries (footholds.hpp),
/// and a step joins two soles whose supports differ by at most max_step_m, within a
/// stride, with nothing in the swing's way. A table top is as flat as the floor; only
/// reachability tells them apart.

#include "mobmap/mapping/budget.hpp"
#include "mobmap/mapping/foot.hpp"
#include "mobmap/mapping/footholds.hpp"
#include "mobmap/mapping/levels.hpp"
#include "mobmap/mapping/mobility_octree.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

namespace mobmap::mapping {

/// The robot and where it starts.
struct ReachParams {
  RobotParams robot;
  double start_radius_m = 0.5;  ///< how far around the start point (horizontally) to look for a place to stand
  /// Where to start, among the places a sole can be put near the start point (their
  /// geometry alone decides, so the start does not move when max_step_m or min_mobility
  /// changes).
  enum class Start {
    /// The sole centre nearest the start point (then the highest) with its support at
    /// most 0.1 m above the point; the walk starts from every standable sole within half
    /// a sole length of it at its height: for a point on or just above the robot's footing.
    kNearest,
    /// Every standable sole within start_radius_m on the map's largest level: the height
    /// with the most walkable surface, measured as `mobmap info` measures its walkable
    /// levels (gatherLevels(walkableBins()): the fullest height bin with its two
    /// neighbours). For a camera position whose footing was never seen:
    /// that level is the floor, not a chair seat or table top nearer the camera, even
    /// where the floor was seen too sparsely for many whole soles. A map without a
    /// walkable place falls back to the height with the most sole centres within 4 cm.
    kLargestLevel,
  };
  Start start_rule = Start::kNearest;
};

/// std::invalid_argument naming the field: the robot's (validate(RobotParams)) or start_radius_m.
void validate(const ReachParams& params);

/// A surface: the top voxel of a run of vertically adjacent occupied voxels in one column
/// (the floor, a table top, a stair tread, the top of a wall).
struct Place {
  octomap::OcTreeKey key;     ///< finest-level key of the run's top voxel
  double x = 0, y = 0;        ///< column centre, map frame
  double top_z = 0;           ///< top face of the run, map frame (z up)
  bool has_mobility = false;  ///< the top voxel, or failing that the highest of the run, has a mobility
  double mobility = 0;        ///< meaningful when has_mobility
  double headroom_m = 0;      ///< free or unknown height above the run, up to the next occupied voxel (+inf if none)
  bool standable = false;     ///< a standable sole (some lattice centre and heading) rests on it
  bool reachable = false;     ///< a reachable sole rests on it
};

/// A lattice sole centre on one surface: the soles of every heading there.
struct FootPlace {
  double x = 0, y = 0;  ///< sole centre, map frame
  /// Support height: the mean over the headings whose geometry passes of their support
  /// planes' height at the centre.
  double z = 0;
  std::size_t place = 0;          ///< the surface (index into places()) under the centre
  std::uint8_t geometry_ok = 0;   ///< bit k: heading k (k * 22.5 degrees, or k + 8) passes every limit but mobility
  std::uint8_t standable = 0;     ///< bit k: heading k passes every limit
  float min_mobility = 0;         ///< the best standable heading's lowest mobility under the sole (0 if none)
  bool reachable = false;         ///< standable and joined to the start by steps
  [[nodiscard]] bool isStandable() const { return standable != 0; }
};

/// The answer for one sole: Reachability::sole().
struct SoleReach {
  Foothold foothold;       ///< the sole as judged on the map
  bool standable = false;  ///< foothold.standable()
  /// Standable and one step (max_step_m, max_stride_m, swing clear) from a reachable sole.
  bool reachable = false;
};

/// The level a walk under ReachParams::Start::kLargestLevel started on, and how well its
/// walkable surface near the start carries whole soles: a floor seen from far away (or in
/// few frames) is striped by the sensor's depth steps, so its walkable voxels are many
/// and its soles few.
struct StartLevel {
  double z_m = 0;             ///< its height (map frame), as gatherLevels(walkableBins()) gives it
  std::size_t walkable = 0;   ///< walkable surfaces on it (Level::count)
  double share = 0;           ///< of the map's walkable surfaces (Level::share)
  /// Walkable places (mobility >= kWalkableMobility) within start_radius_m of the start
  /// point, their top face within max(0.05 m, 2 voxels) of z_m (as the start soles).
  std::size_t walkable_near = 0;
  std::size_t standable_near = 0;  ///< of those, the ones under a standable sole
  /// standable_near / walkable_near (0 when nothing walkable is near).
  [[nodiscard]] double carriedShare() const {
    return walkable_near ? static_cast<double>(standable_near) / static_cast<double>(walkable_near) : 0.0;
  }
};

class Reachability;

/// Which lattice soles of a map can be stood on, wherever the robot starts: the part of
/// computeReachability() that does not depend on the start (most of its time), worked
/// out once per map and robot and shared by every walk over them (ReachCache).
/// Immutable; safe to query from several threads.
class Standability {
 public:
  /// Every surface; `standable` set, `reachable` false.
  [[nodiscard]] const std::vector<Place>& places() const { return places_; }
  /// Every lattice sole centre whose geometry passes for some heading; `reachable` false.
  [[nodiscard]] const std::vector<FootPlace>& footPlaces() const { return feet_; }
  [[nodiscard]] const RobotParams& robot() const { return robot_; }
  [[nodiscard]] double resolution() const { return columns_->resolution(); }
  [[nodiscard]] const SurfaceColumns& columns() const { return *columns_; }
  [[nodiscard]] std::shared_ptr<const SurfaceColumns> sharedColumns() const { return columns_; }
  /// Foot places whose centres lie within `radius_m` of (x, y), horizontally.
  [[nodiscard]] std::vector<std::size_t> footPlacesNear(double x, double y, double radius_m) const;
  /// Surfaces (places) under a standable sole.
  [[nodiscard]] std::size_t standableCount() const { return standable_; }
  /// Bytes this holds, the columns not included (they belong to the map).
  [[nodiscard]] std::size_t memoryBytes() const;

 private:
  friend std::shared_ptr<const Standability> computeStandability(std::shared_ptr<const SurfaceColumns>, const RobotParams&,
                                                                const Budget&);
  friend Reachability computeReachability(std::shared_ptr<const Standability>, const Eigen::Vector3d&, const ReachParams&,
                                          const Budget&);
  RobotParams robot_;
  std::shared_ptr<const SurfaceColumns> columns_;
  std::vector<Place> places_;  ///< one per run of columns_, same index
  std::vector<FootPlace> feet_;
  long lattice_ = 1, lx0_ = 0, ly0_ = 0, lnx_ = 0, lny_ = 0;  ///< lattice step (voxels) and extent (lattice cells)
  std::vector<std::uint32_t> feet_offsets_;  ///< per lattice cell, into feet_
  /// Per foot place, the columns around its centre ((2 reach + 1)^2, row by row) that
  /// carry one of its standable soles: what a reachable foot marks reachable.
  long mask_reach_ = 0;
  std::size_t mask_words_ = 0;
  std::vector<std::uint64_t> support_masks_;
  std::size_t standable_ = 0;
};

/// The result of computeReachability(). Immutable; safe to query from several threads.
class Reachability {
 public:
  [[nodiscard]] const std::vector<Place>& places() const { return places_; }
  [[nodiscard]] const std::vector<FootPlace>& footPlaces() const { return feet_; }
  [[nodiscard]] const ReachParams& params() const { return params_; }
  [[nodiscard]] double resolution() const { return standing_ ? standing_->resolution() : 0.0; }
  /// The foot place the walk is reported to start from (index into footPlaces()): the
  /// nearest of the start soles; nullopt when there was no standable sole to start on
  /// (then nothing is reachable).
  [[nodiscard]] std::optional<std::size_t> start() const { return start_; }
  /// The level the walk started on, under Start::kLargestLevel when some place is
  /// walkable; nullopt otherwise.
  [[nodiscard]] const std::optional<StartLevel>& startLevel() const { return start_level_; }
  /// Surfaces (places) under a standable / a reachable sole.
  [[nodiscard]] std::size_t standableCount() const { return standing_ ? standing_->standableCount() : 0; }
  [[nodiscard]] std::size_t reachableCount() const { return reachable_; }
  /// The highest place in the column of `p_map` whose top face is at or below p's height
  /// plus half a voxel and no lower than `max_drop_m` below p.z; nullptr if none.
  [[nodiscard]] const Place* placeBelow(const Eigen::Vector3d& p_map, double max_drop_m) const;
  /// The place whose run's top voxel is `key`; nullptr if that voxel is not a run's top.
  [[nodiscard]] const Place* placeAt(const octomap::OcTreeKey& key) const;
  /// Judges `foot` (its z: the height to look for the surface, searched from search_up_m
  /// above to search_down_m below) as a place to stand, and whether one step from a
  /// reachable sole gets there.
  [[nodiscard]] SoleReach sole(const Foot& foot, double search_up_m = 0.1, double search_down_m = 0.1) const;
  /// The surface runs the map is made of (shared with the planner).
  [[nodiscard]] const SurfaceColumns& columns() const { return standing_->columns(); }
  [[nodiscard]] std::shared_ptr<const SurfaceColumns> sharedColumns() const { return standing_->sharedColumns(); }
  /// What the walk was worked out over (shared with other walks of the same robot).
  [[nodiscard]] std::shared_ptr<const Standability> standability() const { return standing_; }
  /// Foot places whose centres lie within `radius_m` of (x, y), horizontally.
  [[nodiscard]] std::vector<std::size_t> footPlacesNear(double x, double y, double radius_m) const;
  /// The standable foot places the walk started from (all reachable).
  [[nodiscard]] const std::vector<std::size_t>& startFeet() const { return start_feet_; }
  /// Bytes this result holds, what it shares (its Standability and columns) included.
  [[nodiscard]] std::size_t memoryBytes() const;

 private:
  friend Reachability computeReachability(std::shared_ptr<const Standability>, const Eigen::Vector3d&, const ReachParams&,
                                          const Budget&);
  ReachParams params_;
  std::shared_ptr<const Standability> standing_;
  std::vector<Place> places_;  ///< one per run of the columns, same index
  std::vector<FootPlace> feet_;
  std::optional<std::size_t> start_;
  std::vector<std::size_t> start_feet_;
  std::optional<StartLevel> start_level_;
  std::size_t reachable_ = 0;
};

/// Judges every lattice sole of the map as a place to stand for `robot` (the start-free
/// part of computeReachability). std::invalid_argument for invalid params (a max_step_m
/// under two voxels too); std::length_error if the map spans more than 2^26 columns;
/// BudgetExceeded when `budget` runs out first.
[[nodiscard]] std::shared_ptr<const Standability> computeStandability(std::shared_ptr<const SurfaceColumns> columns,
                                                                      const RobotParams& robot, const Budget& budget = {});

/// Finds every place of `tree`, every lattice sole that can be stood on, and which of them
/// the robot can walk to from `start_map` (params.start_rule). Map frame, z up.
/// std::invalid_argument for invalid params (a max_step_m under two voxels too) or a
/// non-finite start; std::length_error if the map spans more than 2^26 columns;
/// BudgetExceeded when `budget` runs out first (a 60 x 60 m map at 2 cm takes tens of seconds).
[[nodiscard]] Reachability computeReachability(const MobilityOcTree& tree, const Eigen::Vector3d& start_map,
                                               const ReachParams& params = {}, const Budget& budget = {});
/// The same over columns already made from the map (the planner shares them).
[[nodiscard]] Reachability computeReachability(std::shared_ptr<const SurfaceColumns> columns,
                                               const Eigen::Vector3d& start_map, const ReachParams& params = {},
                                               const Budget& budget = {});
/// The walk alone, over soles already judged for params.robot (std::invalid_argument when
/// `standing` was judged for another robot).
[[nodiscard]] Reachability computeReachability(std::shared_ptr<const Standability> standing,
                                               const Eigen::Vector3d& start_map, const ReachParams& params = {},
                                               const Budget& budget = {});

/// Standability and reachability kept per map (its SurfaceColumns, by identity) and
/// robot, and walks per start, so that `reach`, layers, the planner and the server work
/// each out once per map snapshot and parameter set. Least recently used entries go when
/// the bytes held pass the bound (the newest entry always stays), and so do entries
/// whose map no caller holds any more. Safe to use from several threads; a result is
/// computed outside the lock (two threads asking at once may both compute it).
class ReachCache {
 public:
  explicit ReachCache(std::size_t max_bytes = std::size_t{256} << 20);
  ReachCache(const ReachCache&) = delete;
  ReachCache& operator=(const ReachCache&) = delete;
  ~ReachCache();

  /// computeStandability(columns, robot, budget), or the one kept.
  [[nodiscard]] std::shared_ptr<const Standability> standability(const std::shared_ptr<const SurfaceColumns>& columns,
                                                                 const RobotParams& robot, const Budget& budget = {});
  /// computeReachability(columns, start_map, params, budget), or the one kept for the same
  /// map, params and start point.
  [[nodiscard]] std::shared_ptr<const Reachability> reachability(const std::shared_ptr<const SurfaceColumns>& columns,
                                                                 const Eigen::Vector3d& start_map, const ReachParams& params,
                                                                 const Budget& budget = {});
  /// The kept walk for these, if any (never computes).
  [[nodiscard]] std::shared_ptr<const Reachability> findReachability(const std::shared_ptr<const SurfaceColumns>& columns,
                                                                     const Eigen::Vector3d& start_map,
                                                                     const ReachParams& params) const;
  struct Stats {
    std::size_t bytes = 0, entries = 0, hits = 0, misses = 0, evictions = 0;
  };
  [[nodiscard]] Stats stats() const;
  void clear();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mobmap::mapping
