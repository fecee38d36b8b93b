// MobilityOcTree and its node: quantisation, fusion, pruning, against double-precision and
// stock-OctoMap references.
#include "mapping_support.hpp"

namespace mobmap::mapping {
namespace {

TEST(MobilityOcTreeNode, IsNoLargerThanAnOcTreeNode) {
  static_assert(sizeof(MobilityOcTreeNode) <= sizeof(octomap::OcTreeNode), "payload must fit the padding");
  EXPECT_EQ(sizeof(MobilityOcTreeNode), sizeof(octomap::OcTreeNode));
}

TEST(MobilityOcTreeNode, QuantisationErrorIsFarBelowTheBound) {
  double worst = 0;
  for (int i = 0; i <= 100000; ++i) {
    const double m = i / 100000.0;
    worst = std::max(worst, std::abs(MobilityOcTreeNode::decodeMobility(MobilityOcTreeNode::encodeMobility(m)) - m));
  }
  EXPECT_LT(worst, 0.005);            // the requirement
  EXPECT_LE(worst, 0.5 / 16383 + 1e-12);  // what 14 bits give
  for (double w : {1e-3, 0.7, 12.0, 523.0, 19999.0}) {
    const double back = MobilityOcTreeNode::decodeWeight(MobilityOcTreeNode::encodeWeight(w));
    EXPECT_NEAR(back / w, 1.0, 0.011) << w;  // half a 2^(1/32) step
  }
}

TEST(MobilityOcTreeNode, UnknownIsDistinctFromUntraversable) {
  MobilityOcTreeNode n;
  EXPECT_FALSE(n.hasMobility());
  EXPECT_TRUE(std::isinf(n.variance()));
  n.fuse(0.0, 0.01, 1e9);
  EXPECT_TRUE(n.hasMobility());
  EXPECT_EQ(n.mobility(), 0.0);
  EXPECT_EQ(n.count(), 1);
}

TEST(MobilityOcTreeNode, InverseVarianceFusionWeighsConfidentObservationsMore) {
  MobilityOcTreeNode n;
  n.fuse(0.2, 0.01, 1e9);  // confident
  n.fuse(0.8, 0.04, 1e9);  // noisy
  // The stored weight of the first observation is within 1.1 % of 100 (log2 steps of
  // 1/32), which moves the fused value by at most ~0.001.
  EXPECT_NEAR(n.mobility(), (0.2 * 100 + 0.8 * 25) / 125.0, 0.0015);
  EXPECT_NEAR(n.variance(), 1.0 / 125.0, 0.025 / 125.0);
  EXPECT_EQ(n.count(), 2);
}

TEST(MobilityOcTreeNode, LongFusionTracksADoublePrecisionReference) {
  // The same capped inverse-variance recursion in double precision is the oracle; the
  // node's 16-bit, stochastically rounded storage must stay within 0.005 of it.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> m(0, 1), logvar(-6, -1);
  const double cap = 20000;
  for (int trial = 0; trial < 50; ++trial) {
    MobilityOcTreeNode n;
    double ref = 0, w_ref = 0;
    const double base = m(rng);
    for (int i = 0; i < 2000; ++i) {
      const double x = std::clamp(base + 0.2 * (m(rng) - 0.5), 0.0, 1.0);
      const double var = std::exp(logvar(rng));
      const double w = 1 / var;
      n.fuse(x, var, cap);
      ref = w_ref == 0 ? x : (w_ref * ref + w * x) / (w_ref + w);
      w_ref = std::min(w_ref + w, cap);
      // The node's weight is quantised (9 % steps), so its recursion uses slightly
      // different weights; follow its weight to isolate the mobility storage error.
      w_ref = n.weight();
      ASSERT_NEAR(n.mobility(), ref, 0.005) << "trial " << trial << " step " << i;
    }
  }
}

TEST(MobilityOcTree, PrunesOnlyIdenticalChildrenAndKeepsTheMinimumAbove) {
  MobilityOcTree tree(0.05);
  octomap::OcTreeKey base = tree.coordToKey(octomap::point3d(0.01f, 0.01f, 0.01f), 15);  // a depth-15 cell
  auto child_key = [&](int i) {
    return octomap::OcTreeKey(static_cast<octomap::key_type>(base[0] + (i & 1)), static_cast<octomap::key_type>(base[1] + ((i >> 1) & 1)),
                              static_cast<octomap::key_type>(base[2] + ((i >> 2) & 1)));
  };
  base = tree.coordToKey(tree.keyToCoord(base, 15) - octomap::point3d(0.025f, 0.025f, 0.025f));
  for (int i = 0; i < 8; ++i) {
    auto* n = tree.updateNode(child_key(i), true);
    n->setMobility(0.8, 100, 3);
  }
  tree.updateInnerOccupancy();
  tree.prune();
  EXPECT_EQ(tree.getNumLeafNodes(), 1u);  // identical: merged
  // Now one child differs by a single quantisation step: never merged.
  tree.clear();
  for (int i = 0; i < 8; ++i) {
    auto* n = tree.updateNode(child_key(i), true);
    n->setMobility(i == 5 ? 0.8 + 1.0 / 16383 : 0.8, 100, 3);
  }
  tree.updateInnerOccupancy();
  tree.prune();
  EXPECT_EQ(tree.getNumLeafNodes(), 8u);
  // The inner node above holds the minimum known mobility of its children.
  tree.updateNode(child_key(2), true)->setMobility(0.1, 5, 1);
  tree.updateInnerOccupancy();
  const MobilityOcTreeNode* parent = tree.search(child_key(0), 15);
  ASSERT_NE(parent, nullptr);
  EXPECT_NEAR(parent->mobility(), 0.1, 1e-4);
}

// updateLeaf (one descent) against OctoMap's updateNode (search, then descend) on the
// same random updates: hits and misses over a few voxels so that leaves reach the
// clamping bounds (the search's early return), with pruning now and then (pruned
// leaves above the finest level, expanded by the next update). The trees must stay
// equal to the byte, each update must return the node updateNode returns, and
// was_occupied must be the voxel's state before the update (its leaf's, or that of the
// pruned leaf holding it).
void checkUpdateLeafAgainstUpdateNode(bool with_path) {
  MobilityOcTree ours(0.02), stock(0.02);
  MobilityOcTree::UpdatePath path;
  for (MobilityOcTree* t : {&ours, &stock}) {
    t->setProbHit(0.7);
    t->setProbMiss(0.4);
    t->setClampingThresMin(0.12);
    t->setClampingThresMax(0.9);
  }
  const octomap::OcTreeKey base = ours.coordToKey(octomap::point3d(0.3f, -0.2f, 0.1f));
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> offset(0, 3);
  std::bernoulli_distribution hit(0.7);
  const auto bytes = [](const MobilityOcTree& t) {
    std::ostringstream out;
    t.write(out);
    return out.str();
  };
  int early_returns = 0, expanded = 0;
  for (int step = 0; step < 20000; ++step) {
    // Every seventh key lies in a block far away, so paths part at the top levels too.
    const int far = step % 7 == 3 ? 1000 : 0;
    const octomap::OcTreeKey key(static_cast<octomap::key_type>(base[0] + far + offset(rng)),
                                 static_cast<octomap::key_type>(base[1] + offset(rng)),
                                 static_cast<octomap::key_type>(base[2] + offset(rng)));
    // Later phases lean towards misses, so blocks saturate at both bounds.
    const bool occupied = step < 10000 ? hit(rng) : !hit(rng);
    // Where the key's path ends before the update: at the voxel (depth 16), at a
    // pruned leaf above it, or nowhere (a node with other children: before = null).
    const MobilityOcTreeNode* before = ours.getRoot();
    unsigned int depth_before = 0;
    while (before && depth_before < 16) {
      const unsigned int pos = octomap::computeChildIdx(key, static_cast<int>(15 - depth_before));
      if (!ours.nodeChildExists(before, pos)) {
        if (ours.nodeHasChildren(before)) before = nullptr;
        break;
      }
      before = ours.getNodeChild(before, pos);
      ++depth_before;
    }
    const bool expected_was = before && ours.isNodeOccupied(before);
    bool was_occupied = !expected_was;
    MobilityOcTreeNode* a = ours.updateLeaf(key, occupied, &was_occupied, with_path ? &path : nullptr);
    MobilityOcTreeNode* b = stock.updateNode(key, occupied, true);
    ASSERT_NE(a, nullptr);
    ASSERT_NE(b, nullptr);
    EXPECT_EQ(a->getLogOdds(), b->getLogOdds()) << "step " << step;
    EXPECT_EQ(ours.nodeHasChildren(a), stock.nodeHasChildren(b)) << "step " << step;
    EXPECT_EQ(was_occupied, expected_was) << "step " << step;
    if (before && a == before && depth_before < 16) ++early_returns;
    if (before && depth_before < 16 && a != before) ++expanded;
    if (step % 500 == 499) {
      for (MobilityOcTree* t : {&ours, &stock}) {
        t->updateInnerOccupancy();
        t->prune();
      }
      path = MobilityOcTree::UpdatePath();  // pruning deletes nodes a path may hold
      ASSERT_EQ(bytes(ours), bytes(stock)) << "after step " << step;
    }
  }
  EXPECT_EQ(bytes(ours), bytes(stock));
  // Both special paths ran: a pruned leaf at a bound returned as it was, and pruned
  // leaves expanded down to the voxel.
  EXPECT_GT(early_returns, 0);
  EXPECT_GT(expanded, 0);
}

TEST(MobilityOcTree, UpdateLeafEqualsOctomapsUpdateNode) { checkUpdateLeafAgainstUpdateNode(false); }
TEST(MobilityOcTree, UpdateLeafFromThePreviousPathEqualsOctomapsUpdateNode) { checkUpdateLeafAgainstUpdateNode(true); }

}  // namespace
}  // namespace mobmap::mapping
