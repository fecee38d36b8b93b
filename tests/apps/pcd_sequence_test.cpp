// Sequences of .pcd frames with --poses: cut frames, time stamps in names, maps from them.
#include "tum_support.hpp"

namespace mobmap {
namespace {

// Writes frame `f` of the noise-free corridor as an organized binary PCD (x y z, NaN
// where there is no depth, and the rendered colour packed in rgb), as a Kinect grabber would.
void writeOrganizedPcd(const sim::CorridorScene& scene, int f, const std::string& path, float x_scale = 1.f) {
  const auto r = scene.render(f);
  const auto& k = scene.params().intrinsics;
  std::ofstream out(path, std::ios::binary);
  out << "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH " << k.width
      << "\nHEIGHT " << k.height << "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << k.width * k.height << "\nDATA binary\n";
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const float z = r.exact_depth.at(u, v);
      float xyz[3] = {nan, nan, nan};
      if (z > 0) {
        const Eigen::Vector3f p = perception::backProject(k, u, v, z).cast<float>();
        xyz[0] = p.x() * x_scale, xyz[1] = p.y(), xyz[2] = p.z();
      }
      out.write(reinterpret_cast<const char*>(xyz), sizeof xyz);
      const auto& c = r.colour[static_cast<std::size_t>(v) * k.width + u];
      const std::uint32_t packed = (std::uint32_t{c[0]} << 16) | (std::uint32_t{c[1]} << 8) | c[2];
      out.write(reinterpret_cast<const char*>(&packed), sizeof packed);
    }
  }
}

// A .pcd frame cut short is found from its header and size before a run, without
// parsing its points: binary data shorter than WIDTH x HEIGHT x point size, or
// binary_compressed data shorter than its block's declared size.
TEST(PcdSequence, ACutFrameIsFoundFromItsHeaderBeforeTheRun) {
  sim::CorridorParams p;
  p.frames = 2;
  p.noise = sim::NoiseModel::kNone;
  const sim::CorridorScene scene(p);
  const fs::path dir = fs::temp_directory_path() / ("mobmap-pcdcut-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "frames");
  const std::string a = (dir / "frames" / "a.pcd").string(), b = (dir / "frames" / "b.pcd").string();
  writeOrganizedPcd(scene, 0, a);
  writeOrganizedPcd(scene, 1, b);
  {
    std::ofstream poses(dir / "poses.txt");
    sim::writeTumPoseLine(poses, 0.0, scene.cameraPose(0));
    sim::writeTumPoseLine(poses, 0.0, scene.cameraPose(1));
  }
  const auto full = fs::file_size(b);
  fs::resize_file(b, full - 1);  // one byte short of the last point's rgb
  const auto seq = sources::openSequence((dir / "frames").string(), {"", 0.05, (dir / "poses.txt").string(), {}, ""});
  EXPECT_NO_THROW(seq->check(0));
  try {
    seq->check(1);
    FAIL() << "a cut frame passed the check";
  } catch (const app::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("b.pcd: PCD data is shorter than its header declares (" + std::to_string(full - 1) +
                                         " bytes, " + std::to_string(full) + " needed)"),
              std::string::npos)
        << e.what();
  }
  // binary_compressed: the block says 1000 compressed bytes follow its two sizes.
  const std::string head = "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 100\n"
                           "HEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 100\nDATA binary_compressed\n";
  const std::string sizes("\xe8\x03\x00\x00\xb0\x04\x00\x00", 8);  // 1000, 1200
  const std::string c = (dir / "c.pcd").string();
  std::ofstream(c, std::ios::binary) << head << sizes << std::string(999, 'z');
  EXPECT_THROW(sources::checkPcdComplete(c), app::IoError);
  std::ofstream(c, std::ios::binary) << head << sizes << std::string(1000, 'z');
  EXPECT_NO_THROW(sources::checkPcdComplete(c));  // the sizes add up (the bytes are only checked by loading)
  std::ofstream(c, std::ios::binary) << head << sizes.substr(0, 5);
  EXPECT_THROW(sources::checkPcdComplete(c), app::IoError);
  // No x, y, z; and ASCII data shorter than two bytes a value.
  const std::string d = (dir / "d.pcd").string();
  std::ofstream(d) << "# .PCD v0.7\nVERSION 0.7\nFIELDS x y\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\nWIDTH 1\nHEIGHT 1\n"
                      "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 1\nDATA ascii\n1 2\n";
  try {
    sources::checkPcdComplete(d);
    FAIL();
  } catch (const app::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("d.pcd: PCD has no x, y and z fields"), std::string::npos) << e.what();
  }
  std::ofstream(d) << "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
                      "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA ascii\n1 2 3\n";
  EXPECT_THROW(sources::checkPcdComplete(d), app::IoError);  // 6 bytes cannot hold 6 values
  std::ofstream(d) << "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
                      "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n";
  EXPECT_NO_THROW(sources::checkPcdComplete(d));
  EXPECT_THROW(sources::checkPcdComplete((dir / "none.pcd").string()), app::IoError);
  fs::remove_all(dir);
}

TEST(PcdSequence, FileNameTimeStamps) {
  // 2012-12-14 14:22:55 UTC is 1355494975 s after the epoch.
  EXPECT_NEAR(*sources::timestampFromFileName("/x/frame_20121214T142255.814212.pcd"), 1355494975.814212, 1e-6);
  EXPECT_NEAR(*sources::timestampFromFileName("1305031102.175304.pcd"), 1305031102.175304, 1e-6);
  EXPECT_NEAR(*sources::timestampFromFileName("cloud-42.pcd"), 42.0, 0);
  EXPECT_FALSE(sources::timestampFromFileName("cloud.pcd"));
  EXPECT_FALSE(sources::timestampFromFileName("frame_2012121XT.pcd"));
  EXPECT_NEAR(*sources::timestampFromFileName("frame_2012121XT142255.pcd"), 142255.0, 0);  // not a date: the trailing number
}

TEST(PcdSequence, PosesInFileOrderOrByTimeStampAndAMapFromThem) {
  sim::CorridorParams p;
  p.frames = 30;
  p.noise = sim::NoiseModel::kNone;
  const sim::CorridorScene scene(p);
  const fs::path dir = fs::temp_directory_path() / ("mobmap-pcdseq-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "frames");
  const int frames[] = {0, 10, 20};
  {
    std::ofstream in_order(dir / "in_order.txt");
    std::ofstream timed(dir / "timed.txt");
    timed << "# timestamp tx ty tz qx qy qz qw\n";
    for (int f : frames) {
      char name[64];
      std::snprintf(name, sizeof name, "frame_20121214T1422%02d.000000.pcd", 10 + f / 10);  // one per second
      writeOrganizedPcd(scene, f, (dir / "frames" / name).string());
      sim::writeTumPoseLine(in_order, 0.0, scene.cameraPose(f));
    }
    // Timestamped poses every 0.25 s around the frames: the frame times interpolate
    // between samples of the same pose, so they must come back exactly.
    for (int f : frames) {
      for (double dt : {-0.25, 0.0, 0.25}) sim::writeTumPoseLine(timed, 1355494930.0 + f / 10 + dt, scene.cameraPose(f));
    }
  }
  const auto& k = scene.params().intrinsics;
  for (const char* poses : {"in_order.txt", "timed.txt"}) {
    const auto seq = sources::openSequence((dir / "frames").string(), {"", 0.3, (dir / poses).string(), {}, ""});
    ASSERT_EQ(seq->frames().size(), 3u) << poses;
    ASSERT_TRUE(seq->hasDepth()) << seq->describe();
    EXPECT_NEAR(seq->intrinsics().fx, k.fx, 1e-3);
    EXPECT_NEAR(seq->intrinsics().cy, k.cy, 1e-3);
    for (int n : seq->frames()) {
      const auto f = seq->load(n);
      ASSERT_TRUE(seq->pose(n));
      EXPECT_EQ(seq->pose(n)->matrix(), f.T_world_camera->matrix());
      const Eigen::Isometry3d truth = scene.cameraPose(frames[n]);
      EXPECT_LT((f.T_world_camera->translation() - truth.translation()).norm(), 1e-5) << poses << " " << n;
      EXPECT_LT(Eigen::AngleAxisd(f.T_world_camera->linear().transpose() * truth.linear()).angle(), 1e-5);
      const auto r = scene.render(frames[n]);
      for (std::size_t i = 0; i < r.exact_depth.depth_m.size(); i += 101) {
        ASSERT_NEAR(f.depth->depth_m[i], r.exact_depth.depth_m[i], 1e-6) << i;
      }
      // The cloud's rgb is the frame's colour image (for overlay).
      const auto colour = seq->colour(n);
      ASSERT_TRUE(colour);
      ASSERT_EQ(colour->pixels.size(), r.colour.size());
      for (std::size_t i = 0; i < r.colour.size(); i += 101) ASSERT_EQ(colour->pixels[i], r.colour[i]) << i;
    }
  }
  // Too few poses for frames without usable time stamps: a clear error naming the file.
  fs::create_directories(dir / "plain");
  for (const char* name : {"a.pcd", "b.pcd"}) fs::copy_file(fs::directory_iterator(dir / "frames")->path(), dir / "plain" / name);
  {
    std::ofstream one(dir / "one.txt");
    sim::writeTumPoseLine(one, 0.0, scene.cameraPose(0));
  }
  try {
    (void)sources::openSequence((dir / "plain").string(), {"", 0.05, (dir / "one.txt").string(), {}, ""});
    FAIL();
  } catch (const app::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("one.txt: 1 poses for 2 .pcd frames"), std::string::npos) << e.what();
  }
  try {
    (void)sources::openSequence((dir / "plain").string(), {"", 0.05, "", {}, ""});
    FAIL();
  } catch (const app::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("give `poses`"), std::string::npos) << e.what();
  }
  // A later frame that is not the first one's pinhole image (here stretched 5 % in x,
  // as a differently registered cloud would be) is refused, not misread as depth.
  fs::create_directories(dir / "warped");
  writeOrganizedPcd(scene, 0, (dir / "warped" / "a.pcd").string());
  writeOrganizedPcd(scene, 10, (dir / "warped" / "b.pcd").string(), 1.05f);
  {
    std::ofstream two(dir / "two.txt");
    sim::writeTumPoseLine(two, 0.0, scene.cameraPose(0));
    sim::writeTumPoseLine(two, 0.0, scene.cameraPose(10));
  }
  const auto warped = sources::openSequence((dir / "warped").string(), {"", 0.05, (dir / "two.txt").string(), {}, ""});
  ASSERT_TRUE(warped->hasDepth());
  EXPECT_NO_THROW((void)warped->load(0));
  try {
    (void)warped->load(1);
    FAIL() << "a stretched cloud was read as depth";
  } catch (const app::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("b.pcd: its points are not a pinhole image"), std::string::npos) << e.what();
  }
  // The CLI builds a map from the frames: the floor ahead of the walker is found at
  // z = 0 (the corridor's world frame is z up) and scores as traversable.
  const std::string out = (dir / "map.ot").string();
  const std::string cmd = std::string(MOBMAP_EXE) + " build " + (dir / "frames").string() + " --poses " +
                          (dir / "in_order.txt").string() + " --out " + out + " --quiet > " + (dir / "log").string() + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  const auto map = mapping::openMap(out);
  const Eigen::Vector3d cam = scene.cameraPose(10).translation();
  const auto floor = map.snapDown(Eigen::Vector3d(cam.x() + 1.5, cam.y(), 0.1), 0.3);
  ASSERT_TRUE(floor);
  EXPECT_NEAR(floor->centre.z(), 0.0, map.tree().getResolution());
  ASSERT_TRUE(floor->has_mobility);
  EXPECT_GT(floor->mobility, 0.75);
  // overlay reads the same frames with the same poses: the map over the cloud's colours.
  const std::string ov = (dir / "ov.png").string();
  // (--poses defaults to the trajectory MAP.json names.)
  const std::string ov_cmd = std::string(MOBMAP_EXE) + " overlay " + out + " --frame " + (dir / "frames").string() +
                             ":1 --out " + ov + " > " + (dir / "log").string() + " 2>&1";
  ASSERT_EQ(std::system(ov_cmd.c_str()), 0) << ov_cmd;
  const app::ImageRgb picture = app::readPngRgb(ov);
  const auto r10 = scene.render(10);
  ASSERT_GT(picture.pixels.size(), r10.colour.size());  // the frame, then the legend
  ASSERT_EQ(picture.width, scene.params().intrinsics.width);
  std::size_t as_is = 0;
  for (std::size_t i = 0; i < r10.colour.size(); ++i) as_is += picture.pixels[i] == app::greyOf(r10.colour[i]);
  // The colour image shows in grey where no voxel is, and the map covers most of it.
  EXPECT_GT(as_is, 0u);
  EXPECT_LT(as_is, r10.colour.size() / 2) << as_is;
  // info says which trajectory the map was built with.
  const std::string info_cmd = std::string(MOBMAP_EXE) + " info " + out + " > " + (dir / "info").string() + " 2>&1";
  ASSERT_EQ(std::system(info_cmd.c_str()), 0) << info_cmd;
  std::ifstream info_file(dir / "info");
  const std::string info((std::istreambuf_iterator<char>(info_file)), std::istreambuf_iterator<char>());
  EXPECT_NE(info.find("poses: " + fs::absolute(dir / "in_order.txt").lexically_normal().string() + " ("), std::string::npos) << info;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mobmap
