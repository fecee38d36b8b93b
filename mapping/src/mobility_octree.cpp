#include "mobmap/mapping/mobility_octree.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace mobmap::mapping {
namespace {

constexpr std::uint32_t kMobilityMax = 0x3fffu;  // 14 bits
constexpr std::uint32_t kWeightMax = 0x3ffu;     // 10 bits
constexpr double kWeightStepsPerOctave = 32.0;   // log2 step 1/32: 2.2 % relative
constexpr double kWeightLog2Min = -16.0;         // code 0 <-> 2^-16, code 1023 <-> ~2^16

std::uint32_t pack(std::uint32_t m, std::uint32_t w, std::uint32_t c) { return (m << 18) | (w << 8) | c; }
std::uint32_t mobilityCode(std::uint32_t p) { return p >> 18; }
std::uint32_t weightCode(std::uint32_t p) { return (p >> 8) & kWeightMax; }

// A uniform number in [0,1) from the voxel's state and the observation: stochastic
// rounding that is reproducible run to run.
double dither(std::uint32_t payload, double m) {
  std::uint64_t x = (static_cast<std::uint64_t>(payload) << 32) ^ static_cast<std::uint64_t>(m * 4294967295.0);
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  x ^= x >> 31;
  return static_cast<double>(x >> 11) * 0x1.0p-53;
}

}  // namespace

MobilityOcTreeNode* MobilityOcTree::updateLeaf(const octomap::OcTreeKey& key, bool occupied, bool* was_occupied,
                                               UpdatePath* path) {
  if (was_occupied) *was_occupied = false;
  if (use_change_detection || tree_depth != 16) {  // change detection keeps OctoMap's key bookkeeping
    if (path) path->valid = -1;
    return updateNode(key, occupied, true);
  }
  const float update = occupied ? prob_hit_log : prob_miss_log;
  // OctoMap leaves a node as it is when the update cannot move it past the clamp.
  const auto saturated = [&](const MobilityOcTreeNode* n) {
    return (update >= 0 && n->getLogOdds() >= clamping_thres_max) || (update <= 0 && n->getLogOdds() <= clamping_thres_min);
  };
  bool created = false;
  if (!root) {
    root = new MobilityOcTreeNode();
    ++tree_size;
    created = true;
    if (path) path->valid = -1;
  }
  MobilityOcTreeNode* node = root;
  unsigned int depth = 0;
  if (path && path->valid >= 0) {
    // The node at depth d is fixed by the top d bits of each key coordinate; every node
    // of the previous path exists and, above its end, has children, so starting at the
    // deepest shared one is where OctoMap's walk from the root would arrive.
    const unsigned int differ = static_cast<unsigned int>((key[0] ^ path->key[0]) | (key[1] ^ path->key[1]) |
                                                          (key[2] ^ path->key[2]));
    const int shared = differ == 0 ? 16 : __builtin_clz(differ) - 16;
    depth = static_cast<unsigned int>(std::min(shared, path->valid));
    node = path->nodes[depth];
  }
  const auto remember = [&](unsigned int reached) {
    if (!path) return;
    path->nodes[0] = root;
    path->key = key;
    path->valid = static_cast<int>(reached);
  };
  for (; depth < tree_depth; ++depth) {
    const unsigned int pos = octomap::computeChildIdx(key, static_cast<int>(tree_depth - 1 - depth));
    if (!nodeChildExists(node, pos)) {
      if (!nodeHasChildren(node) && !created) {
        // A leaf above the finest level (pruned): OctoMap's search ends here and its
        // early return looks at this node; otherwise it is expanded.
        if (was_occupied) *was_occupied = isNodeOccupied(node);
        if (saturated(node)) {
          remember(depth);
          return node;
        }
        expandNode(node);
      } else {
        // The search would have found nothing (no early return): the path is new from here.
        createNodeChild(node, pos);
        created = true;
      }
    }
    node = getNodeChild(node, pos);
    if (path) path->nodes[depth + 1] = node;
  }
  remember(tree_depth);
  if (!created) {
    if (was_occupied) *was_occupied = isNodeOccupied(node);
    if (saturated(node)) return node;
  }
  updateNodeLogOdds(node, update);
  return node;
}

std::uint32_t MobilityOcTreeNode::encodeMobility(double m) {
  return static_cast<std::uint32_t>(std::lround(std::clamp(m, 0.0, 1.0) * kMobilityMax));
}
double MobilityOcTreeNode::decodeMobility(std::uint32_t code) { return static_cast<double>(code) / kMobilityMax; }

std::uint32_t MobilityOcTreeNode::encodeWeight(double w) {
  if (!(w > 0)) return 0;
  const double code = std::round((std::log2(w) - kWeightLog2Min) * kWeightStepsPerOctave);
  return static_cast<std::uint32_t>(std::clamp(code, 0.0, static_cast<double>(kWeightMax)));
}
double MobilityOcTreeNode::decodeWeight(std::uint32_t code) {
  return std::exp2(static_cast<double>(code) / kWeightStepsPerOctave + kWeightLog2Min);
}

double MobilityOcTreeNode::mobility() const { return decodeMobility(mobilityCode(payload_)); }
double MobilityOcTreeNode::weight() const { return hasMobility() ? decodeWeight(weightCode(payload_)) : 0.0; }
double MobilityOcTreeNode::variance() const {
  return hasMobility() ? 1.0 / decodeWeight(weightCode(payload_)) : std::numeric_limits<double>::infinity();
}

void MobilityOcTreeNode::setMobility(double m, double w, int count) {
  const auto c = static_cast<std::uint32_t>(std::clamp(count, 1, 255));
  payload_ = pack(encodeMobility(m), encodeWeight(w), c);
}

void MobilityOcTreeNode::fuse(double m, double variance, double max_weight) {
  const double w = 1.0 / std::max(variance, 1e-12);
  if (!hasMobility()) {
    setMobility(m, std::min(w, max_weight), 1);
    return;
  }
  const double old_w = weight();
  const double fused = std::clamp((old_w * mobility() + w * m) / (old_w + w), 0.0, 1.0);
  const double scaled = fused * kMobilityMax;
  const auto code = static_cast<std::uint32_t>(std::min<double>(kMobilityMax, std::floor(scaled + dither(payload_, m))));
  payload_ = pack(code, encodeWeight(std::min(old_w + w, max_weight)),
                  static_cast<std::uint32_t>(std::min(count() + 1, 255)));
}

void MobilityOcTreeNode::updateMobilityChildren(int leaf_child_voxels) {
  if (!children) return;
  std::uint32_t best = 0;  // payload of the child with the lowest known mobility
  int count = 0;
  bool any = false;
  for (unsigned int i = 0; i < 8; ++i) {
    if (!children[i]) continue;
    const auto* child = static_cast<const MobilityOcTreeNode*>(children[i]);
    if (!child->hasMobility()) continue;
    count += child->count() * (child->children ? 1 : leaf_child_voxels);
    count = std::min(count, 255);
    if (!any || mobilityCode(child->payload_) < mobilityCode(best)) best = child->payload_;
    any = true;
  }
  payload_ = any ? pack(mobilityCode(best), weightCode(best), static_cast<std::uint32_t>(std::min(count, 255))) : 0;
}

std::istream& MobilityOcTreeNode::readData(std::istream& s) {
  s.read(reinterpret_cast<char*>(&value), sizeof(value));  // occupancy first, as OcTreeNode
  s.read(reinterpret_cast<char*>(&payload_), sizeof(payload_));
  return s;
}

std::ostream& MobilityOcTreeNode::writeData(std::ostream& s) const {
  s.write(reinterpret_cast<const char*>(&value), sizeof(value));
  s.write(reinterpret_cast<const char*>(&payload_), sizeof(payload_));
  return s;
}

MobilityOcTree::StaticMemberInitializer MobilityOcTree::mobility_octree_member_init_;

MobilityOcTree::StaticMemberInitializer::StaticMemberInitializer() {
  auto* tree = new MobilityOcTree(0.1);  // the factory prototype; owned by OctoMap's registry
  tree->clearKeyRays();
  octomap::AbstractOcTree::registerTreeType(tree);
}

MobilityOcTree::MobilityOcTree(double resolution_m) : OccupancyOcTreeBase<MobilityOcTreeNode>(resolution_m) {
  mobility_octree_member_init_.ensureLinking();
}

bool MobilityOcTree::isNodeCollapsible(const MobilityOcTreeNode* node) const {
  if (!nodeChildExists(node, 0)) return false;
  const MobilityOcTreeNode* first = getNodeChild(node, 0);
  if (nodeHasChildren(first)) return false;
  for (unsigned int i = 1; i < 8; ++i) {
    if (!nodeChildExists(node, i)) return false;
    const MobilityOcTreeNode* child = getNodeChild(node, i);
    if (nodeHasChildren(child) || !(*child == *first)) return false;
  }
  return true;
}

void MobilityOcTree::updateInnerOccupancy() {
  if (root) updateInnerOccupancyRecurs(root, 0);
}

void MobilityOcTree::updateInnerOccupancyRecurs(MobilityOcTreeNode* node, unsigned int depth) {
  if (!nodeHasChildren(node)) return;
  if (depth < tree_depth) {
    for (unsigned int i = 0; i < 8; ++i) {
      if (nodeChildExists(node, i)) updateInnerOccupancyRecurs(getNodeChild(node, i), depth + 1);
    }
  }
  node->updateOccupancyChildren();
  // Voxels of the finest level under one child: 8^(levels below the child), capped where
  // any count saturates the 8-bit sum anyway.
  const unsigned int levels_below_child = tree_depth - depth - 1;
  node->updateMobilityChildren(levels_below_child >= 3 ? 256 : 1 << (3 * levels_below_child));
}

std::unique_ptr<MobilityOcTree> MobilityOcTree::clone() const {
  auto copy = std::make_unique<MobilityOcTree>(resolution);
  copy->setProbHit(getProbHit());
  copy->setProbMiss(getProbMiss());
  copy->setClampingThresMin(getClampingThresMin());
  copy->setClampingThresMax(getClampingThresMax());
  copy->setOccupancyThres(getOccupancyThres());
  std::stringstream bytes;
  writeData(bytes);
  const std::string error = copy->readDataChecked(bytes, size());
  if (!error.empty()) throw std::logic_error("MobilityOcTree::clone: " + error);
  return copy;
}

std::string MobilityOcTree::readDataChecked(std::istream& s, std::size_t max_nodes) {
  if (root) return "tree is not empty";
  if (max_nodes == 0) return {};
  root = new MobilityOcTreeNode();
  tree_size = 1;  // createNodeChild() counts the rest
  std::size_t read = 0;
  if (!readNodesChecked(root, s, max_nodes, read, 0)) {
    clear();
    return read >= max_nodes ? "more nodes than the header declares (corrupt file)"
                             : "file ends before the tree does (truncated?)";
  }
  size_changed = true;
  return {};
}

bool MobilityOcTree::readNodesChecked(MobilityOcTreeNode* node, std::istream& s, std::size_t max_nodes,
                                      std::size_t& read, unsigned int depth) {
  if (++read > max_nodes) return false;
  node->readData(s);
  char children_char = 0;
  s.read(&children_char, 1);
  if (!s) return false;
  const auto children = static_cast<unsigned char>(children_char);
  if (children != 0 && depth >= tree_depth) return false;  // leaves at the finest level have no children
  for (unsigned int i = 0; i < 8; ++i) {
    if ((children >> i) & 1u) {
      MobilityOcTreeNode* child = createNodeChild(node, i);
      if (!readNodesChecked(child, s, max_nodes, read, depth + 1)) return false;
    }
  }
  return true;
}

}  // namespace mobmap::mapping
