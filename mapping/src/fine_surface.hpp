#pragma once
// The fused fine surface: per-voxel point moments (weight, mean, covariance) fused from
// every frame, so each surface voxel holds a plane finer than its own size, and rough
// ground scored on the height field those planes make at the scale of a foot
// (docs/ALGORITHM.md, "Rough ground from the fused surface").

#include "mobmap/gp/mobility_model.hpp"
#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/mapping/mobility_octree.hpp"

#include <octomap/OcTreeKey.h>

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <unordered_map>
#include <vector>

namespace mobmap::mapping::detail {

// A voxel's points, each weighted, as offsets from the voxel's centre (float keeps them
// exact enough: offsets of at most a voxel, variances down to a millimetre squared).
struct PointMoments {
  float w = 0;
  float s[3] = {0, 0, 0};              // sum of w d
  float ss[6] = {0, 0, 0, 0, 0, 0};    // sum of w d d^T: xx xy xz yy yz zz
  std::uint16_t views = 0;             // frames that added points (saturating)

  void add(const Eigen::Vector3f& d, float weight) {
    w += weight;
    for (int i = 0; i < 3; ++i) s[i] += weight * d[i];
    ss[0] += weight * d.x() * d.x(), ss[1] += weight * d.x() * d.y(), ss[2] += weight * d.x() * d.z();
    ss[3] += weight * d.y() * d.y(), ss[4] += weight * d.y() * d.z(), ss[5] += weight * d.z() * d.z();
  }
  // Adds another voxel's moments (one frame's); past `cap` the sum is scaled back to it,
  // so old views fade and the surface can follow change.
  void merge(const PointMoments& o, float cap);
  [[nodiscard]] Eigen::Vector3f mean() const { return Eigen::Vector3f(s[0], s[1], s[2]) / w; }
  [[nodiscard]] Eigen::Matrix3f covariance() const;
};

// The moments of every surface voxel with points (finest keys).
class FineSurface {
 public:
  using Table = std::unordered_map<octomap::OcTreeKey, PointMoments, octomap::OcTreeKey::KeyHash>;
  void add(const octomap::OcTreeKey& key, const PointMoments& frame, float cap) {
    PointMoments& m = voxels_[key];
    m.merge(frame, cap);
  }
  void erase(const octomap::OcTreeKey& key) { voxels_.erase(key); }
  void clear() { voxels_.clear(); }
  [[nodiscard]] const Table& voxels() const { return voxels_; }
  [[nodiscard]] std::size_t memoryBytes() const;

 private:
  Table voxels_;
};

// One voxel's plane from its moments: the mean (map frame) and the normal (the
// covariance's smallest axis, pointing up or, for a vertical plane, anywhere).
struct VoxelPlane {
  octomap::OcTreeKey key;
  Eigen::Vector3f mean;
  Eigen::Vector3f normal;
  float weight = 0;
  float thickness = 0;  // the points' spread across the plane (RMS): noise, or a crease
  std::uint16_t views = 0;
};
[[nodiscard]] VoxelPlane planeOf(const MobilityOcTree& tree, const octomap::OcTreeKey& key, const PointMoments& m);

// Scores the surface voxels `voxels` where they are rough ground on the fine surface
// (see the file comment) and writes the result into them. `node_of` gives the tree's
// finest node of a key (nullptr for none), expanding pruned blocks as needed.
RoughGroundReport scoreRoughGround(const FineSurface& surface, const std::vector<octomap::OcTreeKey>& voxels,
                                   const MobilityOcTree& tree, const MapParams& params, const gp::MobilityModel& model,
                                   const std::function<MobilityOcTreeNode*(const octomap::OcTreeKey&)>& node_of,
                                   std::vector<RoughVoxel>* rough);

}  // namespace mobmap::mapping::detail
