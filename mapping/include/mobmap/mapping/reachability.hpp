#pragma once
/// @file reachability.hpp
/// Which walkable surfaces of a map a legged robot can get to from where it stands,
/// stepping no higher than it can climb. Mobility says whether a surface can be stood
/// on; a table top is as flat as the floor, and only reachability tells them apart.

#include "mobmap/mapping/foot.hpp"
#include "mobmap/mapping/mobility_octree.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <unordered_map>
#include <vector>

namespace mobmap::mapping {

/// What the robot can do, units in the names.
struct ReachParams {
  /// Largest rise or drop between neighbouring places (stairs: 0.15-0.18). Tops are voxel
  /// faces, so tops n voxels apart are joined only if n + 1 voxels are within this: the
  /// true step is then surely within it (at 2 cm, 0.15 joins tops up to 12 cm apart).
  /// At least two voxels.
  double max_step_m = 0.15;
  double min_mobility = 0.5;    ///< a place can be stood on when its fused mobility is at least this
  /// Height above a place that must hold no occupied voxel (the robot's height); 0 does
  /// not check. Unknown space counts as free: the map only knows what it has seen.
  double clearance_m = 0.0;
  /// Columns with no occupied voxel near the walking height (holes the sensor did not
  /// fill) up to this wide are stepped over in a straight line; a column holding any
  /// occupied voxel near that height (a wall, an obstacle, a low-mobility surface) never is.
  double max_gap_m = 0.04;
  double start_radius_m = 0.5;  ///< how far around the start point to look for a place to stand
  /// Which of the standable places within start_radius_m of the start point (measured
  /// horizontally, top face at or below the point's height plus max_step_m) to start on.
  enum class Start {
    kNearest,       ///< the nearest, then the highest: for a point on or just above the robot's footing
    kLargestLevel,  ///< on the map's largest level (the height with the most standable
                    ///< places within 4 cm, or a voxel, of it; the lowest of equals), the
                    ///< largest region there, then the nearest: for a camera position
                    ///< whose footing was never seen. That level is the floor; a chair
                    ///< seat or table top nearer the camera is not, even when furniture
                    ///< cuts the floor into pieces smaller than the table top.
  };
  Start start_rule = Start::kNearest;
};

/// std::invalid_argument "ReachParams: <field> is <value> (<rule>)".
void validate(const ReachParams& params);

/// A place: the top voxel of a run of vertically adjacent occupied voxels in one column
/// (the floor, a table top, a stair tread, the top of a wall).
struct Place {
  octomap::OcTreeKey key;     ///< finest-level key of the run's top voxel
  double x = 0, y = 0;        ///< column centre, map frame
  double top_z = 0;           ///< top face of the run, map frame (z up)
  bool has_mobility = false;  ///< the top voxel, or failing that the highest of the run, has a mobility
  double mobility = 0;        ///< meaningful when has_mobility
  double headroom_m = 0;      ///< free or unknown height above the run, up to the next occupied voxel (+inf if none)
  bool standable = false;     ///< has_mobility, mobility >= min_mobility and headroom >= clearance
  bool reachable = false;     ///< standable and connected to the start by steps and gaps within the limits
};

/// How much of a sole rests on places the robot can get to: Reachability::sole().
struct SoleReach {
  int samples = 0;    ///< soleSamples() of the foot, one per voxel
  int on_place = 0;   ///< samples with a place in the band searched under them
  int standable = 0;  ///< of those, on a standable place
  int reachable = 0;  ///< of those, on a reachable place
  /// reachable / samples (0 without samples): like FootprintQuery::known_fraction, a
  /// hole under part of the sole lowers it.
  [[nodiscard]] double reachableFraction() const { return samples > 0 ? static_cast<double>(reachable) / samples : 0.0; }
};

/// The result of computeReachability(): every place of the map and which are reachable.
/// Immutable; safe to query from several threads.
class Reachability {
 public:
  [[nodiscard]] const std::vector<Place>& places() const { return places_; }
  [[nodiscard]] const ReachParams& params() const { return params_; }
  [[nodiscard]] double resolution() const { return resolution_; }
  /// The place the search started from; nullopt if no standable place was found within
  /// start_radius_m of the start point at or below its height plus one step (then
  /// nothing is reachable).
  [[nodiscard]] std::optional<std::size_t> start() const { return start_; }
  [[nodiscard]] std::size_t standableCount() const { return standable_; }
  [[nodiscard]] std::size_t reachableCount() const { return reachable_; }
  /// The highest place in the column of `p_map` whose top voxel is at or below the voxel
  /// holding p, with its top face no lower than `max_drop_m` below p.z; nullptr if none.
  [[nodiscard]] const Place* placeBelow(const Eigen::Vector3d& p_map, double max_drop_m) const;
  /// The samples of `foot` (soleSamples()), each on placeBelow((x, y, foot.z +
  /// search_up_m), search_up_m + search_down_m): the band MobilityMap::footprint()
  /// searches with the same arguments, so both answers speak of the same surface.
  [[nodiscard]] SoleReach sole(const Foot& foot, double search_up_m = 0.1, double search_down_m = 0.1) const;
  /// The place whose run's top voxel is `key`; nullptr if that voxel is not a run's top.
  [[nodiscard]] const Place* placeAt(const octomap::OcTreeKey& key) const;

 private:
  friend Reachability computeReachability(const MobilityOcTree&, const Eigen::Vector3d&, const ReachParams&);
  /// Indices of the places in column (kx, ky), lowest first; nullptr if the column holds
  /// none or lies outside the tree's 16-bit keys.
  [[nodiscard]] const std::vector<std::uint32_t>* columnAt(long kx, long ky) const;
  ReachParams params_;
  double resolution_ = 0;
  std::vector<Place> places_;
  std::vector<std::uint16_t> run_bottom_;  ///< per place: the z key of its run's lowest voxel
  /// Column (x key << 16 | y key) -> indices into places_, lowest first.
  std::unordered_map<std::uint32_t, std::vector<std::uint32_t>> columns_;
  std::optional<std::size_t> start_;
  std::size_t standable_ = 0, reachable_ = 0;
};

/// Finds every place of `tree` (pruned blocks count voxel by voxel), decides which can be
/// stood on, splits those into regions and marks the region of the start place
/// (params.start_rule) reachable. Two standable places are joined when they are in
/// neighbouring columns (8 around) with tops at most max_step_m apart (less a voxel, see
/// ReachParams), or in a straight line across up to max_gap_m of columns that hold no
/// occupied voxel from that step below the lower top to that step (or the clearance)
/// above the higher. Map frame, z up. std::invalid_argument for invalid params (a
/// max_step_m under two voxels too) or a non-finite start; std::length_error if the map has more than 2^26 columns.
[[nodiscard]] Reachability computeReachability(const MobilityOcTree& tree, const Eigen::Vector3d& start_map,
                                               const ReachParams& params = {});

}  // namespace mobmap::mapping
