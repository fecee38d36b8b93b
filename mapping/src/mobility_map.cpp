#include "mobmap/mapping/mobility_map.hpp"

#include "mobmap/mapping/footholds.hpp"
#include "mobmap/mapping/gravity.hpp"
#include "atomic_write.hpp"
#include "fine_surface.hpp"
#include "param_error.hpp"
#include "support_plane.hpp"


#include <octomap/OcTreeKey.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <tuple>
#include <unordered_map>

namespace mobmap::mapping {
namespace {

constexpr int kBlock = 16;  // voxels per block edge in the occupied-voxel index
// The fine surface: a point at this range weighs 1; a voxel's moments stop growing at
// kFineMaxWeight (~500 frames of floor seen from 1.5 m), so old views fade.
constexpr double kFineReferenceRangeM = 1.5;
constexpr float kFineMaxWeight = 2000.0f;
// Every second pixel each way: ~4 mm apart at 2 m on a VGA depth camera, still several
// points per centimetre of surface, for a quarter of the cost.
constexpr int kFinePixelStride = 2;

std::uint64_t blockOf(const octomap::OcTreeKey& key) {
  return (static_cast<std::uint64_t>(key[0] / kBlock) << 32) | (static_cast<std::uint64_t>(key[1] / kBlock) << 16) |
         static_cast<std::uint64_t>(key[2] / kBlock);
}

// std::lround for |v| < 2^31, inline (the library call was ~5 % of fusion): the
// fraction v - trunc(v) of a float is exact.
inline int roundHalfAway(float v) {
  const int t = static_cast<int>(v);
  const float f = v - static_cast<float>(t);
  return t + (f >= 0.5f) - (f <= -0.5f);
}

octomap::point3d toOcto(const Eigen::Vector3d& p) {
  return {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())};
}

// The key of a point in the map, or false outside it. OctoMap takes the point as floats
// and casts it, scaled, to int: a coordinate beyond float's range (1e308) or the int's
// would be undefined there. Any coordinate that far lies outside the tree's 2^16 voxels
// per axis, so it is refused first.
bool keyOf(const MobilityOcTree& tree, const Eigen::Vector3d& p, octomap::OcTreeKey& key) {
  const double limit = 65536.0 * tree.getResolution();
  if (!(std::abs(p.x()) < limit && std::abs(p.y()) < limit && std::abs(p.z()) < limit)) return false;
  return tree.coordToKeyChecked(toOcto(p), key);
}

// The distinct voxels one frame reaches, in the order it first reaches them, found
// through an open-addressing table of indices into that list (a node-based map
// allocated a node per voxel). The caller keeps what it gathers per voxel in lists
// parallel to keys().
class FrameVoxels {
 public:
  // Empty, with room for `n` distinct voxels.
  void reset(std::size_t n) {
    std::size_t capacity = 1024;
    while (capacity < 2 * n) capacity <<= 1;
    slots_.assign(capacity, -1);
    keys_.clear();
  }
  // The index of `key` in keys(), and whether this call added it.
  std::pair<std::size_t, bool> insert(const octomap::OcTreeKey& key) {
    const std::size_t mask = slots_.size() - 1;
    const std::uint64_t packed = (static_cast<std::uint64_t>(key[0]) << 32) | (static_cast<std::uint64_t>(key[1]) << 16) | key[2];
    std::size_t slot = static_cast<std::size_t>((packed * 0x9E3779B97F4A7C15ULL) >> 40) & mask;
    while (slots_[slot] >= 0 && keys_[static_cast<std::size_t>(slots_[slot])] != key) slot = (slot + 1) & mask;
    if (slots_[slot] >= 0) return {static_cast<std::size_t>(slots_[slot]), false};
    slots_[slot] = static_cast<int>(keys_.size());
    keys_.push_back(key);
    return {keys_.size() - 1, true};
  }
  [[nodiscard]] const std::vector<octomap::OcTreeKey>& keys() const { return keys_; }

 private:
  std::vector<int> slots_;
  std::vector<octomap::OcTreeKey> keys_;
};

// A point (map frame) into the moments of its voxel `key`, as an offset from the
// voxel's centre, weighted as depth noise allows: its variance grows with range
// squared, so (1.5 m / range)^4 (a point at 1.5 m weighs 1).
void addToMoments(detail::PointMoments& m, const MobilityOcTree& tree, const octomap::OcTreeKey& key, const Eigen::Vector3d& p,
                  double range2) {
  const octomap::point3d c = tree.keyToCoord(key);
  const double q = kFineReferenceRangeM * kFineReferenceRangeM / std::max(range2, 1e-6);
  m.add(Eigen::Vector3f(static_cast<float>(p.x() - c.x()), static_cast<float>(p.y() - c.y()), static_cast<float>(p.z() - c.z())),
        static_cast<float>(q * q));
}

// Each voxel of the fine surface whose moments weigh at least `min_weight` (and more
// than nothing), with its plane.
template <class Visit>
void forEachFinePlane(const detail::FineSurface& fine, const MobilityOcTree& tree, double min_weight, Visit visit) {
  for (const auto& [key, m] : fine.voxels()) {
    if (m.w < min_weight || !(m.w > 0)) continue;
    visit(key, detail::planeOf(tree, key, m));
  }
}

}  // namespace

void validate(const MapParams& p) {
  if (!(p.resolution_m >= 0.001 && p.resolution_m <= 10)) detail::failParam("MapParams", "resolution_m", p.resolution_m, "must be in [0.001, 10]");
  if (!(p.max_range_m > 0) || !std::isfinite(p.max_range_m)) detail::failParam("MapParams", "max_range_m", p.max_range_m, "must be finite and > 0");
  if (!(p.prob_hit > 0.5 && p.prob_hit < 1)) detail::failParam("MapParams", "prob_hit", p.prob_hit, "must be in (0.5, 1)");
  if (!(p.prob_miss > 0 && p.prob_miss < 0.5)) detail::failParam("MapParams", "prob_miss", p.prob_miss, "must be in (0, 0.5)");
  if (!(p.clamp_min > 0 && p.clamp_min < 0.5)) detail::failParam("MapParams", "clamp_min", p.clamp_min, "must be in (0, 0.5)");
  if (!(p.clamp_max > 0.5 && p.clamp_max < 1)) detail::failParam("MapParams", "clamp_max", p.clamp_max, "must be in (0.5, 1)");
  if (!(p.max_weight > 0) || !std::isfinite(p.max_weight)) detail::failParam("MapParams", "max_weight", p.max_weight, "must be finite and > 0");
  if (!(p.range_variance_per_m2 >= 0) || !std::isfinite(p.range_variance_per_m2)) detail::failParam("MapParams", "range_variance_per_m2", p.range_variance_per_m2, "must be finite and >= 0");
  if (!(p.free_space_margin_m >= 0) || !std::isfinite(p.free_space_margin_m)) detail::failParam("MapParams", "free_space_margin_m", p.free_space_margin_m, "must be finite and >= 0");
  if (p.free_space_ray_stride_px < 0) detail::failParam("MapParams", "free_space_ray_stride_px", p.free_space_ray_stride_px, "must be >= 0");
  if (!(p.fine_max_range_m > 0) || !std::isfinite(p.fine_max_range_m)) detail::failParam("MapParams", "fine_max_range_m", p.fine_max_range_m, "must be finite and > 0");
  if (!(p.fine_min_weight > 0) || !std::isfinite(p.fine_min_weight)) detail::failParam("MapParams", "fine_min_weight", p.fine_min_weight, "must be finite and > 0");
  if (!(p.fine_window_m > 0 && p.fine_window_m <= 1)) detail::failParam("MapParams", "fine_window_m", p.fine_window_m, "must be in (0, 1]");
  if (!(p.fine_support_m > 0 && p.fine_support_m <= 1)) detail::failParam("MapParams", "fine_support_m", p.fine_support_m, "must be in (0, 1]");
  if (!(p.fine_support_length_m >= p.fine_support_m && p.fine_support_length_m <= 1)) detail::failParam("MapParams", "fine_support_length_m", p.fine_support_length_m, "must be in [fine_support_m, 1]");
}

const char* toString(VoxelState s) {
  switch (s) {
    case VoxelState::kUnknown: return "unknown";
    case VoxelState::kFree: return "free";
    case VoxelState::kSurface: return "surface";
  }
  return "unknown";
}

Eigen::Vector3d defaultMapOrigin(const Eigen::Vector3d& first_camera_world) {
  return (first_camera_world / 100).array().round().matrix() * 100;
}

std::optional<std::uint64_t> countOccupiedVoxels(const MobilityOcTree& tree, std::uint64_t limit) {
  const unsigned int depth = tree.getTreeDepth();
  std::uint64_t n = 0;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    if (!tree.isNodeOccupied(*it)) continue;
    const unsigned int levels = depth - it.getDepth();
    if (levels >= 21) return std::nullopt;  // 8^21 voxels would not fit in 64 bits
    n += std::uint64_t{1} << (3 * levels);
    if (n > limit) return std::nullopt;
  }
  return n;
}

std::optional<std::string> voxelBudgetProblem(const MobilityOcTree& tree) {
  const std::uint64_t leaves = tree.getNumLeafNodes();
  const std::uint64_t limit = std::max(kMinVoxelBudget, kMaxVoxelsPerLeaf * leaves);
  if (countOccupiedVoxels(tree, limit)) return std::nullopt;
  unsigned int coarsest = tree.getTreeDepth();
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    if (tree.isNodeOccupied(*it)) coarsest = std::min(coarsest, it.getDepth());
  }
  const unsigned int side = tree.getTreeDepth() - coarsest;
  return "its " + std::to_string(leaves) + " leaves stand for more than " + std::to_string(limit) +
         " occupied voxels (an occupied leaf at depth " + std::to_string(coarsest) + " is a block of 2^" +
         std::to_string(side) + " voxels a side); a map holds at most max(2^20, " + std::to_string(kMaxVoxelsPerLeaf) +
         " x its leaves)";
}

MobilityMap::MobilityMap(MapParams params, const Eigen::Matrix3d& R_map_world, const Eigen::Vector3d& origin_world)
    : MobilityMap(nullptr, params, R_map_world, origin_world) {}

namespace {
void checkOrigin(const Eigen::Vector3d& origin_world) {
  if (!origin_world.allFinite() || origin_world.cwiseAbs().maxCoeff() > kMaxWorldCoordinateM) {
    std::ostringstream msg;
    msg << "MobilityMap: origin_world must be finite and within " << kMaxWorldCoordinateM << " m of the world origin, got ("
        << origin_world.transpose() << ")";
    throw std::invalid_argument(msg.str());
  }
}
}  // namespace

MobilityMap::MobilityMap(std::unique_ptr<MobilityOcTree> tree, MapParams params, const Eigen::Matrix3d& R_map_world,
                         const Eigen::Vector3d& origin_world)
    : params_(params), R_map_world_(R_map_world), origin_world_(origin_world), tree_(std::move(tree)) {
  validate(params_);
  checkOrigin(origin_world);
  Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
  t.topLeftCorner<3, 3>() = R_map_world;
  if (auto problem = checkRigid(t)) throw std::invalid_argument("MobilityMap: R_map_world: " + *problem);
  if (!tree_) tree_ = std::make_unique<MobilityOcTree>(params_.resolution_m);
  params_.resolution_m = tree_->getResolution();
  tree_->setProbHit(params_.prob_hit);
  tree_->setProbMiss(params_.prob_miss);
  tree_->setClampingThresMin(params_.clamp_min);
  tree_->setClampingThresMax(params_.clamp_max);
  if (params_.fine_surface) fine_ = std::make_shared<detail::FineSurface>();
  // A loaded tree: index its occupied voxels (a pruned leaf stands for all its voxels).
  if (auto problem = voxelBudgetProblem(*tree_)) throw std::invalid_argument("MobilityMap: the tree: " + *problem);
  may_be_pruned_ = tree_->size() > 0;
  const unsigned int depth = tree_->getTreeDepth();
  for (auto it = tree_->begin_leafs(), end = tree_->end_leafs(); it != end; ++it) {
    if (!tree_->isNodeOccupied(*it)) continue;
    const unsigned int span = 1u << (depth - it.getDepth());
    const octomap::OcTreeKey base = it.getIndexKey();
    for (unsigned int dx = 0; dx < span; ++dx) {
      for (unsigned int dy = 0; dy < span; ++dy) {
        for (unsigned int dz = 0; dz < span; ++dz) {
          addOccupied(octomap::OcTreeKey(static_cast<octomap::key_type>(base[0] + dx),
                                              static_cast<octomap::key_type>(base[1] + dy),
                                              static_cast<octomap::key_type>(base[2] + dz)));
        }
      }
    }
  }
}

MobilityMap::MobilityMap(const MobilityMap& other)
    : params_(other.params_),
      R_map_world_(other.R_map_world_),
      origin_world_(other.origin_world_),
      tree_(other.tree_->clone()),
      occupied_(other.occupied_),
      occupied_blocks_(other.occupied_blocks_),
      frames_(other.frames_),
      may_be_pruned_(other.may_be_pruned_),
      fine_(other.fine_ ? std::make_shared<detail::FineSurface>(*other.fine_) : nullptr),
      model_(other.model_),
      rough_report_(other.rough_report_),
      rough_voxels_(other.rough_voxels_) {}

std::shared_ptr<const SurfaceColumns> MobilityMap::surfaceColumns() const {
  if (auto kept = std::atomic_load(&columns_)) return kept;
  // Two threads asking at once may both build; both results are the same.
  auto built = std::make_shared<const SurfaceColumns>(*tree_);
  std::atomic_store(&columns_, built);
  return built;
}

HeightScan MobilityMap::heightScan(const std::vector<HeightScanPose>& poses, const HeightScanGrid& grid) const {
  checkHeightScanGrid(grid, poses.size());
  return mapping::heightScan(*surfaceColumns(), poses, grid);
}

void MobilityMap::setOriginWorld(const Eigen::Vector3d& origin_world) {
  if (tree_->size() > 0) throw std::logic_error("MobilityMap::setOriginWorld: the map already holds data");
  checkOrigin(origin_world);
  origin_world_ = origin_world;
}

double MobilityMap::extentM() const {
  return tree_->getResolution() * static_cast<double>(1u << (tree_->getTreeDepth() - 1));
}

IntegrationReport MobilityMap::integrate(const perception::FrameResult& frame, const Eigen::Isometry3d& T_world_camera,
                                         const perception::DepthImage* depth, const perception::PinholeIntrinsics* k) {
  forgetColumns();
  // In double until the points are near the map origin: a world frame in UTM
  // coordinates (~10^6 m) would lose the centimetres in float.
  Eigen::Isometry3d T_map_camera = T_world_camera;
  T_map_camera.linear() = R_map_world_ * T_world_camera.linear();
  T_map_camera.translation() = R_map_world_ * (T_world_camera.translation() - origin_world_);
  IntegrationReport report;

  // One update per voxel per frame. Where several segments share a voxel the least
  // mobile one wins: the conservative reading of an edge between floor and obstacle.
  struct Hit {
    int segment = -1;
    double range = 0.0;
  };
  thread_local FrameVoxels voxels;
  thread_local std::vector<Hit> hits;
  // Each voxel's points this frame, for the fine surface.
  thread_local std::vector<detail::PointMoments> moments;
  voxels.reset(frame.points.size());
  hits.clear();
  moments.clear();
  // With the depth image the fine surface takes every pixel (addPixelMoments); without
  // it, the frame's points.
  const bool fine = fine_ != nullptr && !(depth && k);
  const double max_range2 = params_.max_range_m * params_.max_range_m;
  for (std::size_t i = 0; i < frame.points.size(); ++i) {
    const Eigen::Vector3d pc = frame.points[i].cast<double>();
    const double r2 = pc.squaredNorm();
    if (r2 > max_range2) continue;
    const Eigen::Vector3d p = T_map_camera * pc;
    octomap::OcTreeKey key;
    if (!keyOf(*tree_, p, key)) {
      ++report.points_outside_map;
      continue;
    }
    ++report.points_fused;
    const int seg = frame.segment_of_point.empty() ? -1 : frame.segment_of_point[i];
    const double range = std::sqrt(r2);
    const auto [at, added] = voxels.insert(key);
    if (added) {
      hits.push_back({seg, range});
      if (fine) moments.emplace_back();
    } else {
      Hit& h = hits[at];
      if (seg >= 0 && (h.segment < 0 || frame.segments[static_cast<std::size_t>(seg)].mobility <
                                            frame.segments[static_cast<std::size_t>(h.segment)].mobility)) {
        h.segment = seg;
      }
      h.range = std::min(h.range, range);
    }
    if (fine) addToMoments(moments[at], *tree_, key, p, r2);
  }
  // Consecutive voxels share most of their path from the root (the points come in
  // image order): each descent starts where it parts from the previous one.
  MobilityOcTree::UpdatePath path;
  for (std::size_t i = 0; i < hits.size(); ++i) {
    const Hit& h = hits[i];
    const octomap::OcTreeKey& key = voxels.keys()[i];
    if (may_be_pruned_) expandPrunedAncestors(key);
    bool was_occupied = false;
    MobilityOcTreeNode* node = tree_->updateLeaf(key, true, &was_occupied, &path);
    const bool occupied = tree_->isNodeOccupied(node);
    // An occupied voxel is listed already (occupied_ holds every occupied leaf's key).
    if (!was_occupied && occupied) addOccupied(key);
    if (fine && occupied) fine_->add(key, moments[i], kFineMaxWeight);
    if (h.segment < 0) continue;
    const auto& s = frame.segments[static_cast<std::size_t>(h.segment)];
    node->fuse(s.mobility, s.variance + params_.range_variance_per_m2 * h.range * h.range, params_.max_weight);
  }
  if (depth && k) {
    if (fine_) addPixelMoments(T_map_camera, *depth, *k);
    clearSeenThrough(T_map_camera, *depth, *k);
    if (params_.free_space_ray_stride_px > 0) castFreeRays(T_map_camera, *depth, *k);
  }
  ++frames_;
  return report;
}

// OctoMap's updateNode() stops at the first node on the key's path that has no children
// when the update cannot change its (clamped) occupancy, and returns it: after pruning
// that may be a node standing for a whole block of equal voxels, and the mobility fused
// into it next would overwrite the block. Expanding pruned nodes on the path first
// makes it return the voxel itself. (Leaves above the finest level only come from
// pruning: every update here is at the finest level.)
void MobilityMap::expandPrunedAncestors(const octomap::OcTreeKey& key) {
  MobilityOcTreeNode* node = tree_->getRoot();
  const unsigned int depth = tree_->getTreeDepth();
  for (unsigned int d = 0; node && d < depth; ++d) {
    if (!tree_->nodeHasChildren(node)) tree_->expandNode(node);
    const unsigned int child = octomap::computeChildIdx(key, static_cast<int>(depth - 1 - d));
    if (!tree_->nodeChildExists(node, child)) return;  // nothing stored here yet: updateNode creates the path
    node = tree_->getNodeChild(node, child);
  }
}

void MobilityMap::addOccupied(const octomap::OcTreeKey& key) {
  if (occupied_.insert(key).second) occupied_blocks_[blockOf(key)].push_back(key);
}

void MobilityMap::removeOccupied(const octomap::OcTreeKey& key) {
  if (occupied_.erase(key) == 0) return;
  if (fine_) fine_->erase(key);  // what was there has gone: its points with it
  const auto it = occupied_blocks_.find(blockOf(key));
  if (it == occupied_blocks_.end()) return;
  auto& keys = it->second;
  const auto at = std::find(keys.begin(), keys.end(), key);
  if (at != keys.end()) {
    *at = keys.back();
    keys.pop_back();
  }
  if (keys.empty()) occupied_blocks_.erase(it);
}

// Each depth pixel within range, as a point weighted by (1.5 m / range)^4, into the
// moments of its voxel when that voxel is occupied. Pixels, not the frame's points: the
// perception's 1 cm reduction and denoising round the edges of texture a few
// centimetres tall that the fine surface is there to keep.
void MobilityMap::addPixelMoments(const Eigen::Isometry3d& T_map_camera, const perception::DepthImage& depth,
                                  const perception::PinholeIntrinsics& k) {
  thread_local FrameVoxels voxels;
  thread_local std::vector<detail::PointMoments> moments;
  const int w = std::min(depth.width, k.width), h = std::min(depth.height, k.height);
  voxels.reset(static_cast<std::size_t>((w + kFinePixelStride - 1) / kFinePixelStride) *
               static_cast<std::size_t>((h + kFinePixelStride - 1) / kFinePixelStride));
  moments.clear();
  const Eigen::Matrix3f R = T_map_camera.linear().cast<float>();
  const Eigen::Vector3f t = T_map_camera.translation().cast<float>();
  const double fine_range = std::min(params_.max_range_m, params_.fine_max_range_m);
  const float max_range2 = static_cast<float>(fine_range * fine_range);
  const float fx = static_cast<float>(k.fx), fy = static_cast<float>(k.fy);
  const float cx = static_cast<float>(k.cx), cy = static_cast<float>(k.cy);
  for (int v = 0; v < h; v += kFinePixelStride) {
    const float yv = (static_cast<float>(v) - cy) / fy;
    for (int u = 0; u < w; u += kFinePixelStride) {
      const float d = depth.at(u, v);
      if (!(d > 0.f) || !std::isfinite(d)) continue;
      const Eigen::Vector3f pc((static_cast<float>(u) - cx) / fx * d, yv * d, d);
      const float r2 = pc.squaredNorm();
      if (r2 > max_range2) continue;
      const Eigen::Vector3d p = (R * pc + t).cast<double>();
      octomap::OcTreeKey key;
      if (!keyOf(*tree_, p, key)) continue;
      const auto [at, added] = voxels.insert(key);
      if (added) moments.emplace_back();
      addToMoments(moments[at], *tree_, key, p, r2);
    }
  }
  for (std::size_t i = 0; i < moments.size(); ++i) {
    const octomap::OcTreeKey& key = voxels.keys()[i];
    if (occupied_.count(key)) fine_->add(key, moments[i], kFineMaxWeight);
  }
}

void MobilityMap::clearSeenThrough(const Eigen::Isometry3d& T_map_camera, const perception::DepthImage& depth,
                                   const perception::PinholeIntrinsics& k) {
  const Eigen::Isometry3d T_camera_map = T_map_camera.inverse();
  const Eigen::Matrix3f R = T_camera_map.linear().cast<float>();
  const Eigen::Vector3f t = T_camera_map.translation().cast<float>();
  const double res = tree_->getResolution();
  const float base_margin = static_cast<float>(std::max(params_.free_space_margin_m, 1.5 * res));
  const float max_range = static_cast<float>(params_.max_range_m);
  const float fx = static_cast<float>(k.fx), fy = static_cast<float>(k.fy);
  const float cx = static_cast<float>(k.cx), cy = static_cast<float>(k.cy);
  std::vector<octomap::OcTreeKey> seen_through;
  const auto visit = [&](const octomap::OcTreeKey& key) {
    const octomap::point3d c = tree_->keyToCoord(key);
    const Eigen::Vector3f pc = R * Eigen::Vector3f(c.x(), c.y(), c.z()) + t;
    if (pc.z() < 0.1f || pc.z() > max_range) return;
    const float u = fx * pc.x() / pc.z() + cx, v = fy * pc.y() / pc.z() + cy;
    if (!(std::abs(u) < 1e6f && std::abs(v) < 1e6f)) return;  // far outside the image
    const int ui = roundHalfAway(u), vi = roundHalfAway(v);
    if (ui < 0 || vi < 0 || ui >= k.width || vi >= k.height) return;
    const float d = depth.at(ui, vi);
    if (!(d > 0.f) || !std::isfinite(d)) return;
    // Depth noise grows with the square of the distance (Kinect: ~1.5 mm at 1 m plus
    // quantisation ~2.3 mm): 0.5 cm/m^2 is several sigma.
    const float margin = base_margin + 0.005f * pc.z() * pc.z();
    if (d > pc.z() + margin) seen_through.push_back(key);
  };
  // A block is skipped when its bounding sphere (plus 1 cm, more than the half pixel the
  // rounding above lets in) lies behind the camera, beyond the range or outside one of
  // the four planes through the image borders: none of its voxels could pass `visit`.
  const float block_radius = static_cast<float>((kBlock / 2 + 1) * res * std::sqrt(3.0) + 0.01);
  const Eigen::Vector3f planes[4] = {Eigen::Vector3f(fx, 0, cx).normalized(),
                                     Eigen::Vector3f(-fx, 0, static_cast<float>(k.width) - cx).normalized(),
                                     Eigen::Vector3f(0, fy, cy).normalized(),
                                     Eigen::Vector3f(0, -fy, static_cast<float>(k.height) - cy).normalized()};
  for (const auto& [block, keys] : occupied_blocks_) {
    const octomap::OcTreeKey& first = keys.front();
    const auto centre = [&](unsigned axis) {
      return static_cast<octomap::key_type>((first[axis] & ~static_cast<unsigned>(kBlock - 1)) + kBlock / 2);
    };
    // The key at the block's centre names the voxel just past the middle: half a voxel
    // off, inside the 1 cm allowance.
    const octomap::point3d bc = tree_->keyToCoord(octomap::OcTreeKey(centre(0), centre(1), centre(2)));
    const Eigen::Vector3f bp = R * Eigen::Vector3f(bc.x(), bc.y(), bc.z()) + t;
    if (bp.z() + block_radius < 0.1f || bp.z() - block_radius > max_range) continue;
    bool outside = false;
    for (const auto& n : planes) outside = outside || n.dot(bp) < -block_radius;
    if (outside) continue;
    for (const auto& key : keys) visit(key);
  }
  MobilityOcTree::UpdatePath path;  // the keys come block by block
  for (const auto& key : seen_through) {
    MobilityOcTreeNode* node = tree_->updateLeaf(key, false, nullptr, &path);
    if (!tree_->isNodeOccupied(node)) {
      removeOccupied(key);
      node->clearMobility();  // no longer a surface: its mobility described what was there
    }
  }
}

void MobilityMap::castFreeRays(const Eigen::Isometry3d& T_map_camera, const perception::DepthImage& depth,
                               const perception::PinholeIntrinsics& k) {
  const int stride = params_.free_space_ray_stride_px;
  const double res = tree_->getResolution();
  const octomap::point3d origin = toOcto(T_map_camera.translation());
  octomap::KeySet free;
  octomap::KeyRay ray;
  for (int v = stride / 2; v < k.height; v += stride) {
    for (int u = stride / 2; u < k.width; u += stride) {
      const float d = depth.at(u, v);
      if (!(d > 0.f) || !std::isfinite(d)) continue;
      const Eigen::Vector3d pc = perception::backProject(k, u, v, d);
      const double range = pc.norm();
      // Stop short of the surface so its own voxel (and noise around it) is not freed.
      const double reach = std::min(range - std::max(params_.free_space_margin_m, 3 * res), params_.max_range_m);
      if (reach <= res) continue;
      const Eigen::Vector3d end = T_map_camera * (pc * (reach / range));
      if (!tree_->computeRayKeys(origin, toOcto(end), ray)) continue;
      free.insert(ray.begin(), ray.end());
    }
  }
  for (const auto& key : free) tree_->updateNode(key, false, true);
}

void MobilityMap::finalize() {
  forgetColumns();
  if (fine_) {
    static const gp::MobilityModel default_model;
    rough_voxels_.clear();
    // Every surface voxel, in a fixed order (the scores do not depend on it; the list of
    // rough voxels does).
    std::vector<octomap::OcTreeKey> keys(occupied_.begin(), occupied_.end());
    std::sort(keys.begin(), keys.end(), [](const octomap::OcTreeKey& a, const octomap::OcTreeKey& b) {
      return std::tie(a[0], a[1], a[2]) < std::tie(b[0], b[1], b[2]);
    });
    rough_report_ = detail::scoreRoughGround(
        *fine_, keys, *tree_, params_, model_ ? *model_ : default_model,
        [this](const octomap::OcTreeKey& key) -> MobilityOcTreeNode* {
          if (may_be_pruned_) expandPrunedAncestors(key);
          return tree_->search(key);
        },
        &rough_voxels_);
  }
  tree_->updateInnerOccupancy();
  tree_->prune();
  may_be_pruned_ = true;
}

PointQuery MobilityMap::describe(const octomap::OcTreeKey& key, const MobilityOcTreeNode* node, unsigned int depth) const {
  PointQuery q;
  const octomap::point3d c = tree_->keyToCoord(key, depth);
  q.centre = Eigen::Vector3d(c.x(), c.y(), c.z());
  q.size_m = tree_->getNodeSize(depth);
  if (!node) return q;
  q.occupancy = node->getOccupancy();
  q.state = tree_->isNodeOccupied(node) ? VoxelState::kSurface : VoxelState::kFree;
  q.has_mobility = node->hasMobility();
  q.mobility = q.has_mobility ? node->mobility() : 0.0;
  q.variance = node->variance();
  q.count = node->count();
  return q;
}

PointQuery MobilityMap::query(const Eigen::Vector3d& p) const {
  octomap::OcTreeKey key;
  PointQuery unknown;
  unknown.size_m = tree_->getResolution();
  if (!keyOf(*tree_, p, key)) {
    unknown.centre = p;
    unknown.outside_map = true;
    return unknown;
  }
  // Descend by hand to learn the depth of the (possibly pruned) leaf; like
  // OcTree::search, test for children only where the path ends.
  const unsigned int max_depth = tree_->getTreeDepth();
  const MobilityOcTreeNode* node = tree_->getRoot();
  unsigned int depth = 0;
  while (node && depth < max_depth) {
    const unsigned int pos = octomap::computeChildIdx(key, static_cast<int>(max_depth - 1 - depth));
    if (tree_->nodeChildExists(node, pos)) {
      node = tree_->getNodeChild(node, pos);
      ++depth;
    } else {
      if (tree_->nodeHasChildren(node)) node = nullptr;  // an unknown octant of a known parent
      break;
    }
  }
  return describe(key, node, node ? depth : max_depth);
}

std::optional<PointQuery> MobilityMap::snapDown(const Eigen::Vector3d& p, double max_drop_m) const {
  octomap::OcTreeKey key;
  if (!(max_drop_m >= 0) || !std::isfinite(max_drop_m) || !keyOf(*tree_, p, key)) {
    return std::nullopt;
  }
  // Voxel by voxel through the column, each asked at its centre: stepping a point down by
  // the resolution from a height on a voxel face (z = 0.15 at 1 cm) lands on faces, where
  // rounding can skip a voxel.
  const double res = tree_->getResolution();
  const double lowest = p.z() - max_drop_m;
  for (int kz = key[2]; kz >= 0; --kz) {
    const double centre = tree_->keyToCoord(static_cast<octomap::key_type>(kz));
    if (kz != key[2] && centre + res / 2 <= lowest + 1e-9) break;  // wholly below the search
    const PointQuery q = query({p.x(), p.y(), centre});
    if (q.state == VoxelState::kSurface) return q;
  }
  return std::nullopt;
}

namespace {

// The support plane's answers for footprint(): its gradient turned into the map frame by
// the sole's yaw, its height at the centre, tilt and the RMS of the tops about it.
void describeSupportPlane(const std::vector<detail::SupportSample>& support, double cos_yaw, double sin_yaw,
                          FootprintQuery& out) {
  const auto plane = detail::fitSupportPlane(support);
  if (!plane) return;
  double sq = 0.0;
  for (const auto& p : support) {
    const double r = p.top - plane->at(p.a, p.b);
    sq += r * r;
  }
  const Eigen::Vector2d& g = plane->gradient;
  const double gx = cos_yaw * g.x() - sin_yaw * g.y(), gy = sin_yaw * g.x() + cos_yaw * g.y();
  out.has_support_plane = true;
  out.support_height_m = plane->at(0, 0);  // the sole's centre
  out.support_normal = Eigen::Vector3d(-gx, -gy, 1.0).normalized();
  out.support_tilt_deg = plane->tiltDeg();
  out.support_rms_m = std::sqrt(sq / static_cast<double>(support.size()));
}

}  // namespace

std::vector<SoleSample> soleSamples(const Foot& f, double res) {
  std::vector<SoleSample> out;
  soleSamples(f, res, out);
  return out;
}

void soleSamples(const Foot& f, double res, std::vector<SoleSample>& out) {
  out.clear();
  const bool valid = std::isfinite(f.x) && std::isfinite(f.y) && std::isfinite(f.yaw) && f.length > 0 && f.width > 0 &&
                     res > 0 && f.length / res <= kMaxSoleSamplesPerSide && f.width / res <= kMaxSoleSamplesPerSide;
  if (!valid) return;
  const int nl = std::max(1, static_cast<int>(std::ceil(f.length / res)));
  const int nw = std::max(1, static_cast<int>(std::ceil(f.width / res)));
  const double c = std::cos(f.yaw), s = std::sin(f.yaw);
  out.reserve(static_cast<std::size_t>(nl) * static_cast<std::size_t>(nw));
  for (int i = 0; i < nl; ++i) {
    for (int j = 0; j < nw; ++j) {
      const double a = (i + 0.5) * f.length / nl - 0.5 * f.length;
      const double b = (j + 0.5) * f.width / nw - 0.5 * f.width;
      out.push_back({a, b, f.x + c * a - s * b, f.y + s * a + c * b});
    }
  }
}

FootprintQuery MobilityMap::footprint(const Foot& f, double search_up_m, double search_down_m) const {
  FootprintQuery out;
  const std::vector<SoleSample> samples = soleSamples(f, tree_->getResolution());
  double sum = 0.0, zmin = std::numeric_limits<double>::infinity(), zmax = -zmin;
  int known = 0;
  out.min_mobility = 1.0;
  // Supported samples for the plane: sole coordinates and the top face of the voxel
  // each rests on.
  std::vector<detail::SupportSample> support;
  support.reserve(samples.size());
  const double res = tree_->getResolution();
  // The surface at (x, y) in [lo, hi]: the top voxel of the highest run of occupied voxels
  // whose top face lies in it (a run rising above hi is no surface to rest on; the next
  // run below it may be), as SurfaceColumns::runBelow() finds it.
  const auto runTopIn = [&](double x, double y, double lo, double hi) -> std::optional<PointQuery> {
    lo -= 1e-6, hi += 1e-6;
    double from = hi;
    while (from > lo) {
      const auto q = snapDown({x, y, from}, from - lo);
      if (!q) return std::nullopt;
      // The top of its run: snapDown walked down to it through voxels that are not surface,
      // unless it holds the height the walk started from.
      const double top = q->centre.z() + q->size_m / 2;
      if (top <= hi && (top < from - 1e-9 || query({x, y, top + res / 2}).state != VoxelState::kSurface)) return q;
      double z = q->centre.z();
      while (z > lo && query({x, y, z}).state == VoxelState::kSurface) z -= res;
      from = z;
    }
    return std::nullopt;
  };
  // The reference height: the surface under the centre, as Reachability::sole() takes it.
  double z_ref = f.z;
  if (const auto centre = runTopIn(f.x, f.y, f.z - search_down_m, f.z + search_up_m)) {
    z_ref = centre->centre.z() + centre->size_m / 2;
  }
  const auto restOn = [&](double x, double y) { return runTopIn(x, y, z_ref - search_down_m, z_ref + search_up_m); };
  for (const SoleSample& sample : samples) {
    ++out.samples;
    const auto q = restOn(sample.x, sample.y);
    if (!q) continue;
    zmin = std::min(zmin, q->centre.z());
    zmax = std::max(zmax, q->centre.z());
    support.push_back({sample.a, sample.b, q->centre.z() + q->size_m / 2});
    // The run's mobility: this voxel's, else the highest voxel's below it in the run.
    std::optional<double> mobility;
    if (q->has_mobility) mobility = q->mobility;
    for (double z = q->centre.z() - res; !mobility; z -= res) {
      const PointQuery below = query({sample.x, sample.y, z});
      if (below.state != VoxelState::kSurface) break;
      if (below.has_mobility) mobility = below.mobility;
    }
    if (!mobility) continue;
    ++known;
    sum += *mobility;
    out.min_mobility = std::min(out.min_mobility, *mobility);
  }
  out.known_fraction = out.samples ? static_cast<double>(known) / out.samples : 0.0;
  out.mean_mobility = known ? sum / known : 0.0;
  if (!known) out.min_mobility = 0.0;
  out.max_height_difference_m = std::isfinite(zmin) ? zmax - zmin : 0.0;
  describeSupportPlane(support, std::cos(f.yaw), std::sin(f.yaw), out);
  return out;
}

std::vector<FineSurfacePoint> MobilityMap::fineSurface(double min_weight) const {
  std::vector<FineSurfacePoint> out;
  if (!fine_) return out;
  out.reserve(fine_->voxels().size());
  forEachFinePlane(*fine_, *tree_, min_weight, [&](const octomap::OcTreeKey&, const detail::VoxelPlane& p) {
    FineSurfacePoint f;
    f.point = p.mean.cast<double>();
    f.normal = p.normal.cast<double>();
    f.weight = p.weight;
    f.views = p.views;
    out.push_back(f);
  });
  return out;
}

std::size_t MobilityMap::fineSurfaceBytes() const { return fine_ ? fine_->memoryBytes() : 0; }

void MobilityMap::saveFineSurfacePly(const std::string& path, double min_weight) const {
  static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "the PLY is written as binary_little_endian from memory");
  struct Vertex {
    float x, y, z, nx, ny, nz, weight;
    std::uint16_t views;
    float roughness, mobility;
  };
  std::unordered_map<octomap::OcTreeKey, float, octomap::OcTreeKey::KeyHash> rough;
  for (const RoughVoxel& v : rough_voxels_) {
    octomap::OcTreeKey key;
    if (keyOf(*tree_, v.centre, key)) rough[key] = static_cast<float>(v.roughness);
  }
  std::vector<Vertex> vertices;
  if (fine_) {
    vertices.reserve(fine_->voxels().size());
    forEachFinePlane(*fine_, *tree_, min_weight, [&](const octomap::OcTreeKey& key, const detail::VoxelPlane& p) {
      const MobilityOcTreeNode* node = tree_->search(key);
      const auto r = rough.find(key);
      vertices.push_back({p.mean.x(), p.mean.y(), p.mean.z(), p.normal.x(), p.normal.y(), p.normal.z(), p.weight, p.views,
                          r == rough.end() ? 0.0f : r->second,
                          node && node->hasMobility() ? static_cast<float>(node->mobility()) : -1.0f});
    });
  }
  // Sorted by position, so the file is the same however the table was filled.
  std::sort(vertices.begin(), vertices.end(), [](const Vertex& a, const Vertex& b) {
    return std::tie(a.x, a.y, a.z) < std::tie(b.x, b.y, b.z);
  });
  writeAtomically(path, [&](std::ostream& s) {
    s << "ply\nformat binary_little_endian 1.0\ncomment mobmap fused fine surface, map frame, metres\n"
      << "element vertex " << vertices.size() << "\n"
      << "property float x\nproperty float y\nproperty float z\n"
      << "property float nx\nproperty float ny\nproperty float nz\n"
      << "property float weight\nproperty ushort views\nproperty float roughness\nproperty float mobility\nend_header\n";
    const auto put = [&](const void* data, std::size_t n) {
      s.write(static_cast<const char*>(data), static_cast<std::streamsize>(n));
    };
    for (const Vertex& v : vertices) {
      put(&v.x, 4), put(&v.y, 4), put(&v.z, 4), put(&v.nx, 4), put(&v.ny, 4), put(&v.nz, 4), put(&v.weight, 4);
      put(&v.views, 2), put(&v.roughness, 4), put(&v.mobility, 4);
    }
    return static_cast<bool>(s);
  });
}

}  // namespace mobmap::mapping
