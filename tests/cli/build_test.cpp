// `mobmap build` and the commands that read its map, on simulated sequences and single frames.
#include "cli_support.hpp"

namespace mobmap::cli_test {
namespace {

// simulate -> build -> query/info/evaluate/export/overlay, as a user chains them.
TEST(Cli, BuildQueryInfoEvaluateExportOverlayOnASimulatedSequence) {
  const std::string dir = tempDir("chain");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 4 --noise none --quiet").code, 0);
  const std::string map = dir + "/m.ot";
  const Result b = run("build " + dir + "/seq --out " + map + " --quiet");
  ASSERT_EQ(b.code, 0) << b.out;
  for (const char* f : {"/m.ot", "/m.bt", "/m.octovis.ot", "/m.json"}) EXPECT_TRUE(fs::exists(dir + f)) << f;
  const Result again = run("build " + dir + "/seq --out " + map + " --quiet");
  EXPECT_EQ(again.code, 2);
  EXPECT_NE(again.out.find("--force"), std::string::npos);
  // The fused surface's PLY is not replaced without --force either, and nothing is written.
  const std::string ply = dir + "/keep.ply";
  { std::ofstream(ply) << "mine"; }
  const Result ply_again = run("build " + dir + "/seq --out " + dir + "/m2.ot --surface-ply " + ply + " --quiet");
  EXPECT_EQ(ply_again.code, 2) << ply_again.out;
  EXPECT_NE(ply_again.out.find(ply + " exists; --force overwrites it"), std::string::npos) << ply_again.out;
  EXPECT_FALSE(fs::exists(dir + "/m2.ot"));
  EXPECT_EQ(fileBytes(ply), "mine");
  // The floor 2 m ahead of the first camera position: walkable.
  const Result q = run("query " + map + " 2.0 0.0 0.3 --snap 0.5 --json");
  ASSERT_EQ(q.code, 0) << q.out;
  const auto j = nlohmann::json::parse(q.out);
  EXPECT_EQ(j["state"], "surface");
  EXPECT_NEAR(j["voxel_centre"][2].get<double>(), 0.0, 0.02);
  EXPECT_GT(j["mobility"].get<double>(), 0.9);
  const Result stdin_q = run("query " + map + " --json < /dev/null");
  EXPECT_EQ(stdin_q.code, 0);
  const Result foot = run("query " + map + " --foot 2.0 0 0 0 0.25 0.12 --json");
  ASSERT_EQ(foot.code, 0) << foot.out;
  EXPECT_GT(nlohmann::json::parse(foot.out)["min_mobility"].get<double>(), 0.9);
  // The floor under the sole: a level support plane at the floor's height.
  const auto plane = nlohmann::json::parse(foot.out)["support_plane"];
  ASSERT_TRUE(plane.is_object()) << foot.out;
  EXPECT_NEAR(plane["point"][2].get<double>(), 0.0, 0.021);
  EXPECT_GT(plane["normal"][2].get<double>(), 0.99);
  EXPECT_LT(plane["tilt_deg"].get<double>(), 1.0);
  // A planner's batch: soles on standard input, one answer line each, in order. A sole
  // 25 cm above the floor finds it only when --snap reaches down that far.
  std::ofstream(dir + "/feet.txt") << "2.0 0 0 0 0.25 0.12\n\n2.0 0 0.25 0.5 0.25 0.12\n";
  const Result feet = run("query " + map + " --feet --json < " + dir + "/feet.txt");
  ASSERT_EQ(feet.code, 0) << feet.out;
  std::istringstream lines(feet.out);
  std::string first, second;
  ASSERT_TRUE(std::getline(lines, first) && std::getline(lines, second)) << feet.out;
  EXPECT_GT(nlohmann::json::parse(first)["min_mobility"].get<double>(), 0.9);
  EXPECT_EQ(nlohmann::json::parse(second)["foot"][2].get<double>(), 0.25);
  EXPECT_EQ(nlohmann::json::parse(second)["known_fraction"].get<double>(), 0.0);
  const Result reach = run("query " + map + " --feet --snap 0.3 --json < " + dir + "/feet.txt");
  ASSERT_EQ(reach.code, 0) << reach.out;
  EXPECT_GT(nlohmann::json::parse(reach.out.substr(reach.out.find('\n') + 1))["known_fraction"].get<double>(), 0.9);
  // A planner keeps one process open and asks one sole at a time: every answer must
  // arrive before the next question is written (not held in a pipe buffer).
  {
    int to_child[2], from_child[2];
    ASSERT_EQ(::pipe(to_child), 0);
    ASSERT_EQ(::pipe(from_child), 0);
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      ::dup2(to_child[0], 0);
      ::dup2(from_child[1], 1);
      ::close(to_child[1]);
      ::close(from_child[0]);
      ::execl(MOBMAP_EXE, MOBMAP_EXE, "query", map.c_str(), "--feet", "--json", static_cast<char*>(nullptr));
      ::_exit(127);
    }
    ::close(to_child[0]);
    ::close(from_child[1]);
    struct Reap {  // a child left waiting (a failed assertion) is killed, not left behind
      pid_t pid;
      bool done = false;
      ~Reap() {
        if (!done) {
          ::kill(pid, SIGKILL);
          ::waitpid(pid, nullptr, 0);
        }
      }
    } reap{pid};
    for (int ask = 0; ask < 3; ++ask) {
      const std::string question = "2.0 0 0 " + std::to_string(ask) + " 0.25 0.12\n";
      ASSERT_EQ(::write(to_child[1], question.data(), question.size()), static_cast<ssize_t>(question.size()));
      std::string answer;
      while (answer.find('\n') == std::string::npos) {
        pollfd pfd{from_child[0], POLLIN, 0};
        ASSERT_EQ(::poll(&pfd, 1, 10000), 1) << "no answer to sole " << ask << " within 10 s";
        char buf[512];
        const ssize_t n = ::read(from_child[0], buf, sizeof buf);
        ASSERT_GT(n, 0);
        answer.append(buf, static_cast<std::size_t>(n));
      }
      EXPECT_EQ(nlohmann::json::parse(answer)["foot"][3].get<double>(), ask);
    }
    ::close(to_child[1]);
    int status = 0;
    ::waitpid(pid, &status, 0);
    reap.done = true;
    ::close(from_child[0]);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  }
  std::ofstream(dir + "/bad_feet.txt") << "2.0 0 0 0 0.25\n";
  const Result bad_feet = run("query " + map + " --feet < " + dir + "/bad_feet.txt");
  EXPECT_EQ(bad_feet.code, 2);
  EXPECT_NE(bad_feet.out.find("standard input line 1: expected 'x y z yaw length width'"), std::string::npos) << bad_feet.out;
  const Result info = run("info " + map);
  EXPECT_EQ(info.code, 0);
  EXPECT_NE(info.out.find("MobilityOcTree_v1, resolution 0.020 m"), std::string::npos) << info.out;
  // How it was built, in a few lines: not the metadata file with its camera path.
  EXPECT_NE(info.out.find("frames: 4 fused of 4 selected (frames 0..3)"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("from gravity-direction.txt"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("camera path: 4 positions"), std::string::npos) << info.out;
  EXPECT_EQ(info.out.find("trajectory_map"), std::string::npos) << info.out;
  const Result info_json = run("info " + map + " --json");
  ASSERT_EQ(info_json.code, 0) << info_json.out;
  const auto ij = nlohmann::json::parse(info_json.out);
  std::size_t scored = 0;
  for (const auto& n : ij["mobility_histogram"]) scored += n.get<std::size_t>();
  EXPECT_EQ(scored + ij["surface_leaves_without_mobility"].get<std::size_t>(), ij["surface_leaves"].get<std::size_t>());
  EXPECT_GT(ij["surface_leaves"].get<std::size_t>(), 100u);
  EXPECT_EQ(ij["metadata"]["trajectory_map"].size(), 4u);
  EXPECT_LT(ij["bounds_map"]["min"][2].get<double>(), ij["bounds_map"]["max"][2].get<double>());
  // The corridor's floor (z = 0) is the walkable level holding most walkable voxels.
  ASSERT_GE(ij["walkable_levels"].size(), 1u) << ij.dump();
  EXPECT_NEAR(ij["walkable_levels"][0]["z_m"].get<double>(), 0.0, 0.03);
  EXPECT_GT(ij["walkable_levels"][0]["share"].get<double>(), 0.5);
  // Reach: from the first camera position, the corridor floor (z = 0) in view.
  const Result walk = run("reach " + map + " --json");
  ASSERT_EQ(walk.code, 0) << walk.out;
  const auto rj = nlohmann::json::parse(walk.out);
  EXPECT_NEAR(rj["start"]["place"][2].get<double>(), 0.0, 0.03);
  EXPECT_GT(rj["reachable"]["area_m2"].get<double>(), 2.0) << rj.dump();
  EXPECT_LE(rj["reachable"]["places"].get<std::size_t>(), rj["standable"]["places"].get<std::size_t>());
  const Result reach_text = run("reach " + map + " --from 2.01 0.01 0 --png " + dir + "/reach.png");
  ASSERT_EQ(reach_text.code, 0) << reach_text.out;
  EXPECT_NE(reach_text.out.find("start: the surface at (2.0"), std::string::npos) << reach_text.out;
  EXPECT_NE(reach_text.out.find("reachable:"), std::string::npos) << reach_text.out;
  EXPECT_TRUE(fs::exists(dir + "/reach.png"));
  // --pcd: every place with its flags; as many reachable as the summary says, each
  // standable, on a mobility of at least --min-mobility (default 0.5).
  const auto reachedPlaces = [&](const std::string& options, double min_mobility) {
    const std::string pcd_path = dir + "/reach.pcd";
    EXPECT_EQ(run("reach " + map + " --pcd " + pcd_path + options).code, 0);
    std::size_t reachable = 0, poor = 0;
    for (const auto& [p, f] : readPlaces(pcd_path)) {
      if (!f.reachable) continue;
      ++reachable;
      EXPECT_TRUE(f.standable) << p[0] << " " << p[1] << " " << p[2];
      poor += !(f.mobility >= min_mobility);
    }
    // A sole may rest on up to --max-poor (10 %) of voxels under the limit (stray voxels).
    EXPECT_LE(poor, reachable / 10 + 1) << poor << " of " << reachable;
    return reachable;
  };
  const std::size_t reachable = reachedPlaces("", 0.5);
  EXPECT_EQ(reachable, rj["reachable"]["places"].get<std::size_t>());
  const std::size_t fussy = reachedPlaces(" --min-mobility 0.99", 0.99);
  EXPECT_GT(fussy, 0u);
  EXPECT_LT(fussy, reachable);
  // --octovis: stock OctoMap reads it; as many dark grey voxels as standable places out of
  // reach, and the start place in its mobility colour (yellow on the floor).
  ASSERT_EQ(run("reach " + map + " --octovis " + dir + "/reach.octovis.ot").code, 0);
  {
    std::unique_ptr<octomap::AbstractOcTree> abstract(octomap::AbstractOcTree::read(dir + "/reach.octovis.ot"));
    auto* colour = dynamic_cast<octomap::ColorOcTree*>(abstract.get());
    ASSERT_NE(colour, nullptr);
    std::size_t unreachable = 0;
    for (auto it = colour->begin_leafs(); it != colour->end_leafs(); ++it) {
      unreachable += it->getColor() == octomap::ColorOcTreeNode::Color(70, 70, 70);  // dark grey on viridis
    }
    EXPECT_EQ(unreachable, rj["unreachable"]["places"].get<std::size_t>());
    const auto& start = rj["start"]["place"];
    const auto* at = colour->search(start[0].get<double>(), start[1].get<double>(), start[2].get<double>() - 0.01);
    ASSERT_NE(at, nullptr);
    // Reachable floor: viridis yellow (mobility near 1).
    EXPECT_GT(at->getColor().r, 150);
    EXPECT_GT(at->getColor().g, 150);
    EXPECT_LT(at->getColor().b, 100);
  }
  const Result nowhere = run("reach " + map + " --from 50 50 0");
  EXPECT_EQ(nowhere.code, 1);
  EXPECT_NE(nowhere.out.find("no place for a 0.25 x 0.12 m sole to stand"), std::string::npos) << nowhere.out;
  const Result bad_step = run("reach " + map + " --max-step -0.1");
  EXPECT_EQ(bad_step.code, 2);
  EXPECT_NE(bad_step.out.find("error: --max-step is -0.1 ("), std::string::npos) << bad_step.out;
  EXPECT_EQ(run("reach " + map + " --max-z 0").code, 2);  // the cut is for --png
  // query --reach: the floor under a point from the same start; the robot's options need --reach.
  const Result on_floor = run("query " + map + " 2.01 0.01 0.3 --snap 0.5 --reach --from 2.01 0.01 0");
  ASSERT_EQ(on_floor.code, 0) << on_floor.out;
  EXPECT_NE(on_floor.out.find("reach: surface top at z = 0.020 m, reachable"), std::string::npos) << on_floor.out;
  const Result sole_text = run("query " + map + " --foot 2.01 0.01 0 0 0.25 0.12 --reach --from 2.01 0.01 0");
  ASSERT_EQ(sole_text.code, 0) << sole_text.out;
  EXPECT_NE(sole_text.out.find("reach: the robot can stand here and get here"), std::string::npos) << sole_text.out;
  const Result orphan = run("query " + map + " 2 0 0 --max-step 0.2");
  EXPECT_EQ(orphan.code, 2);
  EXPECT_NE(orphan.out.find("requires --reach"), std::string::npos) << orphan.out;
  EXPECT_EQ(run("query " + map + " 2 0 0 --reach --from 50 50 0").code, 1);  // no place to start on
  const Result ev = run("evaluate " + map + " --truth " + dir + "/seq/ground_truth.json --min-count 1 --json");
  ASSERT_EQ(ev.code, 0) << ev.out;
  EXPECT_GT(nlohmann::json::parse(ev.out)["surfaces"][0]["voxels"].get<int>(), 100);  // the floor
  EXPECT_EQ(run("export " + map + " --png " + dir + "/top.png --pcd " + dir + "/s.pcd").code, 0);
  EXPECT_TRUE(fs::exists(dir + "/top.png"));
  // A top view cut at a height: below the whole map is refused, saying where the map is.
  const double z_min = ij["bounds_map"]["min"][2].get<double>(), z_max = ij["bounds_map"]["max"][2].get<double>();
  EXPECT_EQ(run("export " + map + " --png " + dir + "/cut.png --max-z " + std::to_string((z_min + z_max) / 2)).code, 0);
  EXPECT_TRUE(fs::exists(dir + "/cut.png"));
  const Result below = run("export " + map + " --png " + dir + "/low.png --max-z " + std::to_string(z_min - 1));
  EXPECT_EQ(below.code, 2);
  EXPECT_NE(below.out.find("no surface voxel has its top at or below it (the lowest top is at z = "), std::string::npos)
      << below.out;
  EXPECT_FALSE(fs::exists(dir + "/low.png"));
  EXPECT_EQ(run("export " + map + " --pcd " + dir + "/s2.pcd --max-z 0").code, 2);  // the cut is for --png
  EXPECT_EQ(run("overlay " + map + " --frame " + dir + "/seq:2 --out " + dir + "/ov.png").code, 0);
  EXPECT_TRUE(fs::exists(dir + "/ov.png"));
  fs::remove_all(dir);
}

// An organized cloud of a wall 2 m ahead over a floor 0.4 m below, the wall the larger.
// `scale` multiplies the image size (160 x 120 pixels) and the focal length.
void writeWallOverFloorPcd(const std::string& pcd, int scale = 1) {
  std::ofstream out(pcd);
  const int w = 160 * scale, h = 120 * scale;
  const double f = 120.0 * scale, cx = 80.0 * scale, cy = 60.0 * scale;
  out << "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH " << w << "\nHEIGHT " << h
      << "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << w * h << "\nDATA ascii\n";
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const double dx = (u - cx) / f, dy = (v - cy) / f;
      const double t = dy > 0 ? std::min(2.0, 0.4 / dy) : 2.0;
      out << dx * t << " " << dy * t << " " << t << "\n";
    }
  }
}

// Without gravity the paper takes the largest plane as the ground: here the wall. The
// upright prior (on by default) takes the floor below the camera instead and says so;
// with it off, the paper's choice comes with a note that it may be a wall.
TEST(Cli, WithoutGravityTheFloorBeatsALargerWallUnlessThePriorIsOff) {
  const std::string dir = tempDir("wall");
  fs::create_directories(dir);
  const std::string pcd = dir + "/wall.pcd";
  writeWallOverFloorPcd(pcd);
  const auto groundDistance = [](const Result& r) {
    const auto j = nlohmann::json::parse(r.out.substr(r.out.find('{')));
    return j["ground_plane"].is_null() ? -1.0 : j["ground_plane"][3].get<double>();
  };
  const Result plain = run("analyze " + pcd + " --json");
  ASSERT_EQ(plain.code, 0) << plain.out;
  EXPECT_NEAR(groundDistance(plain), 0.4, 0.02) << plain.out;  // the floor, 0.4 m below
  EXPECT_NE(plain.out.find("\"ground_rule\":\"upright prior\""), std::string::npos) << plain.out;
  EXPECT_NE(plain.out.find("the largest plane found leans away from the image's up axis"), std::string::npos) << plain.out;
  EXPECT_EQ(plain.out.find("may be a wall"), std::string::npos) << plain.out;
  std::ofstream(dir + "/paper.yaml") << "perception:\n  ground_upright_prior_deg: 0\n";
  const Result paper = run("analyze " + pcd + " --config " + dir + "/paper.yaml --json");
  ASSERT_EQ(paper.code, 0) << paper.out;
  EXPECT_NEAR(groundDistance(paper), 2.0, 0.02) << paper.out;  // the wall, 2 m ahead
  EXPECT_NE(paper.out.find("\"ground_rule\":\"largest plane\""), std::string::npos) << paper.out;
  EXPECT_NE(paper.out.find("may be a wall"), std::string::npos) << paper.out;
  EXPECT_NE(paper.out.find("--gravity 0,1,0"), std::string::npos);
  const Result level = run("analyze " + pcd + " --gravity 0,1,0 --json");
  ASSERT_EQ(level.code, 0) << level.out;
  EXPECT_EQ(level.out.find("note:"), std::string::npos) << level.out;
  EXPECT_NEAR(groundDistance(level), 0.4, 0.02);
  EXPECT_NE(level.out.find("\"ground_rule\":\"gravity\""), std::string::npos) << level.out;
  // `build` takes "down" from the ground plane of a lone PCD: the floor's, with the note.
  const Result b = run("build " + pcd + " --out " + dir + "/m.ot --quiet");
  ASSERT_EQ(b.code, 0) << b.out;
  EXPECT_NE(b.out.find("the largest plane found leans away"), std::string::npos) << b.out;
  const Result q = run("query " + dir + "/m.ot 0 0.3 1.0 --input-frame world --snap 1.0 --json");  // over the floor 1 m ahead (its rows are 2 cm apart there, 5 cm at 1.6 m)
  ASSERT_EQ(q.code, 0) << q.out;
  const auto qj = nlohmann::json::parse(q.out);
  EXPECT_EQ(qj["state"], "surface") << q.out;
  EXPECT_GT(qj["mobility"].get<double>(), 0.75) << q.out;
  const Result bp = run("build " + pcd + " --out " + dir + "/p.ot --config " + dir + "/paper.yaml --quiet");
  ASSERT_EQ(bp.code, 0) << bp.out;
  EXPECT_NE(bp.out.find("may be a wall"), std::string::npos) << bp.out;
  const Result bg = run("build " + pcd + " --out " + dir + "/g.ot --gravity 0,1,0 --quiet");
  ASSERT_EQ(bg.code, 0) << bg.out;
  EXPECT_EQ(bg.out.find("note:"), std::string::npos) << bg.out;
  fs::remove_all(dir);
}

// --voxel: the same scene in 2 cm voxels holds about a quarter of the points, finds
// the same floor, and the map's metadata records the voxel size.
TEST(Cli, CoarserVoxelsReduceTheCloudAndKeepTheFloor) {
  const std::string dir = tempDir("voxel");
  fs::create_directories(dir);
  const std::string pcd = dir + "/wall.pcd";
  writeWallOverFloorPcd(pcd, 3);  // pixels 6 mm apart on the wall: every 1 cm voxel holds one
  const auto reduced = [](const Result& r) {
    const auto j = nlohmann::json::parse(r.out);
    for (const auto& s : j["stages"]) {
      if (s["stage"] == "reduction") return s["points_out"].get<double>();
    }
    return -1.0;
  };
  const Result fine = run("analyze " + pcd + " --gravity 0,1,0 --json");
  const Result coarse = run("analyze " + pcd + " --gravity 0,1,0 --voxel 0.02 --json");
  ASSERT_EQ(fine.code, 0) << fine.out;
  ASSERT_EQ(coarse.code, 0) << coarse.out;
  const double ratio = reduced(coarse) / reduced(fine);
  EXPECT_GT(ratio, 0.2) << coarse.out;
  EXPECT_LT(ratio, 0.4) << coarse.out;
  const auto j = nlohmann::json::parse(coarse.out);
  ASSERT_TRUE(j.contains("ground_plane")) << coarse.out;
  EXPECT_NEAR(j["ground_plane"][3].get<double>(), 0.4, 0.02);
  const Result bad = run("analyze " + pcd + " --voxel 2");
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.out.find("error: --voxel is 2 ("), std::string::npos) << bad.out;
  const Result b = run("build " + pcd + " --out " + dir + "/m.ot --gravity 0,1,0 --voxel 0.02 --quiet");
  ASSERT_EQ(b.code, 0) << b.out;
  EXPECT_NE(b.out.find("frames/s)"), std::string::npos) << b.out;  // the summary's rate
  std::ifstream meta_file(dir + "/m.json");
  const auto meta = nlohmann::json::parse(meta_file);
  EXPECT_DOUBLE_EQ(meta["perception"]["voxel_size_m"].get<double>(), 0.02);
  EXPECT_EQ(meta["perception"]["min_segment_points"].get<int>(), 13);  // rescaled from 50
  EXPECT_GT(meta["frames_per_second"].get<double>(), 0.0);
  // A lone frame mapped in its camera frame is no sequence to overlay: say what draws it.
  const Result ov = run("overlay " + dir + "/m.ot --frame 0 --out " + dir + "/ov.png");
  EXPECT_EQ(ov.code, 2) << ov.out;
  EXPECT_NE(ov.out.find("mobmap analyze FILE --overlay OUT.png"), std::string::npos) << ov.out;
  EXPECT_FALSE(fs::exists(dir + "/ov.png"));
  // A mistyped map name is said to be one, not taken for a map without its MAP.json.
  const Result typo = run("overlay " + dir + "/n.ot --frame 0 --out " + dir + "/ov.png");
  EXPECT_EQ(typo.code, 1) << typo.out;
  EXPECT_NE(typo.out.find(dir + "/n.ot: no such file"), std::string::npos) << typo.out;
  // A map without its MAP.json: N alone names no input.
  fs::copy_file(dir + "/m.ot", dir + "/bare.ot");
  const Result bare = run("overlay " + dir + "/bare.ot --frame 0 --out " + dir + "/ov.png");
  EXPECT_EQ(bare.code, 2) << bare.out;
  EXPECT_NE(bare.out.find("give INPUT:N (there is no MAP.json to name the input)"), std::string::npos) << bare.out;
  EXPECT_FALSE(fs::exists(dir + "/ov.png"));
  fs::remove_all(dir);
}

// --max-range: analyze keeps no point farther than it from the camera, and build no
// surface voxel farther than it (plus a voxel) from every camera position of the run;
// a range that leaves nothing to map is an error. --no-free-space: the box that moves
// across the corridor stays in the map where it was first seen.
TEST(Cli, MaxRangeBoundsWhatIsKeptAndNoFreeSpaceKeepsWhatMoved) {
  const std::string dir = tempDir("range");
  // 24 frames: the box 3.2 m ahead moves 1 m sideways in frames 4-8.
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 24 --noise none --quiet").code, 0);
  const auto farthest = [](const std::string& pcd_path, const std::vector<std::array<double, 3>>& from) {
    std::ifstream pcd(pcd_path);
    std::string line;
    while (std::getline(pcd, line) && line != "DATA ascii") {
    }
    double worst = 0;
    std::size_t n = 0;
    while (std::getline(pcd, line)) {
      std::istringstream in(line);
      std::array<double, 3> p{};
      in >> p[0] >> p[1] >> p[2];
      double nearest = 1e9;
      for (const auto& c : from) nearest = std::min(nearest, std::hypot(p[0] - c[0], p[1] - c[1], p[2] - c[2]));
      worst = std::max(worst, nearest);
      ++n;
    }
    return std::make_pair(worst, n);
  };
  const std::vector<std::array<double, 3>> camera{{0, 0, 0}};
  ASSERT_EQ(run("analyze " + dir + "/seq --frame 0 --segments " + dir + "/all.pcd").code, 0);
  const Result near = run("analyze " + dir + "/seq --frame 0 --max-range 2.0 --segments " + dir + "/near.pcd");
  ASSERT_EQ(near.code, 0) << near.out;
  const auto [all_far, all_n] = farthest(dir + "/all.pcd", camera);
  const auto [near_far, near_n] = farthest(dir + "/near.pcd", camera);
  EXPECT_GT(all_far, 2.5);  // the default 3 m sees the corridor farther on
  EXPECT_LE(near_far, 2.0);
  EXPECT_GT(near_n, 5000u);
  EXPECT_LT(near_n, all_n);
  const Result bad = run("analyze " + dir + "/seq --max-range 0.1");
  EXPECT_EQ(bad.code, 2) << bad.out;
  EXPECT_NE(bad.out.find("error: --max-range is 0.1 ("), std::string::npos) << bad.out;
  // build: voxel centres within 2 m of a camera position, give or take a map voxel's
  // half diagonal (0.02 * sqrt(3) / 2) and the perception voxel's centroid (0.01).
  const Result b = run("build " + dir + "/seq --frames 0:23:4 --out " + dir + "/m.ot --max-range 2.0 --quiet");
  ASSERT_EQ(b.code, 0) << b.out;
  std::ifstream meta_file(dir + "/m.json");
  const auto meta = nlohmann::json::parse(meta_file);
  EXPECT_DOUBLE_EQ(meta["perception"]["max_range_m"].get<double>(), 2.0);
  std::vector<std::array<double, 3>> path;
  for (const auto& p : meta["trajectory_map"]) path.push_back({p[0].get<double>(), p[1].get<double>(), p[2].get<double>()});
  ASSERT_EQ(path.size(), 6u);
  ASSERT_EQ(run("export " + dir + "/m.ot --pcd " + dir + "/voxels.pcd").code, 0);
  const auto [map_far, map_n] = farthest(dir + "/voxels.pcd", path);
  EXPECT_GT(map_n, 1000u);
  EXPECT_LE(map_far, 2.0 + 0.0174 + 0.01);
  EXPECT_GT(map_far, 1.9);
  // The camera is 1.35 m up and sees the floor from 1.6 m on: within 1.5 m there is
  // nothing, and an empty map is an error, not a file.
  const Result empty = run("build " + dir + "/seq --out " + dir + "/e.ot --max-range 1.5 --quiet");
  EXPECT_EQ(empty.code, 1) << empty.out;
  EXPECT_NE(empty.out.find(dir + "/seq: none of the 24 frames fused has a measured point between 0.3 and 1.5 m of the camera"),
            std::string::npos) << empty.out;
  EXPECT_NE(empty.out.find("no map written"), std::string::npos) << empty.out;
  for (const char* f : {"/e.ot", "/e.bt", "/e.octovis.ot", "/e.json"}) EXPECT_FALSE(fs::exists(dir + f)) << f;
  // Frames 2-12 see the box before, while and after it moves. Clearing what later
  // frames see through turns the box's first place free; --no-free-space keeps it as
  // surface: the same voxels, none free.
  const auto leaves = [&](const std::string& map) {
    const auto j = nlohmann::json::parse(run("info " + map + " --json").out);
    return std::array<std::size_t, 3>{j["leaves"].get<std::size_t>(), j["surface_leaves"].get<std::size_t>(),
                                      j["free_leaves"].get<std::size_t>()};
  };
  ASSERT_EQ(run("build " + dir + "/seq --frames 2:12:1 --out " + dir + "/cleared.ot --quiet").code, 0);
  ASSERT_EQ(run("build " + dir + "/seq --frames 2:12:1 --out " + dir + "/kept.ot --no-free-space --quiet").code, 0);
  const auto cleared = leaves(dir + "/cleared.ot"), kept = leaves(dir + "/kept.ot");
  EXPECT_GT(cleared[2], 100u);
  EXPECT_EQ(kept[2], 0u);
  EXPECT_EQ(kept[0], cleared[0]);
  EXPECT_GT(kept[1], cleared[1] + 100);
  for (const auto& [name, clears] : {std::pair<const char*, bool>{"/cleared.json", true}, {"/kept.json", false}}) {
    std::ifstream in(dir + name);
    EXPECT_EQ(nlohmann::json::parse(in)["mapping"]["clear_seen_through"].get<bool>(), clears) << name;
  }
  fs::remove_all(dir);
}

// A lone 16-bit depth PNG is mapped like a lone PCD: in its camera frame, "down" from
// the ground plane. The simulator's first frame looks at the floor from 1.35 m.
TEST(Cli, BuildMapsASingleDepthPngWithItsIntrinsics) {
  const std::string dir = tempDir("png");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 1 --noise none --quiet").code, 0);
  const std::string png = dir + "/seq/frame-000000.depth.png";
  // A PNG with no camera-intrinsics.txt beside it needs --intrinsics.
  fs::create_directories(dir + "/loose");
  fs::copy_file(png, dir + "/loose/depth_image_1.png");
  const Result bare = run("build " + dir + "/loose/depth_image_1.png --out " + dir + "/m.ot --quiet");
  EXPECT_EQ(bare.code, 2);
  EXPECT_NE(bare.out.find("--intrinsics (fx,fy,cx,cy or a camera file) is needed for a depth PNG"), std::string::npos) << bare.out;
  EXPECT_FALSE(fs::exists(dir + "/m.ot"));
  // One beside it is used, and said so; --intrinsics wins over it.
  const Result beside = run("analyze " + png + " --json");
  ASSERT_EQ(beside.code, 0) << beside.out;
  EXPECT_NE(beside.out.find("note: intrinsics from " + dir + "/seq/camera-intrinsics.txt, beside the PNG"), std::string::npos)
      << beside.out;
  const Result given = run("analyze " + png + " --intrinsics 585,585,320,240 --json");
  ASSERT_EQ(given.code, 0) << given.out;
  EXPECT_EQ(given.out.find("note: intrinsics"), std::string::npos) << given.out;
  const Result b = run("build " + png + " --out " + dir + "/m.ot");
  ASSERT_EQ(b.code, 0) << b.out;
  EXPECT_NE(b.out.find("1 of 1 frames fused (0 without a ground plane)"), std::string::npos) << b.out;
  // The progress line's rate counts from the run's start, as the summary's does: the
  // frame perceived before the frame loop (to find "down") is not left out of it.
  const std::size_t at_progress = b.out.find("build 1/1 frames (");
  const std::size_t at_summary = b.out.find("frames/s)");
  ASSERT_NE(at_progress, std::string::npos) << b.out;
  ASSERT_NE(at_summary, std::string::npos) << b.out;
  const double progress_fps = std::stod(b.out.substr(at_progress + 18));
  const double summary_fps = std::stod(b.out.substr(b.out.rfind('(', at_summary) + 1));
  EXPECT_GT(summary_fps, 0.0) << b.out;
  EXPECT_LT(progress_fps, 1.5 * summary_fps + 0.1) << b.out;
  // Map frame: origin at the camera, z up, the camera's forward axis along +y.
  const Result q = run("query " + dir + "/m.ot 0 1.8 -1.0 --snap 1.0 --json");
  ASSERT_EQ(q.code, 0) << q.out;
  const auto j = nlohmann::json::parse(q.out);
  EXPECT_EQ(j["state"], "surface") << q.out;
  EXPECT_NEAR(j["voxel_centre"][2].get<double>(), -1.35, 0.02) << q.out;
  EXPECT_GT(j["mobility"].get<double>(), 0.9) << q.out;
  // info says which camera model read the frame (the simulator's intrinsics file).
  std::ifstream k_file(dir + "/seq/camera-intrinsics.txt");
  double fx, skip, cx, fy, cy;
  ASSERT_TRUE(k_file >> fx >> skip >> cx >> skip >> fy >> cy);
  const Result info = run("info " + dir + "/m.ot");
  ASSERT_EQ(info.code, 0) << info.out;
  char camera[160];
  std::snprintf(camera, sizeof camera, "depth camera: 640x480, fx %.2f fy %.2f cx %.2f cy %.2f\n", fx, fy, cx, cy);
  EXPECT_NE(info.out.find(camera), std::string::npos) << info.out;
  EXPECT_EQ(info.out.find("poses:"), std::string::npos) << info.out;
  EXPECT_NE(b.out.find("note: intrinsics from " + dir + "/seq/camera-intrinsics.txt"), std::string::npos) << b.out;
  // A directory of depth PNGs that is not in the 7-Scenes layout: the error says what to do.
  const Result loose = run("build " + dir + "/loose --out " + dir + "/l.ot --quiet");
  EXPECT_EQ(loose.code, 1);
  EXPECT_NE(loose.out.find("for one depth image, pass the .png itself"), std::string::npos) << loose.out;
  fs::remove_all(dir);
}

}  // namespace

// `simulate --scene rough`: the same walk past rough fields, whose ground truth `evaluate`
// reads; the floor between them scores as floor, and every field gets voxels of its own.
TEST(Cli, RoughYardIsSimulatedAndEvaluatedFieldByField) {
  const std::string dir = tempDir("rough-yard");
  const Result sim = run("simulate --scene rough --out " + dir + "/seq --frames 90 --noise none --quiet");
  ASSERT_EQ(sim.code, 0) << sim.out;
  EXPECT_NE(sim.out.find("frames of the rough yard"), std::string::npos) << sim.out;
  const std::string map = dir + "/m.ot";
  ASSERT_EQ(run("build " + dir + "/seq --frames 0:89:3 --out " + map + " --quiet").code, 0);
  const Result ev = run("evaluate " + map + " --truth " + dir + "/seq/ground_truth.json --json");
  ASSERT_EQ(ev.code, 0) << ev.out;
  const auto j = nlohmann::json::parse(ev.out);
  std::map<std::string, nlohmann::json> rows;
  for (const auto& s : j["surfaces"]) rows[s["name"].get<std::string>()] = s;
  EXPECT_LT(rows.at("floor")["mean_abs_error"].get<double>(), 0.05) << ev.out;
  for (const char* field : {"pyramids", "ridges along the path", "ridges across the path"}) {
    EXPECT_GT(rows.at(field)["voxels"].get<int>(), 100) << field << ": " << ev.out;
    EXPECT_DOUBLE_EQ(rows.at(field)["expected_mobility"].get<double>(), 0.5) << field;
  }
  std::ifstream truth(dir + "/seq/ground_truth.json");
  const auto t = nlohmann::json::parse(truth);
  int fields = 0;
  for (const auto& s : t["surfaces"]) {
    if (s["kind"] != "rough") continue;
    ++fields;
    EXPECT_EQ(s["geometry"]["type"], "rough_field");
    EXPECT_FALSE(s["geometry"]["description"].get<std::string>().empty());
  }
  EXPECT_EQ(fields, 5);
  fs::remove_all(dir);
}
}  // namespace mobmap::cli_test
