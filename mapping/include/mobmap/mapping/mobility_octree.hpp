#pragma once
/// @file mobility_octree.hpp
/// An OctoMap whose voxels carry a fused mobility score besides occupancy.

#include <octomap/OccupancyOcTreeBase.h>
#include <octomap/OcTreeNode.h>

#include <cstdint>
#include <istream>
#include <memory>
#include <ostream>
#include <string>

namespace mobmap::mapping {

/// A voxel: occupancy log-odds (OctoMap's float) plus a 32-bit mobility payload, so the
/// node is no larger than octomap::OcTreeNode (16 bytes on x86-64: the 12 bytes of
/// children pointer and value are padded to 16 anyway).
///
/// Payload layout (bit 31 first): 14 bits mobility in [0,1] (step 1/16383), 10 bits
/// fusion weight W = sum of 1/variance on a log2 scale (step 2^(1/32), 2.2 %, covering
/// 2^-16..2^16), 8 bits observation count (saturating at 255). Count 0 means the
/// mobility is unknown, which is distinct from mobility 0 (untraversable). Fusion
/// rounds the mobility stochastically (deterministically seeded by the voxel's own
/// state), so many small updates are not lost to rounding.
///
/// Inner nodes hold a conservative aggregate: the minimum known mobility of their
/// children (with that child's weight), the summed count (saturating); a coarse query
/// can therefore never report an area as better than its worst known voxel.
class MobilityOcTreeNode : public octomap::OcTreeNode {
 public:
  friend class MobilityOcTree;
  MobilityOcTreeNode() = default;
  MobilityOcTreeNode(const MobilityOcTreeNode& rhs) : octomap::OcTreeNode(rhs), payload_(rhs.payload_) {}
  MobilityOcTreeNode& operator=(const MobilityOcTreeNode&) = default;

  /// Equal occupancy and identical payload: the pruning criterion, so voxels whose
  /// mobility differs by even one quantisation step are never merged.
  bool operator==(const MobilityOcTreeNode& rhs) const { return rhs.value == value && rhs.payload_ == payload_; }
  void copyData(const MobilityOcTreeNode& from) {
    octomap::OcTreeNode::copyData(from);
    payload_ = from.payload_;
  }

  [[nodiscard]] bool hasMobility() const { return count() > 0; }
  /// Fused mobility in [0,1]; meaningless when !hasMobility().
  [[nodiscard]] double mobility() const;
  /// 1 / (sum of observation weights); +inf when unknown.
  [[nodiscard]] double variance() const;
  [[nodiscard]] double weight() const;
  [[nodiscard]] int count() const { return static_cast<int>(payload_ & 0xffu); }
  [[nodiscard]] std::uint32_t payload() const { return payload_; }

  /// Sets the fields directly (quantising them). weight > 0, mobility in [0,1].
  void setMobility(double mobility, double weight, int count);
  /// Forgets the mobility (count 0).
  void clearMobility() { payload_ = 0; }
  /// Inverse-variance fusion of one observation: m = (W m + w x) / (W + w),
  /// W = min(W + w, max_weight), with w = 1 / variance. Capping W keeps the map able
  /// to follow change (see docs/MAPPING.md).
  void fuse(double mobility, double variance, double max_weight);

  /// Inner-node aggregate from the children (see the class comment). A child without
  /// children stands for `leaf_child_voxels` voxels of the finest level (more than one
  /// when it is a pruned node, whose count is that of each voxel it replaced), so the
  /// summed count is the same whether or not the tree was pruned before.
  void updateMobilityChildren(int leaf_child_voxels = 1);

  std::istream& readData(std::istream& s);
  std::ostream& writeData(std::ostream& s) const;

  /// Quantisation helpers (exposed for tests).
  static std::uint32_t encodeMobility(double m);
  static double decodeMobility(std::uint32_t code);
  static std::uint32_t encodeWeight(double w);
  static double decodeWeight(std::uint32_t code);

 private:
  std::uint32_t payload_ = 0;
};

/// The tree. Type id "MobilityOcTree_v1" (the .ot format has no version field: the
/// suffix changes whenever the payload layout does). Not thread-safe for writes;
/// const queries may run concurrently while nothing modifies the tree.
class MobilityOcTree : public octomap::OccupancyOcTreeBase<MobilityOcTreeNode> {
 public:
  static constexpr const char* kTreeType = "MobilityOcTree_v1";

  explicit MobilityOcTree(double resolution);
  MobilityOcTree* create() const override { return new MobilityOcTree(resolution); }
  /// A deep copy: every node with its occupancy and payload, and the sensor model.
  /// (OctoMap's copy constructor copies children as its own base node type, which
  /// drops the payload and leaves nodes too small for a MobilityOcTreeNode: do not use it.)
  [[nodiscard]] std::unique_ptr<MobilityOcTree> clone() const;
  std::string getTreeType() const override { return kTreeType; }

  /// Children may be merged only when they are equal in occupancy and payload.
  bool isNodeCollapsible(const MobilityOcTreeNode* node) const override;

  /// Recomputes inner-node occupancy (max of children, OctoMap's rule) and the
  /// mobility aggregate (min of children) over the whole tree.
  /// (Hides the base's non-virtual method: call it on a MobilityOcTree.)
  void updateInnerOccupancy();

  /// updateNode(key, occupied, lazy_eval = true) in one descent instead of two (OctoMap
  /// searches the key first, for its early return at the clamping bound, then walks
  /// down again): the same tree and the same node returned, the search's early return
  /// included. `was_occupied`, if given, tells whether the voxel was occupied before
  /// the update: by its own leaf or by the pruned leaf holding it (false for a voxel
  /// the update creates).
  /// With `path`, the descent starts at the deepest node the key shares with the path
  /// of the previous key updated through the same `path` (a run of nearby keys skips
  /// most of the tree's 16 levels). A path is valid while the tree is only changed by
  /// updateLeaf, updateNode with lazy_eval and expandNode: no prune(), clear(), node
  /// deletion or reading in between.
  struct UpdatePath {
    octomap::OcTreeKey key{0, 0, 0};
    MobilityOcTreeNode* nodes[17] = {};  ///< nodes[d]: the node at depth d on key's path
    int valid = -1;                      ///< nodes[0 .. valid] are set
  };
  MobilityOcTreeNode* updateLeaf(const octomap::OcTreeKey& key, bool occupied, bool* was_occupied = nullptr,
                                 UpdatePath* path = nullptr);

  /// Reads node data written by write()/writeData() with every read checked: stops at
  /// the first failed read or after `max_nodes` nodes instead of trusting the stream
  /// (OctoMap's own reader keeps recursing on a truncated file). Returns an empty
  /// string on success, else the reason. The tree must be empty.
  std::string readDataChecked(std::istream& s, std::size_t max_nodes);

 protected:
  void updateInnerOccupancyRecurs(MobilityOcTreeNode* node, unsigned int depth);
  bool readNodesChecked(MobilityOcTreeNode* node, std::istream& s, std::size_t max_nodes, std::size_t& read,
                        unsigned int depth);

  /// Registers the type with OctoMap's factory so AbstractOcTree::read() can create it.
  class StaticMemberInitializer {
   public:
    StaticMemberInitializer();
    void ensureLinking() {}
  };
  static StaticMemberInitializer mobility_octree_member_init_;
};

}  // namespace mobmap::mapping
