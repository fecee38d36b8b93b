// The 7-Scenes layout as the simulator writes it and as real data has it, and evaluation
// against ground truth.
#include "io_support.hpp"

namespace mobmap::app {
namespace {

// Writes a short noise-free corridor and reads it back through the dataset reader.
class WrittenCorridor : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir();
    sim::CorridorParams p;
    p.frames = 40;
    p.noise = sim::NoiseModel::kNone;
    scene_ = new sim::CorridorScene(p);
    // Only a few frames are needed: write the whole sequence's metadata, then the frames.
    writeSimulation(*scene_, dir_->str(), 2, [](int) {});
  }
  static void TearDownTestSuite() {
    delete scene_;
    delete dir_;
  }
  static inline TempDir* dir_ = nullptr;
  static inline sim::CorridorScene* scene_ = nullptr;
};

TEST_F(WrittenCorridor, SevenScenesReaderRoundTrip) {
  const SevenScenesDirectory d(dir_->str());
  ASSERT_EQ(d.frameNumbers().size(), 40u);
  EXPECT_EQ(d.intrinsics(), scene_->params().intrinsics);
  ASSERT_TRUE(d.gravityDown().has_value());
  EXPECT_NEAR((*d.gravityDown() - scene_->gravityDown()).norm(), 0.0, 1e-15);
  for (int f : {0, 17, 39}) {
    const auto r = scene_->render(f);
    const auto depth = d.readDepth(f);
    for (std::size_t i = 0; i < depth.depth_m.size(); ++i) {
      if (r.exact_depth.depth_m[i] > 0 && r.exact_depth.depth_m[i] < 65.0f) {
        ASSERT_NEAR(depth.depth_m[i], r.exact_depth.depth_m[i], 0.5e-3 + 1e-6);  // millimetre rounding
      } else {
        ASSERT_EQ(depth.depth_m[i], 0.f);
      }
    }
    EXPECT_LT((d.readPose(f) - r.T_world_camera.matrix()).cwiseAbs().maxCoeff(), 1e-15);
    EXPECT_EQ(readPng16(d.labelsPath(f)).pixels, r.labels);
  }
}

TEST_F(WrittenCorridor, BackProjectedRampsRecoverTheirSlopeWithinATenthOfADegree) {
  const SevenScenesDirectory d(dir_->str());
  const Eigen::Vector3d up = -*d.gravityDown();
  std::map<int, std::vector<Eigen::Vector3d>> points;  // ramp id -> world points
  for (int f : {0, 20, 39}) {
    const auto depth = d.readDepth(f);
    const Eigen::Matrix4d pose = d.readPose(f);
    const Eigen::Affine3d T(pose);
    const auto labels = readPng16(d.labelsPath(f)).pixels;
    const auto& k = d.intrinsics();
    for (int v = 0; v < k.height; ++v) {
      for (int u = 0; u < k.width; ++u) {
        const auto i = static_cast<std::size_t>(v * k.width + u);
        const int id = labels[i];
        if (id == 0 || depth.depth_m[i] <= 0 || scene_->surface(id).kind != sim::SurfaceKind::kRamp) continue;
        points[id].push_back(T * perception::backProject(k, u, v, depth.depth_m[i]));
      }
    }
  }
  ASSERT_GE(points.size(), 4u);
  for (const auto& [id, pts] : points) {
    if (pts.size() < 2000) continue;  // only well-observed ramps
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : pts) mean += p;
    mean /= static_cast<double>(pts.size());
    Eigen::MatrixXd a(pts.size(), 3);
    for (std::size_t i = 0; i < pts.size(); ++i) a.row(static_cast<Eigen::Index>(i)) = (pts[i] - mean).transpose();
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeThinV);
    const Eigen::Vector3d n = svd.matrixV().col(2);
    const double slope = std::acos(std::min(1.0, std::abs(n.dot(up)))) / kDeg;
    EXPECT_NEAR(slope, scene_->surface(id).slope_deg, 0.1) << scene_->surface(id).name << " from " << pts.size() << " points";
  }
}

TEST_F(WrittenCorridor, GroundTruthJsonListsEverySurface) {
  const auto j = nlohmann::json::parse(readTextFile(dir_->file("ground_truth.json")));
  ASSERT_EQ(j["surfaces"].size(), scene_->surfaces().size());
  for (const auto& s : j["surfaces"]) {
    const auto& truth = scene_->surface(s["id"].get<int>());
    EXPECT_EQ(s["name"], truth.name);
    EXPECT_DOUBLE_EQ(s["slope_deg"].get<double>(), truth.slope_deg);
    EXPECT_DOUBLE_EQ(s["roughness"].get<double>(), truth.roughness);
    EXPECT_DOUBLE_EQ(s["expected_mobility"].get<double>(), truth.expected_mobility);
  }
  EXPECT_EQ(j["moving_obstacle"]["start_frame"].get<int>(), scene_->movingObstacle().start_frame);
  // pixels_seen: the label images' pixel counts, summed over every frame written.
  std::map<int, long long> counted;
  const SevenScenesDirectory d(dir_->str());
  for (int f : d.frameNumbers()) {
    for (const std::uint16_t id : readPng16(d.labelsPath(f)).pixels) {
      if (id != 0) ++counted[id];
    }
  }
  int never = 0;
  for (const auto& s : j["surfaces"]) {
    const int id = s["id"].get<int>();
    EXPECT_EQ(s["pixels_seen"].get<long long>(), counted.count(id) ? counted[id] : 0) << s["name"];
    never += counted.count(id) == 0;
  }
  EXPECT_GT(never, 0);  // the ramps' backs face away from the walk
  EXPECT_GT(counted[1], 1000000);  // the floor
}

// evaluateMap on a hand-made map: a floor (answer 1) meets a wall (answer 0) at x = 1.005;
// a back face at y = 1 that no frame showed stands on the floor.
TEST(Evaluate, EdgeVoxelsAreScoredApartAndFacesNeverInViewTakeNoVoxels) {
  const std::string truth_json = R"({"format": "mobmap-ground-truth", "gravity_down_world": [0, 0, -1], "surfaces": [
    {"id": 1, "name": "floor", "kind": "floor", "slope_deg": 0, "roughness": 1, "expected_mobility": 1, "pixels_seen": 100,
     "geometry": {"type": "polygons", "polygons": [[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]]}},
    {"id": 2, "name": "wall", "kind": "wall", "slope_deg": 90, "roughness": 1, "expected_mobility": 0, "pixels_seen": 100,
     "geometry": {"type": "polygons", "polygons": [[[1.005, 0, 0], [1.005, 1, 0], [1.005, 1, 1], [1.005, 0, 1]]]}},
    {"id": 3, "name": "back", "kind": "ramp_side", "slope_deg": 90, "roughness": 1, "expected_mobility": 0, "pixels_seen": 0,
     "geometry": {"type": "polygons", "polygons": [[[0, 1, 0], [1, 1, 0], [1, 1, 0.2], [0, 1, 0.2]]]}}]})";
  TempDir dir;
  const std::string with_views = dir.file("truth.json");
  const std::string without_views = dir.file("truth-old.json");
  writeTextFileAtomically(with_views, truth_json);
  std::string old = truth_json;
  for (std::size_t at; (at = old.find(", \"pixels_seen\": ")) != std::string::npos;) old.erase(at, old.find(',', at + 1) - at);
  writeTextFileAtomically(without_views, old);

  auto tree = std::make_unique<mapping::MobilityOcTree>(0.02);
  const auto surface = [&](double x, double y, double z, double mobility) {
    const octomap::OcTreeKey key = tree->coordToKey(x, y, z);
    for (int i = 0; i < 3; ++i) tree->updateNode(key, true)->fuse(mobility, 0.01, 1e4);
  };
  surface(0.51, 0.51, 0.01, 1.0);  // floor
  surface(0.31, 0.51, 0.01, 0.8);  // floor, off by 0.2
  surface(1.01, 0.51, 0.51, 0.0);  // wall
  surface(0.99, 0.51, 0.01, 0.0);  // the corner: 1 cm from the floor, 1.5 cm from the wall
  surface(0.51, 0.99, 0.03, 1.0);  // floor noise 1 cm from the back face, 3 cm above the floor
  const mapping::MobilityMap map(std::move(tree), mapping::MapParams{}, Eigen::Matrix3d::Identity());

  // The evaluation points into the ground truth: both must outlive the checks.
  const GroundTruth truth = loadGroundTruth(with_views);
  const Evaluation ev = evaluateMap(map, truth, 3, 0.04);
  ASSERT_EQ(ev.surfaces.size(), 3u);
  EXPECT_FALSE(ev.surfaces[2].surface->seen);
  EXPECT_EQ(ev.surfaces[0].voxels, 3);  // with the voxel beside the back face
  EXPECT_NEAR(ev.surfaces[0].mean_abs_error, 0.2 / 3, 0.005);
  EXPECT_EQ(ev.surfaces[1].voxels, 1);
  EXPECT_NEAR(ev.surfaces[1].mean_abs_error, 0.0, 0.005);
  EXPECT_EQ(ev.surfaces[2].voxels, 0);
  EXPECT_EQ(ev.edge_voxels, 1);
  EXPECT_NEAR(ev.edge_mean_abs_error, 1.0, 0.005);      // the nearest surface (the floor) says 1
  EXPECT_NEAR(ev.edge_mean_abs_error_any, 0.0, 0.005);  // the wall it also touches says 0
  // All five count in the confusion; only the corner is on the wrong side.
  EXPECT_EQ(ev.true_traversable + ev.true_untraversable, 4);
  EXPECT_EQ(ev.false_untraversable, 1);

  // Without pixels_seen every surface counts as seen: the back face takes its voxel.
  const GroundTruth truth_all = loadGroundTruth(without_views);
  const Evaluation all = evaluateMap(map, truth_all, 3, 0.04);
  EXPECT_TRUE(all.surfaces[2].surface->seen);
  EXPECT_EQ(all.surfaces[2].voxels, 1);
  EXPECT_NEAR(all.surfaces[2].mean_abs_error, 1.0, 0.005);
  EXPECT_EQ(all.surfaces[0].voxels, 2);
}

TEST(SevenScenesDirectory, MismatchedInputsNameTheFile) {
  TempDir dir;
  EXPECT_NE(errorOf([&] { SevenScenesDirectory{dir.str()}; }).find("no frame-NNNNNN.depth.png"), std::string::npos);
  writePng16(dir.file("frame-000000.depth.png"), Image16{8, 6, std::vector<std::uint16_t>(48, 1000)});
  const std::string no_k = errorOf([&] { SevenScenesDirectory{dir.str()}; });
  EXPECT_NE(no_k.find("no camera-intrinsics.txt here or in the parent directory: give `intrinsics`"), std::string::npos)
      << no_k;
  // Microsoft's 7-Scenes download has no camera-intrinsics.txt: --intrinsics stands in.
  {
    const SevenScenesDirectory given(dir.str(), "5,6,3.5,2.5");
    EXPECT_EQ(given.intrinsics().width, 8);
    EXPECT_EQ(given.intrinsics().height, 6);
    EXPECT_EQ(given.intrinsics().fy, 6.0);
    EXPECT_EQ(given.intrinsics().cx, 3.5);
  }
  writeIntrinsicsFile(dir.file("camera-intrinsics.txt"), {8, 6, 5, 5, 4, 3});
  // ... and wins over the file.
  EXPECT_EQ(SevenScenesDirectory(dir.str(), "7,7,4,3").intrinsics().fx, 7.0);
  writePng16(dir.file("frame-000001.depth.png"), Image16{9, 6, std::vector<std::uint16_t>(54, 1000)});
  const SevenScenesDirectory d(dir.str());
  EXPECT_NO_THROW((void)d.readDepth(0));
  EXPECT_NE(errorOf([&] { (void)d.readDepth(1); }).find("frame-000001.depth.png: depth image is 9x6"), std::string::npos);
  EXPECT_NE(errorOf([&] { (void)d.readPose(0); }).find("frame-000000.pose.txt: no such file"), std::string::npos);
  // A scene folder of the 7-Scenes / 3DMatch downloads: its sequences are sub-folders.
  TempDir scene;
  std::filesystem::create_directories(scene.file("seq-02"));
  std::filesystem::create_directories(scene.file("seq-01"));
  std::filesystem::create_directories(scene.file("empty"));
  for (const char* f : {"seq-02/frame-000000.depth.png", "seq-02/frame-000001.depth.png", "seq-01/frame-000000.depth.png"})
    writePng16(scene.file(f), Image16{8, 6, std::vector<std::uint16_t>(48, 1000)});
  const std::string parent = errorOf([&] { SevenScenesDirectory{scene.str()}; });
  EXPECT_NE(parent.find(scene.str() + ": no frame-NNNNNN.depth.png files here, but these sub-folders have them: "
                                      "seq-01 (1 frame), seq-02 (2 frames); pass one sequence folder, such as " +
                        scene.file("seq-01")),
            std::string::npos)
      << parent;
}


TEST(RealData, SevenScenesRedkitchenReadsWithGravityAndRigidPoses) {
  const std::string dir = std::string(MOBMAP_SHARED_DATA_DIR) + "/7scenes-redkitchen";
  if (!fs::exists(dir)) GTEST_SKIP() << "shared data not found at " << dir;
  const SevenScenesDirectory d(dir);
  EXPECT_EQ(d.frameNumbers().size(), 1000u);
  EXPECT_EQ(d.intrinsics(), (perception::PinholeIntrinsics{640, 480, 585, 585, 320, 240}));
  ASSERT_TRUE(d.gravityDown().has_value());
  EXPECT_NEAR(d.gravityDown()->norm(), 1.0, 1e-12);
  const auto depth = d.readDepth(50);
  int valid = 0;
  for (float z : depth.depth_m) valid += (z > 0.3f && z < 10.f);
  EXPECT_GT(valid, 100000);
  (void)d.readPose(50);  // throws if not rigid
}

TEST(RealData, ThreeDMatchLoungeFindsIntrinsicsInTheParentDirectory) {
  const std::string dir = std::string(MOBMAP_SHARED_DATA_DIR) + "/3dmatch-lounge/seq-01";
  if (!fs::exists(dir)) GTEST_SKIP() << "shared data not found at " << dir;
  const SevenScenesDirectory d(dir);
  EXPECT_EQ(d.frameNumbers().size(), 5u);
  EXPECT_NEAR(d.intrinsics().fx, 570.342205, 1e-9);  // the file's value (the data README rounds it)
  EXPECT_FALSE(d.gravityDown().has_value());
}

}  // namespace
}  // namespace mobmap::app
