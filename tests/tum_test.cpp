// TUM RGB-D sequences: timestamp association with MRPT pose interpolation, the
// 5000-per-metre depth scale, skipped frames, and building a map from one.
#include "dataset.hpp"
#include "io_error.hpp"
#include "png_io.hpp"
#include "sequence.hpp"

#include "mobmap/mapping/trajectory.hpp"
#include "mobmap/sim/corridor_scene.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

namespace mobmap {
namespace {

namespace fs = std::filesystem;
constexpr double kT0 = 1305031102.0;  // TUM timestamps are Unix seconds

// Writes frames 0..n-1 of the noise-free corridor as a TUM directory: depth at 30 Hz,
// ground truth at 100 Hz shifted by 3 ms, with a 40 ms hole around `gap_frame` (with a
// 20 ms tolerance that frame has no pose; its neighbours, 33 ms away, keep theirs).
std::string writeTum(const sim::CorridorScene& scene, int n, int gap_frame) {
  const fs::path dir = fs::temp_directory_path() / ("mobmap-tum-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "depth");
  std::ofstream depth_txt(dir / "depth.txt");
  depth_txt << "# depth maps\n# timestamp filename\n";
  for (int f = 0; f < n; ++f) {
    const auto r = scene.render(f);
    app::Image16 img{r.exact_depth.width, r.exact_depth.height, {}};
    for (float z : r.exact_depth.depth_m) img.pixels.push_back(static_cast<std::uint16_t>(z > 0 && z < 13 ? std::lround(z * 5000) : 0));
    char name[64];
    std::snprintf(name, sizeof(name), "depth/%.6f.png", kT0 + f / 30.0);
    app::writePng16((dir / name).string(), img);
    depth_txt << std::fixed << kT0 + f / 30.0 << " " << name << "\n";
  }
  std::ofstream gt(dir / "groundtruth.txt");
  gt << "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n";
  const double gap_t = gap_frame / 30.0;
  for (double t = -0.05; t < n / 30.0 + 0.05; t += 0.01) {
    if (std::abs(t + 0.003 - gap_t) < 0.02) continue;
    const Eigen::Isometry3d T = scene.cameraPoseAt(t + 0.003);
    const Eigen::Quaterniond q(T.linear());
    gt.precision(9);
    gt << std::fixed << kT0 + t + 0.003 << " " << T.translation().x() << " " << T.translation().y() << " " << T.translation().z() << " "
       << q.x() << " " << q.y() << " " << q.z() << " " << q.w() << "\n";
  }
  return dir.string();
}

TEST(Trajectory, InterpolatesLinearlyAndSlerpsAndRefusesGaps) {
  mapping::Trajectory tr;
  Eigen::Isometry3d a = Eigen::Isometry3d::Identity(), b = Eigen::Isometry3d::Identity();
  b.translation() = Eigen::Vector3d(1, 2, 3);
  b.linear() = Eigen::AngleAxisd(0.6, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  tr.insert(10.0, a);
  tr.insert(10.1, b);
  const auto mid = tr.at(10.05, 0.2);
  ASSERT_TRUE(mid);
  // MRPT's clock counts 100 ns ticks, so times are good to ~1e-6 s: at 37 m/s and
  // 6 rad/s between these samples that is ~4e-5 m and ~6e-6 rad.
  EXPECT_LT((mid->translation() - Eigen::Vector3d(0.5, 1, 1.5)).norm(), 1e-4);
  EXPECT_NEAR(Eigen::AngleAxisd(mid->linear()).angle(), 0.3, 2e-5);
  EXPECT_FALSE(tr.at(9.99, 0.2));         // before the first sample
  EXPECT_FALSE(tr.at(10.11, 0.2));        // after the last
  EXPECT_FALSE(tr.at(10.05, 0.04));       // neighbours 50 ms away, only 40 ms allowed
  EXPECT_TRUE(tr.at(10.1, 0.0));          // an exact sample
  EXPECT_THROW(tr.insert(std::nan(""), a), std::invalid_argument);
}

TEST(TumSequence, AssociatesDepthWithInterpolatedPosesAndSkipsFramesInAGap) {
  sim::CorridorParams p;
  p.frames = 10;
  p.noise = sim::NoiseModel::kNone;
  const sim::CorridorScene scene(p);
  const std::string dir = writeTum(scene, 10, 5);
  const auto seq = app::openSequence(dir, "585,585,320,240", 0.02);
  EXPECT_NE(seq->describe().find("TUM"), std::string::npos);
  ASSERT_EQ(seq->frames().size(), 9u);  // frame 5 has no pose within 20 ms
  EXPECT_NE(seq->skipped().find("1 of 10 depth frames"), std::string::npos) << seq->skipped();
  for (int n : seq->frames()) {
    const auto f = seq->load(n);
    const int frame = n < 5 ? n : n + 1;  // sequence indices skip the gap frame
    const Eigen::Isometry3d truth = scene.cameraPose(frame);
    // Linear + slerp over 10 ms of a smooth walk: sub-millimetre.
    EXPECT_LT((f.T_world_camera.translation() - truth.translation()).norm(), 1e-3) << frame;
    EXPECT_LT(Eigen::AngleAxisd(f.T_world_camera.linear().transpose() * truth.linear()).angle(), 1e-3) << frame;
    const auto r = scene.render(frame);
    for (std::size_t i = 0; i < r.exact_depth.depth_m.size(); i += 97) {
      if (r.exact_depth.depth_m[i] > 0) ASSERT_NEAR(f.depth.depth_m[i], r.exact_depth.depth_m[i], 1.0 / 10000 + 1e-6);
    }
  }
  fs::remove_all(dir);
}

TEST(TumSequence, BadGroundTruthNamesTheFileAndPose) {
  const fs::path dir = fs::temp_directory_path() / ("mobmap-tum-bad-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "depth.txt") << "1.0 depth/1.png\n";
  std::ofstream(dir / "groundtruth.txt") << "1.0 0 0 0 0 0 0 1\n1.1 0 0 0 0.5 0 0 0.5\n";
  try {
    (void)app::openSequence(dir.string(), "", 0.05);
    FAIL();
  } catch (const app::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("groundtruth.txt: pose 2: quaternion norm"), std::string::npos) << e.what();
  }
  std::ofstream(dir / "groundtruth.txt") << "1.0 0 0 0 0 0 0\n";
  try {
    (void)app::openSequence(dir.string(), "", 0.05);
    FAIL();
  } catch (const app::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("line 1: expected 8 columns"), std::string::npos) << e.what();
  }
  fs::remove(dir / "groundtruth.txt");
  try {
    (void)app::openSequence(dir.string(), "", 0.05);
    FAIL();
  } catch (const app::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("groundtruth.txt: missing"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mobmap
