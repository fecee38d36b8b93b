// Map files: round trips, hostile files, exports stock OctoMap reads, the writer's lock.
#include "mapping_support.hpp"

namespace mobmap::mapping {
namespace {

TEST(MapFiles, OtRoundTripIsExact) {
  const MobilityMap map = builtMap();
  const std::string path = tempPath("round.ot");
  saveMobilityMap(map.tree(), path);
  const auto back = loadMobilityMap(path);
  ASSERT_EQ(back->size(), map.tree().size());
  EXPECT_EQ(back->getResolution(), map.tree().getResolution());
  auto a = map.tree().begin_tree(), b = back->begin_tree();
  for (; a != map.tree().end_tree(); ++a, ++b) {
    ASSERT_NE(b, back->end_tree());
    ASSERT_EQ(a.getKey(), b.getKey());
    ASSERT_EQ(a.getDepth(), b.getDepth());
    ASSERT_EQ(a->getValue(), b->getValue());
    ASSERT_EQ(a->payload(), b->payload());
  }
  EXPECT_EQ(b, back->end_tree());
}

// A run where nothing was in range leaves an empty tree: every format still writes it,
// and what OctoMap reads back is empty too (ColorOcTree used to crash on it).
TEST(MapFiles, AnEmptyMapIsWrittenInEveryFormat) {
  MobilityMap map;
  map.finalize();
  ASSERT_EQ(map.tree().size(), 0u);
  const std::string ot = tempPath("empty.ot"), bt = tempPath("empty.bt"), colour = tempPath("empty.octovis.ot"),
                    pcd = tempPath("empty.pcd");
  saveMobilityMap(map.tree(), ot);
  EXPECT_EQ(loadMobilityMap(ot)->size(), 0u);
  saveOccupancyBt(map.tree(), bt);
  octomap::OcTree occupancy(0.1);
  ASSERT_TRUE(occupancy.readBinary(bt));
  EXPECT_EQ(occupancy.size(), 0u);
  EXPECT_DOUBLE_EQ(occupancy.getResolution(), map.tree().getResolution());
  saveOctovisColorTree(map.tree(), colour);
  std::unique_ptr<octomap::AbstractOcTree> read(octomap::AbstractOcTree::read(colour));
  const auto* colour_tree = dynamic_cast<const octomap::ColorOcTree*>(read.get());
  ASSERT_NE(colour_tree, nullptr);
  EXPECT_EQ(colour_tree->size(), 0u);
  saveSurfacePcd(map.tree(), pcd);
  std::ifstream in(pcd);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("\nPOINTS 0\nDATA ascii\n"), std::string::npos) << text;
  EXPECT_EQ(text.substr(text.size() - 11), "DATA ascii\n");
}

std::string loadError(const std::string& path) {
  try {
    (void)loadMobilityMap(path);
  } catch (const MapIoError& e) {
    return e.what();
  }
  return "no error";
}

TEST(MapFiles, HostileFilesGiveClearErrors) {
  const MobilityMap map = builtMap();
  const std::string good = tempPath("good.ot");
  saveMobilityMap(map.tree(), good);
  std::string bytes;
  {
    std::ifstream in(good, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  for (double frac : {0.99, 0.7, 0.3}) {
    const std::string cut = tempPath("cut.ot");
    std::ofstream(cut, std::ios::binary) << bytes.substr(0, static_cast<std::size_t>(bytes.size() * frac));
    const std::string e = loadError(cut);
    EXPECT_NE(e.find("cut.ot: "), std::string::npos) << e;
    EXPECT_NE(e.find("truncated"), std::string::npos) << e;
  }
  EXPECT_NE(loadError(tempPath("missing.ot")).find("no such file"), std::string::npos);
  const std::string junk = tempPath("junk.ot");
  std::ofstream(junk) << "hello\n";
  EXPECT_NE(loadError(junk).find("not an OctoMap .ot file"), std::string::npos);
  // A stock OcTree and a .bt are recognised as such.
  octomap::OcTree plain(0.1);
  plain.updateNode(octomap::point3d(0, 0, 0), true);
  const std::string other = tempPath("plain.ot");
  plain.write(other);
  EXPECT_NE(loadError(other).find("holds an OctoMap 'OcTree'"), std::string::npos) << loadError(other);
  const std::string bt = tempPath("occ.bt");
  saveOccupancyBt(map.tree(), bt);
  EXPECT_NE(loadError(bt).find(".bt"), std::string::npos);
  // A map from a future layout.
  std::string future = bytes;
  future.replace(future.find("MobilityOcTree_v1"), 17, "MobilityOcTree_v9");
  const std::string fut = tempPath("future.ot");
  std::ofstream(fut, std::ios::binary) << future;
  EXPECT_NE(loadError(fut).find("another version"), std::string::npos);
  // Bytes after the tree (two files joined, a partial overwrite) are named, not ignored.
  const std::string joined = tempPath("joined.ot");
  std::ofstream(joined, std::ios::binary) << bytes << "junk";
  EXPECT_NE(loadError(joined).find("joined.ot: 4 bytes follow the tree's data"), std::string::npos) << loadError(joined);
}

// A .ot whose tree is one chain from the root down to a single occupied leaf at `depth`:
// 9 bytes per node, a leaf that stands for (2^(16 - depth))^3 voxels.
std::string chainToLeaf(unsigned int depth, const std::string& res = "0.02") {
  std::string data;
  for (unsigned int d = 0; d <= depth; ++d) {
    const float log_odds = 2.0f;
    const std::uint32_t payload = 0;
    data.append(reinterpret_cast<const char*>(&log_odds), 4);
    data.append(reinterpret_cast<const char*>(&payload), 4);
    data.push_back(d < depth ? '\x01' : '\x00');
  }
  return "# Octomap OcTree file\nid MobilityOcTree_v1\nsize " + std::to_string(depth + 1) + "\nres " + res + "\ndata\n" + data;
}


TEST(MapFiles, ALeafStandingForMoreVoxelsThanTheFileCanHoldIsRefusedNotExpanded) {
  // The 73-byte root leaf (2^48 voxels) and a depth-9 leaf (2^21 voxels, ~140 MB of index)
  // used to be expanded voxel by voxel until memory ran out.
  for (unsigned int depth : {0u, 5u, 9u}) {
    const std::string path = tempPath("leaf" + std::to_string(depth) + ".ot");
    std::ofstream(path, std::ios::binary) << chainToLeaf(depth);
    if (depth == 0) {
      EXPECT_EQ(std::filesystem::file_size(path), 73u);
    }
    const std::string e = loadError(path);
    EXPECT_EQ(e.rfind(path + ": ", 0), 0u) << e;
    EXPECT_NE(e.find("stand for more than 1048576 occupied voxels"), std::string::npos) << e;
    EXPECT_NE(e.find("at depth " + std::to_string(depth)), std::string::npos) << e;
    // The library refuses the same tree handed to it directly.
    MobilityOcTree tree(0.02);
    std::istringstream in(chainToLeaf(depth).substr(chainToLeaf(depth).find("data\n") + 5));
    ASSERT_EQ(tree.readDataChecked(in, depth + 1), "");
    EXPECT_THROW(MobilityMap(std::make_unique<MobilityOcTree>(std::move(tree)), MapParams{}, Eigen::Matrix3d::Identity()),
                 std::invalid_argument);
  }
  // A depth-10 leaf (64^3 = 262144 voxels) is within the budget: the map opens, and every
  // voxel of the block answers as surface, none outside it.
  const std::string ok = tempPath("leaf10.ot");
  std::ofstream(ok, std::ios::binary) << chainToLeaf(10);
  auto tree = loadMobilityMap(ok);
  EXPECT_EQ(countOccupiedVoxels(*tree, ~std::uint64_t{0}), std::optional<std::uint64_t>(262144));
  const MobilityMap map = openMap(ok);
  // The chain takes child 0 at every level: the block's lowest corner is key 0.
  const octomap::point3d corner = map.tree().keyToCoord(octomap::OcTreeKey(0, 0, 0));
  const Eigen::Vector3d c(corner.x(), corner.y(), corner.z());
  EXPECT_EQ(map.query(c).state, VoxelState::kSurface);
  EXPECT_EQ(map.query(c + Eigen::Vector3d::Constant(63 * 0.02)).state, VoxelState::kSurface);
  EXPECT_EQ(map.query(c + Eigen::Vector3d::Constant(64 * 0.02)).state, VoxelState::kUnknown);
  EXPECT_EQ(map.query(c - Eigen::Vector3d::Constant(0.02)).state, VoxelState::kUnknown);
}

std::string lockError(const std::string& ot) {
  try {
    const MapLock lock(ot);
  } catch (const MapIoError& e) {
    return e.what();
  }
  return "no error";
}

TEST(MapLock, OneWriterAtATimeAndADeadHolderBlocksNobody) {
  const std::string dir = tempPath("lockdir");
  std::filesystem::create_directories(dir);
  const std::string ot = dir + "/m.ot";
  EXPECT_EQ(mapLockPath(ot), dir + "/m.lock");
  {
    const MapLock held(ot);
    EXPECT_TRUE(std::filesystem::exists(held.path()));
    const std::string e = lockError(ot);
    EXPECT_EQ(e.rfind(ot + ": is being written by another process (pid " + std::to_string(::getpid()) + " holds " +
                          dir + "/m.lock)", 0),
              0u)
        << e;
    EXPECT_EQ(lockError(dir + "/other.ot"), "no error");  // another map is another lock
  }
  EXPECT_FALSE(std::filesystem::exists(dir + "/m.lock"));  // removed on release
  // A lock file left behind by a writer that is gone (its pid inside, nobody holding it).
  std::ofstream(dir + "/m.lock") << "999999\n";
  EXPECT_EQ(lockError(ot), "no error");
  // A writer killed while it holds the lock: the system releases it. The child says
  // when it holds it through a pipe; no timing involved.
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(ready[0]);
    const MapLock held(ot);
    const char c = 'x';
    if (::write(ready[1], &c, 1) != 1) ::_exit(1);
    for (;;) ::pause();
  }
  ::close(ready[1]);
  char c = 0;
  ASSERT_EQ(::read(ready[0], &c, 1), 1);
  ::close(ready[0]);
  EXPECT_NE(lockError(ot).find("(pid " + std::to_string(child) + " holds"), std::string::npos) << lockError(ot);
  ::kill(child, SIGKILL);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  EXPECT_EQ(lockError(ot), "no error");
  std::filesystem::remove_all(dir);
}

TEST(MapFiles, AResolutionThatIsNotAUsableNumberIsNamed) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"nan", "res 'nan' is not a finite number"},     {"inf", "res 'inf' is not a finite number"},
      {"0.02x", "res '0.02x' is not a finite number"}, {"1e-300", "res 1e-300 m is outside"},
      {"20", "res 20 m is outside"},                   {"-0.02", "res -0.02 m is outside"}};
  for (const auto& [res, expected] : cases) {
    const std::string path = tempPath("res.ot");
    std::ofstream(path, std::ios::binary) << chainToLeaf(16, res);
    const std::string e = loadError(path);
    EXPECT_EQ(e.rfind(path + ": ", 0), 0u) << e;
    EXPECT_NE(e.find(expected), std::string::npos) << res << ": " << e;
  }
  const std::string no_res = tempPath("nores.ot");
  std::ofstream(no_res, std::ios::binary) << "# Octomap OcTree file\nid MobilityOcTree_v1\nsize 1\ndata\n";
  EXPECT_NE(loadError(no_res).find("header has no 'res'"), std::string::npos) << loadError(no_res);
  // A one-voxel map at the finest level is fine.
  const std::string fine = tempPath("fine.ot");
  std::ofstream(fine, std::ios::binary) << chainToLeaf(16);
  EXPECT_EQ(loadError(fine), "no error");
}

TEST(MapFiles, BtAndOctovisExportLoadInStockOctomapWithTheSameOccupiedVoxels) {
  const MobilityMap map = builtMap();
  std::set<octomap::OcTreeKey, bool (*)(const octomap::OcTreeKey&, const octomap::OcTreeKey&)> ours(
      [](const octomap::OcTreeKey& a, const octomap::OcTreeKey& b) {
        return std::tie(a[0], a[1], a[2]) < std::tie(b[0], b[1], b[2]);
      });
  for (auto it = map.tree().begin_leafs(); it != map.tree().end_leafs(); ++it) {
    if (map.tree().isNodeOccupied(*it)) ours.insert(it.getKey());
  }
  ASSERT_GT(ours.size(), 1000u);
  const std::string bt = tempPath("map.bt");
  saveOccupancyBt(map.tree(), bt);
  octomap::OcTree stock(0.1);
  ASSERT_TRUE(stock.readBinary(bt));
  EXPECT_DOUBLE_EQ(stock.getResolution(), map.tree().getResolution());
  std::size_t occupied = 0;
  for (auto it = stock.begin_leafs(); it != stock.end_leafs(); ++it) {
    if (!stock.isNodeOccupied(*it)) continue;
    ++occupied;
    EXPECT_TRUE(ours.count(it.getKey())) << "extra occupied voxel";
  }
  EXPECT_EQ(occupied, ours.size());

  const std::string ov = tempPath("map.octovis.ot");
  saveOctovisColorTree(map.tree(), ov);
  std::unique_ptr<octomap::AbstractOcTree> abstract(octomap::AbstractOcTree::read(ov));
  auto* colour = dynamic_cast<octomap::ColorOcTree*>(abstract.get());
  ASSERT_NE(colour, nullptr);
  std::size_t coloured = 0;
  for (auto it = colour->begin_leafs(); it != colour->end_leafs(); ++it) {
    if (!colour->isNodeOccupied(*it)) continue;
    ++coloured;
    ASSERT_TRUE(ours.count(it.getKey()));
    const auto q = map.query(Eigen::Vector3d(it.getX(), it.getY(), it.getZ()));
    const auto c = it->getColor();
    const VoxelRgb want = mobilityRgb(q.mobility);
    if (q.mobility > 0.99) {
      EXPECT_GT(c.r, 200);  // viridis yellow
      EXPECT_GT(c.g, 200);
    }
    if (q.mobility < 0.01) {
      EXPECT_LT(c.g, 10);  // viridis dark purple
      EXPECT_GT(c.b, 60);
    }
    if (q.has_mobility) EXPECT_EQ((VoxelRgb{c.r, c.g, c.b}), want);
  }
  EXPECT_EQ(coloured, ours.size());
}

// A colour per voxel: a pruned block is written voxel by voxel, each in the colour its
// own key is given, and stock OctoMap reads every one back.
TEST(MapFiles, OctovisExportColoursEachVoxelByItsKeyAlsoInsidePrunedBlocks) {
  MobilityOcTree t(0.02);
  // An 8 x 8 x 8 block aligned to the tree's 8-voxel cells (keys from 32768), one value
  // throughout so it prunes, and one lone voxel with another mobility.
  std::set<std::tuple<int, int, int>> voxels;
  for (int i = 0; i < 8; ++i) {
    for (int j = 0; j < 8; ++j) {
      for (int k = 0; k < 8; ++k) {
        const octomap::OcTreeKey key(static_cast<octomap::key_type>(32768 + i), static_cast<octomap::key_type>(32768 + j),
                                     static_cast<octomap::key_type>(32768 + k));
        auto* n = t.updateNode(key, 2.0f);
        n->setMobility(0.8, 0.01, 2);
        voxels.insert({32768 + i, 32768 + j, 32768 + k});
      }
    }
  }
  auto* lone = t.updateNode(octomap::OcTreeKey(32800, 32800, 32800), 2.0f);
  lone->setMobility(0.1, 0.01, 2);
  voxels.insert({32800, 32800, 32800});
  t.updateInnerOccupancy();
  t.prune();
  std::size_t leaves = 0, widest = 0;
  for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) {
    ++leaves;
    widest = std::max<std::size_t>(widest, std::lround(it.getSize() / 0.02));
  }
  ASSERT_EQ(widest, 8u) << "the block did not prune";
  ASSERT_EQ(leaves, 2u);
  const auto code = [](const octomap::OcTreeKey& k) {
    return VoxelRgb{static_cast<std::uint8_t>(k[0] % 256), static_cast<std::uint8_t>(k[1] % 256),
                    static_cast<std::uint8_t>((k[2] * 7) % 256)};
  };
  const std::string ov = tempPath("keys.octovis.ot");
  saveOctovisColorTree(t, ov, [&](const octomap::OcTreeKey& k, const MobilityOcTreeNode& n) {
    // The node is the leaf holding the voxel: the block's or the lone voxel's.
    EXPECT_NEAR(n.mobility(), k[0] == 32800 ? 0.1 : 0.8, 1e-3);  // stored in 16 bits
    return code(k);
  });
  std::unique_ptr<octomap::AbstractOcTree> abstract(octomap::AbstractOcTree::read(ov));
  auto* colour = dynamic_cast<octomap::ColorOcTree*>(abstract.get());
  ASSERT_NE(colour, nullptr);
  std::set<std::tuple<int, int, int>> read;
  for (auto it = colour->begin_leafs(); it != colour->end_leafs(); ++it) {
    ASSERT_EQ(it.getDepth(), 16u);
    const octomap::OcTreeKey k = it.getKey();
    read.insert({k[0], k[1], k[2]});
    EXPECT_EQ(it->getColor(), octomap::ColorOcTreeNode::Color(code(k)[0], code(k)[1], code(k)[2]));
  }
  EXPECT_EQ(read, voxels);
  // The one-argument export is this with the mobility colours: viridis, 0.1 lies 0.8 of
  // the way from its first stop (68, 1, 84) to its second (72, 40, 120); on the red-green
  // scale, 255 red and 220 x 0.2 green.
  const MobilityOcTreeNode& lone_node = *t.search(octomap::OcTreeKey(32800, 32800, 32800));
  EXPECT_EQ(mobilityRgb(lone_node), (VoxelRgb{71, 32, 113}));
  EXPECT_EQ(mobilityRgb(lone_node, ColourScale::kRedGreen), (VoxelRgb{255, 44, 0}));
  MobilityOcTreeNode unknown;
  EXPECT_EQ(mobilityRgb(unknown), (VoxelRgb{190, 190, 190}));
  EXPECT_EQ(mobilityRgb(unknown, ColourScale::kRedGreen), (VoxelRgb{140, 140, 140}));
  std::remove(ov.c_str());
}

}  // namespace
}  // namespace mobmap::mapping
