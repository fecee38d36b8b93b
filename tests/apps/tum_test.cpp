// TUM RGB-D sequences: pose interpolation and association, overlays, bad ground truth; keyframes.
#include "tum_support.hpp"

namespace mobmap {
namespace {

TEST(Trajectory, InterpolatesLinearlyAndSlerpsAndRefusesGaps) {
  mapping::Trajectory tr;
  Eigen::Isometry3d a = Eigen::Isometry3d::Identity(), b = Eigen::Isometry3d::Identity();
  b.translation() = Eigen::Vector3d(1, 2, 3);
  b.linear() = Eigen::AngleAxisd(0.6, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  tr.insert(10.0, a);
  tr.insert(10.1, b);
  const auto mid = tr.at(10.05, 0.2);
  ASSERT_TRUE(mid);
  // Times are kept to the nanosecond: at 37 m/s and 6 rad/s between these samples that
  // is ~4e-8 m and ~6e-9 rad.
  EXPECT_LT((mid->translation() - Eigen::Vector3d(0.5, 1, 1.5)).norm(), 1e-7);
  EXPECT_NEAR(Eigen::AngleAxisd(mid->linear()).angle(), 0.3, 1e-8);
  EXPECT_FALSE(tr.at(9.99, 0.2));         // before the first sample
  EXPECT_FALSE(tr.at(10.11, 0.2));        // after the last
  // The gap is the span between the two samples around the stamp (100 ms here), as for
  // TF: each is only 50 ms from 10.05, but they lie more than 60 ms apart.
  EXPECT_FALSE(tr.at(10.05, 0.06));
  EXPECT_TRUE(tr.at(10.05, 0.1));
  EXPECT_TRUE(tr.at(10.1, 0.0));          // an exact sample
  // Inserted out of order, the same trajectory.
  mapping::Trajectory reversed;
  reversed.insert(10.1, b);
  reversed.insert(10.0, a);
  const auto again = reversed.at(10.05, 0.2);
  ASSERT_TRUE(again);
  EXPECT_TRUE(again->isApprox(*mid, 1e-15));
  EXPECT_THROW(tr.insert(std::nan(""), a), std::invalid_argument);
}

TEST(Keyframes, FollowTheLastKeyframeNotTheLastFrame) {
  // A camera that stands still for 5 poses, then moves 1 cm per pose along x, then turns
  // 1 degree per pose about a tilted axis on the spot.
  std::vector<Eigen::Isometry3d> path;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  for (int i = 0; i < 5; ++i) path.push_back(T);
  for (int i = 0; i < 20; ++i) {
    T.translation().x() += 0.01;
    path.push_back(T);
  }
  const Eigen::Vector3d axis = Eigen::Vector3d(0.3, -1, 0.2).normalized();
  for (int i = 0; i < 20; ++i) {
    T.linear() = T.linear() * Eigen::AngleAxisd(M_PI / 180, axis).toRotationMatrix();
    path.push_back(T);
  }
  // Brute force: walk the path with the rule written out.
  const auto reference = [&](double min_m, double min_deg) {
    std::vector<std::size_t> keep{0};
    for (std::size_t i = 1; i < path.size(); ++i) {
      const Eigen::Isometry3d& k = path[keep.back()];
      const double d = (path[i].translation() - k.translation()).norm();
      const Eigen::Quaterniond q(k.linear().transpose() * path[i].linear());
      const double deg = 2 * std::atan2(q.vec().norm(), std::abs(q.w())) * 180 / M_PI;
      if ((min_m > 0 && d >= min_m - 1e-9) || (min_deg > 0 && deg >= min_deg - 1e-9)) keep.push_back(i);
    }
    return keep;
  };
  // 4.5 cm: every 5th pose of the walk (a drift of 1 cm per pose is not a keyframe
  // each time: distance counts from the last keyframe); the turn alone never qualifies.
  const auto walk = mapping::selectKeyframes(path, 0.045, 0);
  EXPECT_EQ(walk, (std::vector<std::size_t>{0, 9, 14, 19, 24}));
  EXPECT_EQ(walk, reference(0.045, 0));
  // 2.5 degrees: every 3rd pose of the turn.
  const auto turn = mapping::selectKeyframes(path, 0, 2.5);
  EXPECT_EQ(turn, (std::vector<std::size_t>{0, 27, 30, 33, 36, 39, 42}));
  EXPECT_EQ(turn, reference(0, 2.5));
  // Either limit.
  EXPECT_EQ(mapping::selectKeyframes(path, 0.045, 2.5), (std::vector<std::size_t>{0, 9, 14, 19, 24, 27, 30, 33, 36, 39, 42}));
  EXPECT_TRUE(mapping::selectKeyframes({}, 0.1, 5).empty());
  EXPECT_THROW((void)mapping::selectKeyframes(path, 0, 0), std::invalid_argument);
  EXPECT_THROW((void)mapping::selectKeyframes(path, -0.1, 5), std::invalid_argument);
  EXPECT_THROW((void)mapping::selectKeyframes(path, 0.1, std::nan("")), std::invalid_argument);
}

TEST(TumSequence, AssociatesDepthWithInterpolatedPosesAndSkipsFramesInAGap) {
  sim::CorridorParams p;
  p.frames = 10;
  p.noise = sim::NoiseModel::kNone;
  const sim::CorridorScene scene(p);
  const std::string dir = writeTum(scene, 10, 5);
  const auto seq = sources::openSequence(dir, {"585,585,320,240", 0.02, "", {}, ""});
  EXPECT_NE(seq->describe().find("TUM"), std::string::npos);
  ASSERT_EQ(seq->frames().size(), 9u);  // frame 5 has no pose within 20 ms
  EXPECT_NE(seq->skipped().find("1 of 10 depth frames"), std::string::npos) << seq->skipped();
  for (int n : seq->frames()) {
    const auto f = seq->load(n);
    ASSERT_TRUE(seq->pose(n));  // known before the run (build --keyframes), the same as load()'s
    EXPECT_EQ(seq->pose(n)->matrix(), f.T_world_camera->matrix());
    const int frame = n < 5 ? n : n + 1;  // sequence indices skip the gap frame
    const Eigen::Isometry3d truth = scene.cameraPose(frame);
    // Linear + slerp over 10 ms of a smooth walk: sub-millimetre.
    EXPECT_LT((f.T_world_camera->translation() - truth.translation()).norm(), 1e-3) << frame;
    EXPECT_LT(Eigen::AngleAxisd(f.T_world_camera->linear().transpose() * truth.linear()).angle(), 1e-3) << frame;
    const auto r = scene.render(frame);
    for (std::size_t i = 0; i < r.exact_depth.depth_m.size(); i += 97) {
      if (r.exact_depth.depth_m[i] > 0) {
        ASSERT_NEAR(f.depth->depth_m[i], r.exact_depth.depth_m[i], 1.0 / 10000 + 1e-6);
      }
    }
  }
  fs::remove_all(dir);
}

// `overlay` reads a TUM frame as `build` numbers it, over its registered colour image
// (rgb.txt, paired within 0.02 s), and paints the map where the frame sees it: the
// floor's pixels in green, the box and ramp sides' in red.
// `analyze` reads a TUM directory's frames too, numbered the same way.
TEST(TumSequence, OverlayPaintsTheMapOverTheRegisteredColourAndAnalyzeReadsTheSameFrame) {
  sim::CorridorParams p;
  p.frames = 240;       // the moving box moves from frame 40 on: it stands still in frames 0-11
  p.noise = sim::NoiseModel::kNone;
  p.speed_mps = 12.0;  // 0.4 m per frame: frame 6 stands before the steeper ramps
  const sim::CorridorScene scene(p);
  const std::string dir = writeTum(scene, 12, 1000);  // no gap: sequence index = frame
  const auto& k = scene.params().intrinsics;
  // Colour 5 ms after each depth frame, a pattern that names the frame in blue; frame
  // 3's colour is 30 ms late, too far to pair with its depth.
  auto pattern = [](int u, int v, int f) -> std::array<std::uint8_t, 3> {
    return {static_cast<std::uint8_t>(u % 200), static_cast<std::uint8_t>(v % 200), static_cast<std::uint8_t>(10 * f)};
  };
  fs::create_directories(fs::path(dir) / "rgb");
  {
    std::ofstream rgb_txt(fs::path(dir) / "rgb.txt");
    rgb_txt << "# color images\n# timestamp filename\n";
    for (int f = 0; f < 12; ++f) {
      app::ImageRgb img{k.width, k.height, {}};
      for (int v = 0; v < k.height; ++v) {
        for (int u = 0; u < k.width; ++u) img.pixels.push_back(pattern(u, v, f));
      }
      const double t = kT0 + f / 30.0 + (f == 3 ? 0.03 : 0.005);
      char name[64];
      std::snprintf(name, sizeof(name), "rgb/%.6f.png", t);
      app::writePngRgb((fs::path(dir) / name).string(), img);
      rgb_txt << std::fixed << t << " " << name << "\n";
    }
  }
  const std::string intrinsics = "585,585,320,240";
  const auto seq = sources::openSequence(dir, {intrinsics, 0.02, "", {}, ""});
  ASSERT_EQ(seq->frames().size(), 12u);
  for (int n : {0, 6, 11}) {
    const auto c = seq->colour(n);
    ASSERT_TRUE(c) << n;
    ASSERT_EQ(c->width, k.width);
    EXPECT_EQ(c->pixels[static_cast<std::size_t>(123 * k.width + 456)], pattern(456, 123, n));
  }
  EXPECT_FALSE(seq->colour(3));
  const std::string map = dir + "/map.ot", out = dir + "/ov.png";
  const std::string log = " > " + dir + "/log 2>&1";
  ASSERT_EQ(std::system((std::string(MOBMAP_EXE) + " build " + dir + " --intrinsics " + intrinsics + " --out " + map + " --quiet" + log).c_str()), 0);
  // The intrinsics the map was built with come from MAP.json.
  ASSERT_EQ(std::system((std::string(MOBMAP_EXE) + " overlay " + map + " --frame " + dir + "/:6 --colours red-green --out " + out + log).c_str()), 0);
  const app::ImageRgb ov = app::readPngRgb(out);
  // The frame, then the legend below it.
  ASSERT_EQ(ov.width, k.width);
  ASSERT_GT(ov.height, k.height);
  // Every pixel is the colour image's in grey, or that grey 2:3 blended with a mobility
  // colour: recover that colour (to within rounding) and count the pixels of the floor
  // and of the surfaces no robot stands on.
  const auto r = scene.render(6);
  struct Paint {
    int floor = 0, floor_painted = 0, floor_green = 0, blocked_painted = 0, blocked_red = 0, neither = 0;
    int beyond_range_painted = 0;  // farther than the 3 m range: nothing measured there
    int unpainted = 0;             // exactly the grey of this frame's colour image
  };
  const auto judge = [&](const app::ImageRgb& picture) {
    Paint n;
    for (int v = 0; v < k.height; ++v) {
      for (int u = 0; u < k.width; ++u) {
        const std::size_t i = static_cast<std::size_t>(v) * k.width + u;
        const auto base = app::greyOf(pattern(u, v, 6));
        const auto o = picture.pixels[i];
        const bool painted = o != base;
        n.unpainted += !painted;
        std::array<int, 3> paint{};
        for (std::size_t ch = 0; ch < 3; ++ch) paint[ch] = (5 * o[ch] - 2 * base[ch]) / 3;
        // A blend of this base with a colour in [0, 255] (integer division: within 2).
        const bool blend = std::all_of(paint.begin(), paint.end(), [](int x) { return x >= -2 && x <= 257; });
        n.neither += painted && !blend;
        const int id = r.labels[i];
        const float z = r.exact_depth.depth_m[i];
        const double range = perception::backProject(k, u, v, z).norm();
        n.beyond_range_painted += painted && (id == 0 || range > 3.05);
        // Within the 3 m mapping range, and not at its edge.
        if (id == 0 || range > 2.8) continue;
        const sim::SurfaceKind kind = scene.surface(id).kind;
        if (kind == sim::SurfaceKind::kFloor) {
          ++n.floor;
          n.floor_painted += painted;
          n.floor_green += painted && paint[1] > paint[0] + 100;
        } else if (scene.surface(id).expected_mobility == 0.0 && painted) {  // box and ramp sides here
          ++n.blocked_painted;
          n.blocked_red += paint[0] > paint[1] + 100;
        }
      }
    }
    return n;
  };
  // Every painted pixel a blend over the base; the floor in range painted, green; the
  // surfaces no robot stands on, red.
  const auto expectMobilityPaint = [&](const Paint& n) {
    EXPECT_EQ(n.neither, 0);
    // Frame 6's own colour image under the paint (frame 5's or 7's would differ by a grey
    // level or two everywhere): where nothing is painted, it shows as it is.
    EXPECT_GT(n.unpainted, k.width * k.height / 20) << n.unpainted;
    ASSERT_GT(n.floor, 20000);  // the floor fills most of the view
    EXPECT_GT(n.floor_painted, 0.95 * n.floor) << n.floor_painted << " of " << n.floor;
    EXPECT_GT(n.floor_green, 0.97 * n.floor_painted) << n.floor_green << " of " << n.floor_painted;
    ASSERT_GT(n.blocked_painted, 5000);
    EXPECT_GT(n.blocked_red, 0.9 * n.blocked_painted) << n.blocked_red << " of " << n.blocked_painted;
  };
  ASSERT_NO_FATAL_FAILURE(expectMobilityPaint(judge(ov)));
  // How many of a sample of a picture's pixels show frame f's colour image, in grey.
  const auto patternPixels = [&](const app::ImageRgb& picture, int f) {
    std::pair<int, int> shown_sampled{0, 0};
    for (int v = 0; v < k.height; v += 7) {
      for (int u = 0; u < k.width; u += 7, ++shown_sampled.second) {
        shown_sampled.first += picture.pixels[static_cast<std::size_t>(v) * k.width + u] == app::greyOf(pattern(u, v, f));
      }
    }
    return shown_sampled;
  };
  const auto [paired, of_paired] = patternPixels(ov, 6);
  EXPECT_GT(paired, of_paired / 20) << paired << " of " << of_paired;
  // Frame 3 (of the map's own input: N alone) has no colour to pair: the base is the
  // shaded depth, so the pattern's grey shows only where the two happen to agree. So
  // does frame 6 with --background depth.
  ASSERT_EQ(std::system((std::string(MOBMAP_EXE) + " overlay " + map + " --frame 3 --out " + out + log).c_str()), 0);
  const auto [unpaired, sampled] = patternPixels(app::readPngRgb(out), 3);
  EXPECT_LT(unpaired, sampled / 50) << unpaired << " of " << sampled;
  ASSERT_EQ(std::system((std::string(MOBMAP_EXE) + " overlay " + map + " --frame 6 --background depth --out " + out + log).c_str()), 0);
  const int on_depth = patternPixels(app::readPngRgb(out), 6).first;
  EXPECT_LT(on_depth, sampled / 50) << on_depth << " of " << sampled;
  // analyze reads the same frame, numbered the same way: its ground plane lies the
  // camera's height below it.
  const std::string json = dir + "/frame6.json", analyze_ov = dir + "/analyze.png", segments = dir + "/segments.pcd";
  ASSERT_EQ(std::system((std::string(MOBMAP_EXE) + " analyze " + dir + " --frame 6 --intrinsics " + intrinsics + " --json --colours red-green --overlay " +
                         analyze_ov + " --segments " + segments + " > " + json + " 2> " + dir + "/log").c_str()), 0);
  std::ifstream json_file(json);
  const auto analyzed = nlohmann::json::parse(json_file);
  ASSERT_TRUE(analyzed.contains("ground_plane")) << analyzed.dump();
  const auto& plane = analyzed["ground_plane"];
  EXPECT_NEAR(plane[3].get<double>(), scene.cameraPose(6).translation().z(), 0.01);
  // analyze --overlay: the frame's own segments over the same colour image, the same way.
  {
    const Paint n = judge(app::readPngRgb(analyze_ov));
    ASSERT_NO_FATAL_FAILURE(expectMobilityPaint(n));
    EXPECT_EQ(n.beyond_range_painted, 0);
    ASSERT_EQ(std::system((std::string(MOBMAP_EXE) + " analyze " + dir + " --frame 6 --intrinsics " + intrinsics +
                           " --background depth --overlay " + analyze_ov + log).c_str()),
              0);
    const auto [shown, of] = patternPixels(app::readPngRgb(analyze_ov), 6);
    EXPECT_LT(shown, of / 50) << shown << " of " << of;
  }
  // analyze --segments: an ASCII PCD of the segmented points in the camera frame, each
  // with its segment's id, mobility and the mobility's colour as PCL's packed rgb.
  {
    const auto& segs = analyzed["segments"];
    ASSERT_GE(segs.size(), 3u) << analyzed.dump();
    std::size_t total = 0;
    for (const auto& s : segs) total += s["points"].get<std::size_t>();
    std::ifstream pcd(segments);
    std::string line;
    std::vector<std::string> header;
    while (std::getline(pcd, line) && line != "DATA ascii") header.push_back(line);
    ASSERT_EQ(line, "DATA ascii");
    EXPECT_NE(std::find(header.begin(), header.end(), "FIELDS x y z rgb segment mobility"), header.end());
    EXPECT_NE(std::find(header.begin(), header.end(), "POINTS " + std::to_string(total)), header.end());
    std::vector<std::size_t> rows(segs.size(), 0);
    std::size_t on_surface = 0, on_ground_plane = 0, bad = 0;
    float x, y, z, rgb, m;
    int s;
    while (pcd >> x >> y >> z >> rgb >> s >> m) {
      if (s < 0 || static_cast<std::size_t>(s) >= segs.size()) {
        ++bad;
        continue;
      }
      ++rows[static_cast<std::size_t>(s)];
      const auto& seg = segs[static_cast<std::size_t>(s)];
      std::uint32_t packed = 0;
      std::memcpy(&packed, &rgb, sizeof(packed));
      const double mobility = seg["mobility"].get<double>();
      const app::Rgb c = app::mobilityColour(mobility, app::ColourScale::kRedGreen);
      bad += seg["id"].get<int>() != s || std::abs(m - mobility) > 6e-5 ||
             packed != ((static_cast<std::uint32_t>(c[0]) << 16) | (static_cast<std::uint32_t>(c[1]) << 8) | c[2]);
      // The point lies on the surface the camera sees through its pixel (a voxel's
      // centroid: within 1 cm of the exact depth there, away from edges).
      const int u = static_cast<int>(std::lround(k.fx * x / z + k.cx)), v = static_cast<int>(std::lround(k.fy * y / z + k.cy));
      if (u >= 0 && v >= 0 && u < k.width && v < k.height) {
        on_surface += std::abs(r.exact_depth.depth_m[static_cast<std::size_t>(v) * k.width + u] - z) < 0.01;
      }
      if (seg["is_ground"].get<bool>()) {
        on_ground_plane += std::abs(plane[0].get<double>() * x + plane[1].get<double>() * y + plane[2].get<double>() * z +
                                    plane[3].get<double>()) < 0.02;
      }
    }
    EXPECT_EQ(bad, 0u);
    for (std::size_t i = 0; i < segs.size(); ++i) EXPECT_EQ(rows[i], segs[i]["points"].get<std::size_t>()) << "segment " << i;
    EXPECT_GT(on_surface, 0.95 * total) << on_surface << " of " << total;
    ASSERT_TRUE(segs[0]["is_ground"].get<bool>());
    EXPECT_EQ(on_ground_plane, segs[0]["points"].get<std::size_t>());
  }
  // A frame the sequence does not have: exit 1, naming the input and the frames it has.
  ASSERT_NE(std::system((std::string(MOBMAP_EXE) + " overlay " + map + " --frame " + dir + ":12 --out " + out + log).c_str()), 0);
  std::ifstream log_file(dir + "/log");
  const std::string text((std::istreambuf_iterator<char>(log_file)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("has no posed frame 12 (frames 0..11, 12 of them)"), std::string::npos) << text;
  fs::remove_all(dir);
}

TEST(TumSequence, BadGroundTruthNamesTheFileAndPose) {
  const fs::path dir = fs::temp_directory_path() / ("mobmap-tum-bad-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "depth.txt") << "1.0 depth/1.png\n";
  std::ofstream(dir / "groundtruth.txt") << "1.0 0 0 0 0 0 0 1\n1.1 0 0 0 0.5 0 0 0.5\n";
  try {
    (void)sources::openSequence(dir.string(), {"", 0.05, "", {}, ""});
    FAIL();
  } catch (const app::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("groundtruth.txt: pose 2: quaternion norm"), std::string::npos) << e.what();
  }
  std::ofstream(dir / "groundtruth.txt") << "1.0 0 0 0 0 0 0\n";
  try {
    (void)sources::openSequence(dir.string(), {"", 0.05, "", {}, ""});
    FAIL();
  } catch (const app::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("line 1: expected 8 columns"), std::string::npos) << e.what();
  }
  fs::remove(dir / "groundtruth.txt");
  try {
    (void)sources::openSequence(dir.string(), {"", 0.05, "", {}, ""});
    FAIL();
  } catch (const app::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("groundtruth.txt: missing"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mobmap
