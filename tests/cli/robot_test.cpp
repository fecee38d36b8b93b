// Robot limits, picture sizes, keyframes, and errors that name the file.
#include "cli_support.hpp"

namespace mobmap::cli_test {
namespace {

TEST(Cli, RobotLimitsPictureSizesEvaluateToleranceAndDemoStep) {
  const std::string dir = tempDir("limits");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 24 --quiet").code, 0);  // Kinect noise
  const std::string map = dir + "/m.ot";
  ASSERT_EQ(run("build " + dir + "/seq --frames 0:23:2 --out " + map + " --quiet").code, 0);
  const auto places = [&](const std::string& options) {
    const Result r = run("reach " + map + " --pcd " + dir + "/p.pcd" + options);
    EXPECT_EQ(r.code, 0) << r.out;
    return readPlaces(dir + "/p.pcd");
  };
  const auto base = places(""), tall = places(" --clearance 1.9"), no_gap = places(" --max-gap 0");
  ASSERT_GT(base.size(), 5000u);
  ASSERT_EQ(tall.size(), base.size());
  ASSERT_EQ(no_gap.size(), base.size());
  // --clearance: a place stays standable only if no run above it in its column starts
  // within 1.9 m (a run's top place is at least one 2 cm voxel above its bottom); the
  // places it rules out all have something above them.
  std::map<std::pair<double, double>, std::vector<double>> columns;
  for (const auto& [p, f] : base) columns[{p[0], p[1]}].push_back(p[2]);
  std::vector<std::array<double, 3>> lost;
  for (const auto& [p, f] : base) {
    const PlaceFlags& t = tall.at(p);
    EXPECT_TRUE(!t.standable || f.standable);
    EXPECT_TRUE(!t.reachable || f.reachable);
    double lowest_above = 1e9;
    for (double z : columns[{p[0], p[1]}])
      if (z > p[2]) lowest_above = std::min(lowest_above, z);
    if (t.standable) {
      EXPECT_GE(lowest_above - 0.02 - p[2], 1.9 - 1e-6) << p[0] << " " << p[1] << " " << p[2];
    }
    if (f.standable && !t.standable) {
      lost.push_back(p);
      EXPECT_LT(lowest_above, 1e9) << p[0] << " " << p[1] << " " << p[2];
    }
  }
  ASSERT_FALSE(lost.empty());
  // --max-gap 0: the same places standable, reachable ones a subset.
  for (const auto& [p, f] : base) {
    EXPECT_EQ(no_gap.at(p).standable, f.standable);
    EXPECT_TRUE(!no_gap.at(p).reachable || f.reachable);
  }
  // query --reach passes the same limits on, and says which one a place fails.
  const auto& q = lost.front();
  const std::string at = std::to_string(q[0]) + " " + std::to_string(q[1]) + " " + std::to_string(q[2] + 0.01);
  const Result fits = run("query " + map + " " + at + " --reach --json");
  ASSERT_EQ(fits.code, 0) << fits.out;
  const auto fj = jsonLine(fits.out);
  EXPECT_TRUE(fj["reach"]["standable"].get<bool>()) << fits.out;
  const Result low = run("query " + map + " " + at + " --reach --clearance 1.9 --json");
  ASSERT_EQ(low.code, 0) << low.out;
  const auto lj = jsonLine(low.out);
  EXPECT_FALSE(lj["reach"]["standable"].get<bool>()) << low.out;
  EXPECT_LT(lj["reach"]["headroom_m"].get<double>(), 1.9) << low.out;
  EXPECT_NE(run("query " + map + " " + at + " --reach --clearance 1.9").out.find("cannot be stood on"), std::string::npos);
  // The library names the field; the command line says the flag and the value.
  for (const auto& [options, field] : {std::pair<const char*, const char*>{" --clearance -1", "error: --clearance is -1 ("},
                                       {" --max-gap 5", "error: --max-gap is 5 ("},
                                       {" --min-mobility 1.5", "error: --min-mobility is 1.5 ("}}) {
    for (const std::string& cmd : {"reach " + map, "query " + map + " 1 0 0 --reach"}) {
      const Result bad = run(cmd + options);
      EXPECT_EQ(bad.code, 2) << cmd << options << ": " << bad.out;
      EXPECT_NE(bad.out.find(field), std::string::npos) << bad.out;
      EXPECT_EQ(bad.out.find_first_of("`_"), std::string::npos) << bad.out;
    }
  }
  // --max-pixels: the default draws one 2 cm voxel as several pixels; 64 draws cells of
  // k x k voxels, k = ceil(columns / 64); the sizes printed are the files'.
  const Result big = run("export " + map + " --png " + dir + "/big.png");
  const Result small = run("export " + map + " --png " + dir + "/small.png --max-pixels 64");
  ASSERT_EQ(big.code, 0) << big.out;
  ASSERT_EQ(small.code, 0) << small.out;
  int bw = 0, bh = 0, ppv = 0, sw = 0, sh = 0, k = 0;
  ASSERT_EQ(std::sscanf(big.out.substr(big.out.find('(')).c_str(), "(%dx%d px, %d px per 2 cm voxel", &bw, &bh, &ppv), 3) << big.out;
  ASSERT_EQ(std::sscanf(small.out.substr(small.out.find('(')).c_str(), "(%dx%d px, 1 px per %*d cm cell: the highest of %dx", &sw,
                        &sh, &k),
            3)
      << small.out;
  EXPECT_EQ(pngSize(dir + "/big.png"), std::make_pair(bw, bh));
  EXPECT_EQ(pngSize(dir + "/small.png"), std::make_pair(sw, sh));
  const int columns_max = 1400 / ppv;  // the map's longer side in voxels, to within ppv
  EXPECT_GE(k, (1400 / (ppv + 1) + 63) / 64);
  EXPECT_LE(k, (columns_max + 63) / 64 + 1);
  EXPECT_LT(sw, bw);
  EXPECT_LT(sh, bh);
  const Result reach_small = run("reach " + map + " --png " + dir + "/reach_small.png --max-pixels 64");
  ASSERT_EQ(reach_small.code, 0) << reach_small.out;
  int rw = 0, rh = 0, rk = 0;
  const std::size_t wrote = reach_small.out.find("wrote " + dir + "/reach_small.png (");
  ASSERT_NE(wrote, std::string::npos) << reach_small.out;
  ASSERT_EQ(std::sscanf(reach_small.out.c_str() + reach_small.out.find('(', wrote),
                        "(%dx%d px, 1 px per %*d cm cell: the highest of %dx", &rw, &rh, &rk),
            3)
      << reach_small.out;
  EXPECT_EQ(pngSize(dir + "/reach_small.png"), std::make_pair(rw, rh));
  EXPECT_EQ(rk, k);
  EXPECT_LT(rw, bw);
  // evaluate --tolerance: floor voxel centres are 1 cm above the floor, so 5 mm counts
  // none of them and the default 4 cm all those --tolerance 0.1 does.
  const auto floorVoxels = [&](const std::string& options) {
    const Result ev = run("evaluate " + map + " --truth " + dir + "/seq/ground_truth.json --json" + options);
    EXPECT_EQ(ev.code, 0) << ev.out;
    return nlohmann::json::parse(ev.out)["surfaces"][0]["voxels"].get<int>();
  };
  EXPECT_EQ(floorVoxels(" --tolerance 0.005"), 0);
  const int floor4 = floorVoxels(""), floor10 = floorVoxels(" --tolerance 0.1");
  EXPECT_GT(floor4, 1000);
  EXPECT_GE(floor10, floor4);
  EXPECT_LT(floor10, floor4 * 11 / 10);
  // demo --step 4 over 12 frames fuses frames 0, 4 and 8.
  const Result demo = run("demo --out " + dir + "/demo --frames 12 --step 4 --quiet");
  ASSERT_EQ(demo.code, 0) << demo.out;
  EXPECT_NE(demo.out.find("--frames 0:11:4"), std::string::npos) << demo.out;
  std::ifstream meta(dir + "/demo/corridor.json");
  const auto dj = nlohmann::json::parse(meta);
  EXPECT_EQ(dj["frames"].get<int>(), 3);
  EXPECT_EQ(dj["trajectory_map"].size(), 3u);
  fs::remove_all(dir);
}

// `build --keyframes M,DEG` fuses the frames whose camera moved >= M or turned >= DEG
// since the last frame fused: checked against the rule applied to the pose files.
TEST(Cli, KeyframesAreTheFramesThatMovedOrTurnedEnoughSinceTheLastOneFused) {
  const std::string dir = tempDir("keyframes");
  const int n = 12;
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames " + std::to_string(n) + " --quiet").code, 0);
  // The corridor walk moves ~2.6 cm and turns 0.2-0.5 degrees per frame.
  const double min_m = 0.07, min_deg = 0.9;
  using Pose = std::array<std::array<double, 4>, 3>;
  std::vector<Pose> poses;
  for (int f = 0; f < n; ++f) {
    char name[64];
    std::snprintf(name, sizeof name, "/seq/frame-%06d.pose.txt", f);
    std::ifstream in(dir + name);
    Pose p{};
    for (auto& row : p) for (double& v : row) in >> v;
    ASSERT_TRUE(in) << name;
    poses.push_back(p);
  }
  std::vector<int> expected{0};
  for (int f = 1; f < n; ++f) {
    const Pose& a = poses[static_cast<std::size_t>(expected.back())];
    const Pose& b = poses[static_cast<std::size_t>(f)];
    double d2 = 0, trace = 0;
    for (int i = 0; i < 3; ++i) {
      d2 += (a[i][3] - b[i][3]) * (a[i][3] - b[i][3]);
      for (int k = 0; k < 3; ++k) trace += a[k][i] * b[k][i];  // trace(A^T B)
    }
    const double deg = std::acos(std::clamp((trace - 1) / 2, -1.0, 1.0)) * 180 / M_PI;
    if (std::sqrt(d2) >= min_m || deg >= min_deg) expected.push_back(f);
  }
  ASSERT_GT(expected.size(), 2u);
  ASSERT_LT(expected.size(), static_cast<std::size_t>(n) - 3);

  const Result built = run("build " + dir + "/seq --out " + dir + "/kf.ot --keyframes 0.07,0.9");
  ASSERT_EQ(built.code, 0) << built.out;
  const std::string said = "keyframes: " + std::to_string(expected.size()) + " of the " + std::to_string(n) + " selected frames";
  EXPECT_NE(built.out.find(said), std::string::npos) << built.out;
  const auto meta = nlohmann::json::parse(fileBytes(dir + "/kf.json"));
  EXPECT_EQ(meta["frames"], expected.size());
  EXPECT_EQ(meta["frame_numbers"], nlohmann::json({expected.front(), expected.back()}));
  EXPECT_EQ(meta["keyframes"]["frames_considered"], n);
  // The camera path holds the fused frames' positions (map frame = R_map_world * world).
  const auto& R = meta["R_map_world"];
  const auto& path = meta["trajectory_map"];
  ASSERT_EQ(path.size(), expected.size());
  for (std::size_t k = 0; k < expected.size(); ++k) {
    const Pose& p = poses[static_cast<std::size_t>(expected[k])];
    for (int i = 0; i < 3; ++i) {
      double v = 0;
      for (int j = 0; j < 3; ++j) v += R[i][j].get<double>() * p[j][3];
      EXPECT_NEAR(path[k][i].get<double>(), v, 1e-9) << "keyframe " << k;
    }
  }
  const Result info = run("info " + dir + "/kf.ot");
  EXPECT_NE(info.out.find("(keyframes of " + std::to_string(n) + ": camera moved >= 0.07 m or turned >= 0.9 degrees)"),
            std::string::npos) << info.out;

  const Result none = run("build " + dir + "/seq --out " + dir + "/none.ot --keyframes 0,0");
  EXPECT_EQ(none.code, 2);
  EXPECT_NE(none.out.find("--keyframes: at least one of"), std::string::npos) << none.out;
  const Result one = run("build " + dir + "/seq --out " + dir + "/none.ot --keyframes 0.05");
  EXPECT_EQ(one.code, 2) << one.out;
  const Result lone = run("build " + dir + "/seq/frame-000000.depth.png --intrinsics 585,585,320,240 --out " + dir +
                          "/none.ot --keyframes 0.05,5");
  EXPECT_EQ(lone.code, 2);
  EXPECT_NE(lone.out.find("--keyframes needs a sequence"), std::string::npos) << lone.out;
  EXPECT_FALSE(fs::exists(dir + "/none.ot"));
  fs::remove_all(dir);
}

TEST(Cli, BadSequencesAndMapsGiveErrorsNamingTheFile) {
  const std::string dir = tempDir("bad");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 3 --noise none --quiet").code, 0);
  // A pose that is not a rigid transform.
  std::ofstream(dir + "/seq/frame-000001.pose.txt") << "2 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
  const Result scaled = run("build " + dir + "/seq --out " + dir + "/m.ot --quiet");
  EXPECT_EQ(scaled.code, 1);
  EXPECT_NE(scaled.out.find("frame-000001.pose.txt: not a rigid transform"), std::string::npos) << scaled.out;
  EXPECT_FALSE(fs::exists(dir + "/m.ot"));  // no partial map left behind
  // Fewer poses than frames.
  fs::remove(dir + "/seq/frame-000001.pose.txt");
  const Result missing = run("build " + dir + "/seq --out " + dir + "/m.ot --quiet");
  EXPECT_EQ(missing.code, 1);
  EXPECT_NE(missing.out.find("frame-000001.pose.txt: missing"), std::string::npos) << missing.out;
  // An output that cannot be written: said before any frame is read (the pose error
  // above would otherwise come first), and nothing is left behind.
  fs::create_directories(dir + "/taken.ot");
  const Result into_dir = run("build " + dir + "/seq --out " + dir + "/taken.ot --force --quiet");
  EXPECT_EQ(into_dir.code, 1);
  EXPECT_NE(into_dir.out.find("taken.ot: is a directory"), std::string::npos) << into_dir.out;
  std::ofstream(dir + "/plain") << "a file, not a directory";
  const Result under_file = run("build " + dir + "/seq --out " + dir + "/plain/m.ot --quiet");
  EXPECT_EQ(under_file.code, 1);
  EXPECT_NE(under_file.out.find("plain/m.ot: cannot create directory"), std::string::npos) << under_file.out;
  for (const auto& e : fs::directory_iterator(dir)) EXPECT_EQ(e.path().string().find(".probe."), std::string::npos);
  // A depth frame cut short (a recorder killed mid-write), here the last one: found before
  // the run, not after the whole sequence has been processed.
  ASSERT_EQ(run("simulate --out " + dir + "/cut --frames 3 --noise none --quiet").code, 0);
  const std::string last = dir + "/cut/frame-000002.depth.png";
  fs::resize_file(last, fs::file_size(last) / 2);
  const Result cut = run("build " + dir + "/cut --out " + dir + "/cut.ot");  // not a terminal: a log line per frame
  EXPECT_EQ(cut.code, 1);
  EXPECT_NE(cut.out.find("frame-000002.depth.png: truncated PNG"), std::string::npos) << cut.out;
  EXPECT_EQ(cut.out.find("build 1/3"), std::string::npos) << cut.out;  // no frame was processed
  EXPECT_FALSE(fs::exists(dir + "/cut.ot"));
  // Not a map.
  std::ofstream(dir + "/junk.ot") << "junk";
  const Result junk = run("info " + dir + "/junk.ot");
  EXPECT_EQ(junk.code, 1);
  EXPECT_NE(junk.out.find("junk.ot: not an OctoMap .ot file"), std::string::npos) << junk.out;
  // A bad configuration file.
  std::ofstream(dir + "/c.yaml") << "mapping:\n  resolutoin_m: 0.05\n";
  const Result cfg = run("config --check " + dir + "/c.yaml");
  EXPECT_EQ(cfg.code, 1);
  EXPECT_NE(cfg.out.find("c.yaml: mapping.resolutoin_m: unknown key"), std::string::npos) << cfg.out;
  EXPECT_EQ(run("config --print-default").code, 0);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mobmap::cli_test
