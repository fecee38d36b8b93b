#pragma once
/// @file footholds.hpp
/// Foot-scale questions: can a sole stand here, and can the robot step from one sole to
/// another? A sole is judged by the whole surface under it, never by one voxel, so an
/// edge voxel half way up a riser can never carry a foot or be a stepping stone.

#include "mobmap/mapping/mobility_octree.hpp"

#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace mobmap::mapping {

/// The robot's feet and legs, units in the names. The defaults describe a small humanoid.
struct RobotParams {
  double sole_length_m = 0.25;  ///< along the foot's heading
  double sole_width_m = 0.12;   ///< across it
  /// Lowest mobility the robot stands on: the surface under a sole must have at least
  /// this, but for a share of at most max_poor_fraction of its known voxels (a stray
  /// voxel scored apart, as at edges, does not condemn a sole).
  double min_mobility = 0.5;
  double max_poor_fraction = 0.1;
  /// Share of a sole's samples (one per voxel) that must rest on surface with a known
  /// mobility: the rest may hang over unseen ground or an edge.
  double min_support_fraction = 0.8;
  double max_tilt_deg = 20.0;  ///< largest tilt of the plane the sole rests on
  /// Largest distance of a voxel top under the sole from that plane. Tops are voxel
  /// faces, so a flat floor already shows half a voxel.
  double max_unevenness_m = 0.03;
  /// Free (or unseen) height the robot needs above the sole's plane (its height); 0
  /// checks only the swing clearance below.
  double clearance_m = 0.0;
  /// Largest rise or drop between the supports of successive footsteps. Support heights
  /// are known to a voxel, so a step passes only when its measured height plus one voxel
  /// is within this (it is then surely within it). At least two voxels.
  double max_step_m = 0.15;
  double max_stride_m = 0.4;  ///< horizontal distance between the centres of successive footsteps
  /// How high the swing foot lifts above the higher of its two supports: anything
  /// between them that stands higher blocks the step, and a sole needs this much free
  /// height above it.
  double swing_clearance_m = 0.1;
  /// Longest stretch under a swing (between the sole centres) with no surface near the
  /// walking height: unseen or missing ground the foot passes over.
  double max_gap_m = 0.1;
  double stance_width_m = 0.2;  ///< sideways distance between the feet's centres when standing
  /// Spacing of the sole centres that reachability and the planner try; rounded to whole
  /// voxels (at least one).
  double lattice_m = 0.04;
};

/// std::invalid_argument "RobotParams: <field> is <value> (<rule>)".
void validate(const RobotParams& params);

/// Every field equal (a cache's key).
[[nodiscard]] bool operator==(const RobotParams& a, const RobotParams& b);
[[nodiscard]] inline bool operator!=(const RobotParams& a, const RobotParams& b) { return !(a == b); }

/// RobotParams' fields by name (the names above: sole_length_m ... lattice_m), for callers
/// that take them as keyword arguments or JSON (Python, `mobmap serve`). False for a name
/// that is none of them; the value is not checked (validate() does).
bool setRobotParameter(RobotParams& params, const std::string& name, double value);
/// The names setRobotParameter() takes, in the order of the fields.
const std::vector<std::string>& robotParameterNames();

/// Headings the lattice tries: 16, every 22.5 degrees; a sole is symmetric, so heading k
/// and k + 8 stand on the same voxels.
inline constexpr int kHeadings = 16;
[[nodiscard]] double headingYaw(int heading);  ///< radians, heading in [0, kHeadings)

/// The occupied voxels of a map as runs per column (x, y key): what soles rest on.
/// Built once from a tree (pruned blocks count voxel by voxel); immutable afterwards and
/// safe to query from several threads.
class SurfaceColumns {
 public:
  /// A run of vertically adjacent occupied voxels: z keys bottom..top, and the mobility of
  /// its top voxel (or, failing that, of the highest voxel of the run that has one).
  struct Run {
    int bottom = 0, top = 0;
    float mobility = std::numeric_limits<float>::quiet_NaN();  ///< NaN: unknown
    float variance = std::numeric_limits<float>::infinity();
    [[nodiscard]] bool hasMobility() const { return mobility == mobility; }
  };
  /// std::length_error if the occupied columns span more than 2^26 columns.
  explicit SurfaceColumns(const MobilityOcTree& tree);
  SurfaceColumns() = default;

  [[nodiscard]] double resolution() const { return res_; }
  /// Key of the voxel holding coordinate c (not clamped: may lie outside the tree), found
  /// as the tree finds it (the coordinate as a float, times 1 / resolution, floored), so a
  /// point on a voxel face falls in the same voxel for the columns and for the tree.
  [[nodiscard]] long keyOf(double c) const {
    const double v = inv_res_ * static_cast<double>(static_cast<float>(c));
    const long k = static_cast<long>(v);  // floor, without a call into libm
    return (static_cast<double>(k) > v ? k - 1 : k) + 32768L;
  }
  /// Coordinate of a key's voxel centre.
  [[nodiscard]] double centreOf(long key) const { return (static_cast<double>(key - 32768L) + 0.5) * res_; }
  [[nodiscard]] double topFace(const Run& r) const { return centreOf(r.top) + res_ / 2; }
  [[nodiscard]] double bottomFace(const Run& r) const { return centreOf(r.bottom) - res_ / 2; }
  /// Index of column (kx, ky) or -1 outside the occupied area.
  [[nodiscard]] long columnIndex(long kx, long ky) const {
    const long i = kx - kx0_, j = ky - ky0_;
    return i < 0 || j < 0 || i >= nx_ || j >= ny_ ? -1 : i * ny_ + j;
  }
  /// The runs of column `index` (columnIndex), lowest first; run ids are indices into runs().
  [[nodiscard]] std::size_t runBegin(long index) const { return index < 0 ? 0 : offsets_[static_cast<std::size_t>(index)]; }
  [[nodiscard]] std::size_t runEnd(long index) const { return index < 0 ? 0 : offsets_[static_cast<std::size_t>(index) + 1]; }
  [[nodiscard]] const std::vector<Run>& runs() const { return runs_; }
  [[nodiscard]] long keyX0() const { return kx0_; }
  [[nodiscard]] long keyY0() const { return ky0_; }
  [[nodiscard]] long columnsX() const { return nx_; }
  [[nodiscard]] long columnsY() const { return ny_; }
  /// Bytes held.
  [[nodiscard]] std::size_t memoryBytes() const {
    return sizeof(*this) + offsets_.capacity() * sizeof(std::uint32_t) + runs_.capacity() * sizeof(Run) +
           run_column_.capacity() * sizeof(std::uint32_t);
  }
  /// Column keys of a run id.
  [[nodiscard]] long runColumn(std::size_t run) const { return run_column_[run]; }
  /// The highest run of the column holding (x, y) whose top face is at or below `z_max`
  /// and at or above `z_min`; -1 if none.
  [[nodiscard]] long runBelow(double x, double y, double z_max, double z_min) const;

 private:
  double res_ = 0;
  double inv_res_ = 0;  ///< 1 / res_, as octomap computes its resolution factor
  long kx0_ = 0, ky0_ = 0, nx_ = 0, ny_ = 0;
  std::vector<std::uint32_t> offsets_;  ///< per column, into runs_ (nx * ny + 1)
  std::vector<Run> runs_;
  std::vector<std::uint32_t> run_column_;  ///< per run, its column index
};

/// Why a sole cannot be stood on (the first limit it fails, in this order).
enum class FootholdProblem {
  kNone,
  kNoSurface,      ///< too little of the sole rests on known surface (min_support_fraction)
  kTooSteep,       ///< the support plane tilts more than max_tilt_deg
  kUneven,         ///< a voxel top under the sole lies further than max_unevenness_m from that plane
  kObstacle,       ///< something occupied inside the sole's volume (swing_clearance_m, clearance_m)
  kLowMobility,    ///< more than max_poor_fraction of the surface under the sole has mobility under min_mobility
};
const char* toString(FootholdProblem p);

/// A sole placed on the map and what the surface under it says.
struct Foothold {
  double x = 0, y = 0, yaw = 0;  ///< sole centre and heading, map frame
  /// Height of the support plane (through the tops of the voxels under the sole) at the
  /// centre: where the sole rests. Meaningful when has_plane.
  double z = 0;
  bool has_plane = false;
  double tilt_deg = 0;          ///< of the support plane
  double unevenness_m = 0;      ///< largest distance of a top under the sole from the plane
  double support_fraction = 0;  ///< samples resting on surface with a mobility
  double min_mobility = 0, mean_mobility = 0;  ///< over those samples (0 if none)
  double poor_fraction = 0;     ///< of those samples, the share under RobotParams::min_mobility
  double mean_variance = 0;     ///< of their mobility estimates
  int samples = 0;
  FootholdProblem geometry = FootholdProblem::kNone;  ///< first geometric limit failed
  FootholdProblem problem = FootholdProblem::kNone;   ///< geometry, else kLowMobility
  [[nodiscard]] bool geometryOk() const { return geometry == FootholdProblem::kNone; }
  [[nodiscard]] bool standable() const { return problem == FootholdProblem::kNone; }
};

/// Judges a sole centred at (x, y) with heading `yaw`, resting on the surface near height
/// `z_ref` (map frame): each sample (one per voxel) rests on the highest top of its column
/// within the band a tilted sole can span around z_ref; a plane is fitted through those
/// tops. `supports`, when given, receives the run ids the samples rest on.
[[nodiscard]] Foothold evaluateFoothold(const SurfaceColumns& columns, double x, double y, double yaw, double z_ref,
                                        const RobotParams& robot, std::vector<std::size_t>* supports = nullptr);

/// What blocks a step between two soles' centres at heights za and zb (support heights),
/// apart from their height difference: kNone, kObstacle (something between them higher
/// than the swing clearance above the higher support) or kNoSurface (a stretch of more
/// than max_gap_m without surface near the walking height).
[[nodiscard]] FootholdProblem swingProblem(const SurfaceColumns& columns, double xa, double ya, double za, double xb,
                                           double yb, double zb, const RobotParams& robot);

/// A limit as a person gave it: the shortest decimal that reads back as the same double
/// ("0.155", not "0.15" or "0.15500000000000000"), for messages that name it.
[[nodiscard]] std::string formatLimit(double value);

/// How far above a swing's higher support swingProblem() looks for what meets the leg:
/// max(clearance_m, swing_clearance_m + 0.5 m) (a table top 0.7 m above the floor does not).
[[nodiscard]] double swingLegTop(const RobotParams& robot);

/// Whether a step from a support at za to one at zb passes max_step_m (one voxel of
/// margin, see RobotParams::max_step_m).
[[nodiscard]] bool stepHeightOk(double za, double zb, const RobotParams& robot, double resolution);

/// Whether the robot can step between soles centred at (xa, ya) and (xb, yb) resting at za
/// and zb: centres within max_stride_m, stepHeightOk and no swingProblem.
[[nodiscard]] bool canStep(const SurfaceColumns& columns, double xa, double ya, double za, double xb, double yb, double zb,
                           const RobotParams& robot);

}  // namespace mobmap::mapping
