#pragma once
/// @file mobility_map.hpp
/// Fusing scored frames into a MobilityOcTree, and the queries a footstep planner asks.

#include "mobmap/mapping/foot.hpp"
#include "mobmap/mapping/height_scan.hpp"
#include "mobmap/mapping/map_metadata.hpp"
#include "mobmap/mapping/mobility_octree.hpp"
#include "mobmap/perception/camera.hpp"
#include "mobmap/perception/frame_result.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <cstdint>
#include <unordered_map>
#include <unordered_set>
#include <stdexcept>
#include <string>
#include <vector>

namespace mobmap::gp {
class MobilityModel;
}

namespace mobmap::mapping {

class SurfaceColumns;
namespace detail {
class FineSurface;
}

/// Map parameters, units in the names. OctoMap's sensor model (hit 0.7, miss 0.4) with
/// a lower upper clamp than OctoMap's 0.97: at 0.9 a voxel needs ~5 misses instead of
/// ~9 to turn free, so obstacles that move away clear while they are still in view.
struct MapParams {
  double resolution_m = 0.02;
  double max_range_m = 4.0;      ///< points beyond this range from the camera are ignored
  double prob_hit = 0.7;         ///< occupancy update of a surface voxel
  double prob_miss = 0.4;        ///< occupancy update of a voxel seen through
  double clamp_min = 0.12;
  double clamp_max = 0.9;
  double max_weight = 20000.0;   ///< cap on a voxel's summed 1/variance (~40 confident observations)
  /// Observation variance = segment variance + range_variance_per_m2 * range^2, so a
  /// far (noisier) observation weighs less than a near one.
  double range_variance_per_m2 = 0.002;
  /// Free space: a mapped voxel whose projection into the depth image lies more than
  /// max(this, 1.5 voxels) + 0.5 cm/m^2 * depth^2 in front of the measured depth is seen
  /// through and gets a miss (the depth term covers Kinect noise, ~1 cm at 2 m). A
  /// voxel closer than that to the surface behind it cannot be cleared this way: at
  /// 2 m and 40 degrees down, objects lower than ~4 cm leave a trace.
  double free_space_margin_m = 0.03;
  /// Free space for never-mapped space: one ray per this many pixels (each way) from
  /// the camera to just before the measured surface; 0 (default) disables the rays.
  /// Clearing of mapped voxels (above) does not need them. Rays cost time and memory:
  /// stride 16 on VGA adds ~100 ms and ~10x the nodes per frame (docs/PERFORMANCE.md).
  int free_space_ray_stride_px = 0;
  /// The fused fine surface (docs/ALGORITHM.md, "Rough ground from the fused surface"):
  /// each surface voxel keeps the moments of the depth pixels (without a depth image,
  /// the frame's points) every frame put in it, each weighted by (1.5 m / its range)^4
  /// as depth noise grows with range squared, so the voxel holds a plane finer than
  /// itself. finalize() scores ground that no flat sole-sized rectangle
  /// (`fine_support_m` x `fine_support_length_m`) holds by the area ratio (A/A') of that
  /// surface in a window of `fine_window_m` and the model's rule, in place of what the
  /// frames said. Off by default: on real data whose poses disagree by a centimetre or
  /// two the fused floor reads rough (docs/PERCEPTION.md); false keeps the frames' (the
  /// paper's) score only and no moments.
  bool fine_surface = false;
  /// A voxel's plane counts from this weight (a pixel at 1.5 m weighs 1; a frame puts
  /// dozens of pixels into a 2 cm voxel of floor within 2 m).
  double fine_min_weight = 1.0;
  /// Pixels farther than this add nothing to the fine surface: a depth camera's
  /// correlation window blurs a few centimetres of texture at a few metres.
  double fine_max_range_m = 2.5;
  double fine_window_m = 0.2;   ///< the window rough ground is measured in
  /// A flat rectangle this wide and this long (a sole, either way round) holds a foot:
  /// ground on one is not rough ground, whatever lies beside it (a curb, a wall, a stair).
  double fine_support_m = 0.12;
  double fine_support_length_m = 0.24;
};

/// What finalize() found on the fine surface (MapParams::fine_surface).
struct RoughGroundReport {
  std::size_t planes = 0;      ///< voxels whose moments make a plane (fine_min_weight)
  // Each surface voxel is at most one of these:
  std::size_t supported = 0;   ///< on a flat rectangle that holds a sole: the frames' score stays
  std::size_t scored = 0;      ///< scored as rough ground
  std::size_t too_sparse = 0;  ///< too little fine surface around it to tell
  std::size_t too_noisy = 0;   ///< its window's relief is within the noise of its points
};

/// A voxel finalize() scored as rough ground.
struct RoughVoxel {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< map frame
  double roughness = 1.0;  ///< A/A' of the fine surface in the foot window
  double slope_deg = 0.0;  ///< of that surface's mean plane
  double mobility = 0.0;   ///< what the model gives for the two, now the voxel's
  /// What the frames had fused there before (NaN when they gave it no mobility).
  double frames_mobility = 0.0;
};

/// A voxel of the fine surface, for export.
struct FineSurfacePoint {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();   ///< the mean of its points (map frame)
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< its plane's, unit, upward where it has an up
  double weight = 0.0;
  int views = 0;  ///< frames that saw it (saturating at 65535)
};

/// Throws std::invalid_argument "MapParams: <field> is <value> (<rule>)".
void validate(const MapParams& params);

/// What a point of space is.
enum class VoxelState { kUnknown, kFree, kSurface };
const char* toString(VoxelState s);

/// Answer of MobilityMap::query().
struct PointQuery {
  VoxelState state = VoxelState::kUnknown;
  bool has_mobility = false;
  double mobility = 0.0;   ///< meaningful when has_mobility
  double variance = 0.0;   ///< +inf when !has_mobility
  int count = 0;
  double occupancy = 0.5;  ///< probability
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< map frame
  double size_m = 0.0;     ///< edge of the (possibly pruned) voxel
  /// The point lies beyond every voxel the map's tree can hold (+-32768 voxels around
  /// the map origin, or not finite): no map of this resolution reaches it (state kUnknown).
  bool outside_map = false;
};

/// Answer of MobilityMap::footprint().
struct FootprintQuery {
  double min_mobility = 0.0;        ///< over sole samples with a known surface (0 if none)
  double mean_mobility = 0.0;
  double known_fraction = 0.0;      ///< samples on a surface with a mobility (footprint())
  double max_height_difference_m = 0.0;  ///< between the highest and lowest supporting voxel
  int samples = 0;
  /// The support plane: least squares through the top faces of the supporting voxels
  /// (z as a linear function of x and y). Needs >= 3 supported samples not on one line;
  /// has_support_plane is false otherwise and the fields below keep their defaults.
  /// Its height is where the sole rests. Its tilt comes from voxel tops, which step a
  /// whole voxel at a time: over a 25 x 12 cm sole in a 2 cm map it was within 3 degrees
  /// along 15-35 degree ramps, but one step across the sole's 12 cm reads as up to ~14
  /// degrees (a 5-degree ramp read 12; docs/MAPPING.md, "Queries"). For slope, trust the
  /// mobility, which perception measures in 1 cm voxels.
  bool has_support_plane = false;
  double support_height_m = 0.0;  ///< the plane's z under the sole's centre (map frame)
  Eigen::Vector3d support_normal = Eigen::Vector3d::UnitZ();  ///< unit, upward (map frame)
  double support_tilt_deg = 0.0;  ///< angle between the plane's normal and +z
  double support_rms_m = 0.0;     ///< RMS of the top faces about the plane: unevenness under the sole
};

/// Occupied voxels a tree may stand for, pruned leaves counted voxel by voxel: at most
/// max(kMinVoxelBudget, kMaxVoxelsPerLeaf x its leaves). Fused surfaces prune to leaves
/// of 8 or 64 voxels; a file whose few leaves claim millions of voxels each (a root that
/// is one occupied leaf stands for 2^48) cannot be expanded into the map's index and is
/// refused. The count of `tree`'s occupied voxels, or nullopt once it passes `limit`.
inline constexpr std::uint64_t kMaxVoxelsPerLeaf = 64;
inline constexpr std::uint64_t kMinVoxelBudget = std::uint64_t{1} << 20;
[[nodiscard]] std::optional<std::uint64_t> countOccupiedVoxels(const MobilityOcTree& tree, std::uint64_t limit);
/// The problem of a tree that holds more voxels than its size allows (above), or nullopt.
[[nodiscard]] std::optional<std::string> voxelBudgetProblem(const MobilityOcTree& tree);

/// The map origin `mobmap build` and LiveMapper take unless told one: the first camera
/// position (world frame) rounded to the nearest 100 m, so data near the world origin
/// keep their coordinates and UTM-sized ones get small map coordinates.
[[nodiscard]] Eigen::Vector3d defaultMapOrigin(const Eigen::Vector3d& first_camera_world);

/// What integrate() did with a frame's points.
struct IntegrationReport {
  std::size_t points_fused = 0;    ///< within max_range_m and inside the map's extent
  /// Within max_range_m but outside the map's extent (OctoMap's keys reach 32768 voxels
  /// from the map origin each way: +-655 m at 2 cm), so left out: a pose far from the
  /// origin, or poses in another unit.
  std::size_t points_outside_map = 0;
};

/// Fuses scored frames. Frames: the map frame is gravity aligned (z up) and centred on
/// an origin near the data: p_map = R_map_world (p_world - origin_world). R_map_world is
/// a fixed rotation for data sets whose world frame is not z up; origin_world keeps
/// world frames with large coordinates (UTM, a building's survey grid) inside the map's
/// extent and in float precision.
///
/// Threading: integrate() must not run concurrently with anything else. All const
/// methods (queries, exports) are safe to call from several threads at once while no
/// integrate() or finalize() runs.
class MobilityMap {
 public:
  /// std::invalid_argument if a parameter is out of range, R_map_world is not a
  /// rotation (checkRigid's tolerance), or if origin_world is not finite.
  explicit MobilityMap(MapParams params = {}, const Eigen::Matrix3d& R_map_world = Eigen::Matrix3d::Identity(),
                       const Eigen::Vector3d& origin_world = Eigen::Vector3d::Zero());
  /// Wraps a loaded tree (params.resolution_m must match the tree's); std::invalid_argument
  /// if its pruned leaves stand for more voxels than its size allows (voxelBudgetProblem).
  MobilityMap(std::unique_ptr<MobilityOcTree> tree, MapParams params, const Eigen::Matrix3d& R_map_world,
              const Eigen::Vector3d& origin_world = Eigen::Vector3d::Zero());
  /// A deep copy: the same tree, frame and index; fusing into either leaves the other as it was.
  MobilityMap(const MobilityMap& other);
  MobilityMap(MobilityMap&&) noexcept = default;
  MobilityMap& operator=(MobilityMap&&) noexcept = default;
  MobilityMap& operator=(const MobilityMap&) = delete;

  /// Fuses one frame: every segment point marks its voxel occupied and fuses the
  /// segment's mobility (inverse-variance weighting); points outside segments mark
  /// occupancy only. With the frame's depth image and intrinsics, free space is
  /// updated too (see MapParams). Leaves are current at once; call finalize() before
  /// saving or asking coarse (inner-node) questions. Points outside the map's extent
  /// are left out and counted in the report.
  IntegrationReport integrate(const perception::FrameResult& frame, const Eigen::Isometry3d& T_world_camera,
                              const perception::DepthImage* depth = nullptr,
                              const perception::PinholeIntrinsics* intrinsics = nullptr);

  /// Scores rough ground on the fine surface (MapParams::fine_surface), then recomputes
  /// inner nodes (occupancy max, mobility min) and prunes equal children.
  /// Frames may be integrated afterwards (and into a loaded map): pruned blocks are
  /// expanded where new data lands, so the result equals fusing without the pruning.
  void finalize();
  /// The model rough ground is scored with (the perception's, so both score alike);
  /// unset: gp::MobilityModel's default.
  void setMobilityModel(std::shared_ptr<const gp::MobilityModel> model) { model_ = std::move(model); }
  /// What the last finalize() found on the fine surface, and the voxels it scored as
  /// rough ground (with what the frames had said there).
  [[nodiscard]] const RoughGroundReport& roughGroundReport() const { return rough_report_; }
  [[nodiscard]] const std::vector<RoughVoxel>& roughVoxels() const { return rough_voxels_; }
  /// The fine surface: a point with a normal per voxel whose moments weigh at least
  /// `min_weight`. Empty without MapParams::fine_surface, and for a map read from a
  /// file (the .ot keeps no moments).
  [[nodiscard]] std::vector<FineSurfacePoint> fineSurface(double min_weight = 0.0) const;
  /// Bytes the fine surface's moments take (0 without them).
  [[nodiscard]] std::size_t fineSurfaceBytes() const;
  /// Writes the fine surface (fineSurface(min_weight)) as a binary little-endian PLY,
  /// map frame, atomically: per point x y z, its normal nx ny nz, `weight`, `views`,
  /// `roughness` (the A/A' finalize() measured where it scored the voxel as rough
  /// ground, else 0) and `mobility` (the voxel's, -1 where it has none). MapIoError
  /// naming the path if it cannot be written.
  void saveFineSurfacePly(const std::string& path, double min_weight = 0.0) const;

  /// State of the voxel holding `p_map` (map frame).
  [[nodiscard]] PointQuery query(const Eigen::Vector3d& p_map) const;
  /// The first surface voxel at or below `p_map` along -z within `max_drop_m`, searched
  /// one voxel at a time; nullopt if none (or if max_drop_m is negative or not finite).
  [[nodiscard]] std::optional<PointQuery> snapDown(const Eigen::Vector3d& p_map, double max_drop_m) const;
  /// Mobility under a rectangular sole, sampled every voxel. The surface under the sole's
  /// centre within [foot.z - search_down_m, foot.z + search_up_m] sets the reference
  /// height (foot.z when there is none); each sample rests on the first surface voxel at
  /// or below the reference plus search_up_m, down to the reference minus search_down_m.
  /// A sample is known when that surface has a mobility: the voxel's own or, failing
  /// that, the highest one below it in the same run of occupied voxels. That is how
  /// evaluateFoothold() counts a sole's support (Foothold::support_fraction), so with the
  /// default RobotParams (their band is within 1 mm of 0.1 m) the two agree.
  [[nodiscard]] FootprintQuery footprint(const Foot& foot, double search_up_m = 0.1, double search_down_m = 0.1) const;

  /// The surface columns of the map as it is now (footholds.hpp): built on first use
  /// (one pass over the leaves) and kept until the map changes (integrate(), finalize(),
  /// the non-const tree()). Costs SurfaceColumns::memoryBytes() while kept: ~4 bytes per
  /// column of the map's extent and ~20 per run of occupied voxels (1.5 MB for the
  /// 1000-frame redkitchen at 2 cm, built in ~20 ms). Safe to call from several threads at once.
  [[nodiscard]] std::shared_ptr<const SurfaceColumns> surfaceColumns() const;
  /// Height scans (height_scan.hpp) of poses in the map frame, over surfaceColumns().
  /// std::invalid_argument for a bad grid or a pose that is not finite.
  [[nodiscard]] HeightScan heightScan(const std::vector<HeightScanPose>& poses, const HeightScanGrid& grid = {}) const;

  /// Converts a point of the data's world frame into the map frame.
  [[nodiscard]] Eigen::Vector3d worldToMap(const Eigen::Vector3d& p_world) const {
    return R_map_world_ * (p_world - origin_world_);
  }
  /// Converts a point of the map frame into the data's world frame.
  [[nodiscard]] Eigen::Vector3d mapToWorld(const Eigen::Vector3d& p_map) const {
    return R_map_world_.transpose() * p_map + origin_world_;
  }
  /// A heading (yaw, radians) of the world frame's x-y plane as a yaw in the map frame:
  /// the direction (cos, sin, 0) turned into the map frame, seen from above.
  [[nodiscard]] double worldYawToMap(double yaw_world) const {
    const Eigen::Vector3d d = R_map_world_ * Eigen::Vector3d(std::cos(yaw_world), std::sin(yaw_world), 0.0);
    return std::atan2(d.y(), d.x());
  }
  /// A yaw of the map frame as a heading in the world frame's x-y plane.
  [[nodiscard]] double mapYawToWorld(double yaw_map) const {
    const Eigen::Vector3d d = R_map_world_.transpose() * Eigen::Vector3d(std::cos(yaw_map), std::sin(yaw_map), 0.0);
    return std::atan2(d.y(), d.x());
  }
  /// The map frame's origin in the world frame.
  [[nodiscard]] const Eigen::Vector3d& originWorld() const { return origin_world_; }
  /// Moves the map's origin (world frame) before anything is fused: for a stream whose
  /// first pose is known only when its first frame arrives. std::logic_error once the
  /// map holds anything; std::invalid_argument if not finite.
  void setOriginWorld(const Eigen::Vector3d& origin_world);
  /// Half the edge of the cube the map can hold, centred on its origin (metres):
  /// 32768 voxels (655.36 m at 2 cm).
  [[nodiscard]] double extentM() const;

  [[nodiscard]] const MobilityOcTree& tree() const { return *tree_; }
  [[nodiscard]] MobilityOcTree& tree() {
    forgetColumns();
    return *tree_;
  }
  [[nodiscard]] const MapParams& params() const { return params_; }
  [[nodiscard]] const Eigen::Matrix3d& rotationMapWorld() const { return R_map_world_; }
  [[nodiscard]] int framesIntegrated() const { return frames_; }
  void setFramesIntegrated(int n) { frames_ = n; }

 private:
  void clearSeenThrough(const Eigen::Isometry3d& T_map_camera, const perception::DepthImage& depth,
                        const perception::PinholeIntrinsics& k);
  void addPixelMoments(const Eigen::Isometry3d& T_map_camera, const perception::DepthImage& depth,
                       const perception::PinholeIntrinsics& k);
  void castFreeRays(const Eigen::Isometry3d& T_map_camera, const perception::DepthImage& depth,
                    const perception::PinholeIntrinsics& k);
  PointQuery describe(const octomap::OcTreeKey& key, const MobilityOcTreeNode* node, unsigned int depth) const;
  void addOccupied(const octomap::OcTreeKey& key);
  void expandPrunedAncestors(const octomap::OcTreeKey& key);
  void removeOccupied(const octomap::OcTreeKey& key);
  void forgetColumns() { std::atomic_store(&columns_, std::shared_ptr<const SurfaceColumns>()); }

  MapParams params_;
  Eigen::Matrix3d R_map_world_;
  Eigen::Vector3d origin_world_ = Eigen::Vector3d::Zero();
  std::unique_ptr<MobilityOcTree> tree_;
  /// Keys (finest level) of occupied voxels: free-space clearing visits these instead
  /// of every leaf in the view. The set answers "is it listed"; the same keys grouped
  /// by block of 16^3 voxels let clearing skip whole blocks outside the camera's view.
  std::unordered_set<octomap::OcTreeKey, octomap::OcTreeKey::KeyHash> occupied_;
  std::unordered_map<std::uint64_t, std::vector<octomap::OcTreeKey>> occupied_blocks_;
  int frames_ = 0;
  /// surfaceColumns()' cache, read and written with std::atomic_load / atomic_store.
  mutable std::shared_ptr<const SurfaceColumns> columns_;
  /// finalize() has run or the tree was loaded: some voxels may sit in pruned nodes.
  bool may_be_pruned_ = false;
  /// The fine surface's moments (MapParams::fine_surface; else null), the model rough
  /// ground is scored with, and what the last finalize() scored.
  std::shared_ptr<detail::FineSurface> fine_;
  std::shared_ptr<const gp::MobilityModel> model_;
  RoughGroundReport rough_report_;
  std::vector<RoughVoxel> rough_voxels_;
};

/// Map file errors: the message starts with the path.
class MapIoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Writes the full tree (.ot) atomically: a temporary file beside `path`, then rename.
void saveMobilityMap(const MobilityOcTree& tree, const std::string& path);
/// Reads a .ot written by saveMobilityMap(). MapIoError naming the path if the file is
/// missing, truncated, of another tree type, not an OctoMap file, of a resolution outside
/// [0.001, 10] m, or if its pruned leaves stand for more voxels than its size allows
/// (voxelBudgetProblem). Always links
/// the MobilityOcTree registration, also from static libraries.
std::unique_ptr<MobilityOcTree> loadMobilityMap(const std::string& path);
/// Occupancy only, OctoMap's binary .bt (readable by any OctoMap tool), atomically.
void saveOccupancyBt(const MobilityOcTree& tree, const std::string& path);
/// A voxel's colour in a ColorOcTree export: red, green, blue.
using VoxelRgb = std::array<std::uint8_t, 3>;
/// The colour scales of mobility. kViridis (the default): dark purple (0) through teal
/// (0.5) to yellow (1), matplotlib's viridis, which stays ordered and apart under the
/// common colour-vision deficiencies; unknown is a light grey no mobility takes.
/// kRedGreen: red (0) through yellow (0.5) to green (1), as the paper's figures; unknown
/// a mid grey. docs/MAPPING.md has the distances between them, with and without a
/// simulated deuteranopia and protanopia.
enum class ColourScale { kViridis, kRedGreen };
/// The colours a scale passes through at evenly spaced mobilities from 0 to 1 (9 for
/// viridis, 3 for red-green); between them it is linear in sRGB.
[[nodiscard]] const std::vector<VoxelRgb>& colourStops(ColourScale scale);
/// "viridis" or "red-green".
[[nodiscard]] const char* toString(ColourScale scale);
/// The scale named `name` ("viridis", "red-green"); nullopt for any other name.
[[nodiscard]] std::optional<ColourScale> colourScaleNamed(const std::string& name);
/// A mobility's colour on `scale`, clamped to [0, 1]; the unknown colour for NaN: the
/// colours of the octovis export, the pictures and the viewer.
[[nodiscard]] VoxelRgb mobilityRgb(double mobility, ColourScale scale = ColourScale::kViridis);
/// The colour of a surface with no mobility estimate on `scale`.
[[nodiscard]] VoxelRgb unknownRgb(ColourScale scale = ColourScale::kViridis);
/// mobilityRgb(node.mobility()), or unknownRgb() for a voxel without a mobility estimate.
[[nodiscard]] VoxelRgb mobilityRgb(const MobilityOcTreeNode& node, ColourScale scale = ColourScale::kViridis);
/// A ColorOcTree .ot for stock octovis: every occupied voxel in mobilityRgb() colours.
/// Free space is not exported. Written atomically.
void saveOctovisColorTree(const MobilityOcTree& tree, const std::string& path);
/// The same, each occupied voxel in the colour `colour(key, node)` gives it: `key` is the
/// voxel's finest-level key (a pruned leaf is asked once for every voxel it covers, with
/// its own key), `node` the leaf holding it.
void saveOctovisColorTree(const MobilityOcTree& tree, const std::string& path,
                          const std::function<VoxelRgb(const octomap::OcTreeKey&, const MobilityOcTreeNode&)>& colour);
/// Surface voxel centres as ASCII PCD with fields x y z mobility variance count.
void saveSurfacePcd(const MobilityOcTree& tree, const std::string& path);

/// A map as `mobmap build` left it: MAP.ot with the frame recorded in MAP.json, so
/// worldToMap() takes points in the world frame of the poses it was built from. Errors
/// as loadMobilityMap() and readMapMetadata().
MobilityMap openMap(const std::string& ot_path, MapParams params = {});
/// The same from a tree already loaded (loadMobilityMap) and its metadata already read
/// (readMapMetadata), for callers that also want the rest of MAP.json without reading
/// and checking it twice.
MobilityMap openMap(std::unique_ptr<MobilityOcTree> tree, const MapMetadata& metadata, MapParams params = {});

}  // namespace mobmap::mapping
