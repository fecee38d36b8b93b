// Inputs as they come: 7-Scenes folders, gravity from the floor, real Kinect and lounge frames,
// depth units, camera files.
#include "cli_support.hpp"

namespace mobmap::cli_test {
namespace {

// Microsoft's 7-Scenes download keeps each sequence in a folder of its own (seq-01, ...)
// and has no camera-intrinsics.txt: the scene folder's error names its sequences, and
// --intrinsics stands in for the file.
TEST(Cli, SevenScenesSequenceFoldersAndIntrinsicsFromTheCommandLine) {
  const std::string dir = tempDir("7scenes");
  ASSERT_EQ(run("simulate --out " + dir + "/scene/seq-01 --frames 3 --noise none --quiet").code, 0);
  fs::remove(dir + "/scene/seq-01/camera-intrinsics.txt");
  const Result scene = run("build " + dir + "/scene --out " + dir + "/m.ot --quiet");
  EXPECT_EQ(scene.code, 1);
  EXPECT_NE(scene.out.find("but these sub-folders have them: seq-01 (3 frames); pass one sequence folder, such as " +
                           dir + "/scene/seq-01"),
            std::string::npos)
      << scene.out;
  const Result no_k = run("build " + dir + "/scene/seq-01 --out " + dir + "/m.ot --quiet");
  EXPECT_EQ(no_k.code, 1);
  EXPECT_NE(no_k.out.find("no camera-intrinsics.txt here or in the parent directory: give --intrinsics fx,fy,cx,cy"),
            std::string::npos)
      << no_k.out;
  EXPECT_FALSE(fs::exists(dir + "/m.ot"));
  // The simulator's camera, given on the command line: build, info and analyze use it.
  const Result b = run("build " + dir + "/scene/seq-01 --intrinsics 585,585,320,240 --out " + dir + "/m.ot --quiet");
  ASSERT_EQ(b.code, 0) << b.out;
  const Result info = run("info " + dir + "/m.ot");
  EXPECT_NE(info.out.find("depth camera: 640x480, fx 585.00 fy 585.00 cx 320.00 cy 240.00\n"), std::string::npos)
      << info.out;
  const Result a = run("analyze " + dir + "/scene/seq-01 --frame 2 --intrinsics 585,585,320,240 --json");
  ASSERT_EQ(a.code, 0) << a.out;
  EXPECT_TRUE(jsonLine(a.out).contains("ground_plane")) << a.out;
  // A wrong camera is caught, not mapped.
  const Result odd = run("build " + dir + "/scene/seq-01 --intrinsics 585,585,320 --out " + dir + "/n.ot --quiet");
  EXPECT_EQ(odd.code, 2);
  EXPECT_NE(odd.out.find("--intrinsics"), std::string::npos) << odd.out;
  fs::remove_all(dir);
}

// A posed sequence whose world frame has y down (as in 3DMatch) and no
// gravity-direction.txt: "down" comes from the floor the frames see, not from -z.
TEST(Cli, BuildFindsGravityFromTheFloorWhenTheSequenceDoesNotGiveIt) {
  const std::string dir = tempDir("gravity");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 6 --noise none --quiet").code, 0);
  fs::remove(dir + "/seq/gravity-direction.txt");
  // World' = Q world, Q a quarter turn about x: the simulator's z up becomes y down.
  for (const auto& entry : fs::directory_iterator(dir + "/seq")) {
    const std::string name = entry.path().filename().string();
    if (name.size() < 9 || name.compare(name.size() - 9, 9, ".pose.txt") != 0) continue;
    double t[16];
    {
      std::ifstream in(entry.path());
      for (double& v : t) ASSERT_TRUE(in >> v) << name;
    }
    std::ofstream out(entry.path());
    out.precision(17);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) {
        // Row r of Q T: Q's rows are (1 0 0), (0 0 -1), (0 1 0).
        const double v = r == 0 ? t[c] : r == 1 ? -t[8 + c] : t[4 + c];
        out << v << (c == 3 ? "\n" : " ");
      }
    }
    out << "0 0 0 1\n";
  }
  const Result b = run("build " + dir + "/seq --out " + dir + "/m.ot --quiet");
  ASSERT_EQ(b.code, 0) << b.out;
  EXPECT_NE(b.out.find("from the floor in 6 of 6 sampled frames"), std::string::npos) << b.out;
  std::ifstream meta_file(dir + "/m.json");
  const auto meta = nlohmann::json::parse(meta_file);
  const auto& g = meta["gravity_down_world"];
  EXPECT_GT(g[1].get<double>(), std::cos(0.5 * 3.14159265358979 / 180.0)) << g;  // within half a degree of +y
  EXPECT_NE(meta["gravity_source"].get<std::string>().find("the floor"), std::string::npos);
  // The floor 2 m ahead of the first camera, asked in the data's own world frame.
  const Result q = run("query " + dir + "/m.ot 2.0 -0.3 0.0 --input-frame world --snap 0.5 --json");
  ASSERT_EQ(q.code, 0) << q.out;
  const auto j = nlohmann::json::parse(q.out);
  EXPECT_EQ(j["state"], "surface") << q.out;
  EXPECT_NEAR(j["voxel_centre"][2].get<double>(), 0.0, 0.02) << q.out;
  EXPECT_GT(j["mobility"].get<double>(), 0.9) << q.out;
  // --gravity still wins, and says so.
  const Result given = run("build " + dir + "/seq --out " + dir + "/g.ot --gravity 0,1,0 --quiet");
  ASSERT_EQ(given.code, 0) << given.out;
  EXPECT_EQ(given.out.find("from the floor"), std::string::npos) << given.out;
  std::ifstream given_meta(dir + "/g.json");
  const nlohmann::json gm = nlohmann::json::parse(given_meta);
  // Checked against the floor, which agrees within a degree: kept exactly.
  EXPECT_EQ(gm["gravity_source"].get<std::string>().rfind("`gravity` (the floor in 6 of 6 sampled frames agrees within", 0), 0u)
      << gm.dump();
  EXPECT_EQ(gm["gravity_down_world"], nlohmann::json({0.0, 1.0, 0.0}));
  EXPECT_LT(gm["gravity_floor_angle_deg"].get<double>(), 1.0);
  fs::remove_all(dir);
}

// The real 3DMatch lounge (world frame y down, no gravity file): the carpet, the
// lowest broad surface of the map, must come out walkable.
// (height, mobility) of the scored voxels in an `export --pcd` file (map frame, z up).
std::vector<std::pair<double, double>> scoredVoxelHeights(const std::string& pcd) {
  std::ifstream in(pcd);
  std::string line;
  while (std::getline(in, line) && line.rfind("DATA", 0) != 0) {
  }
  std::vector<std::pair<double, double>> z_mobility;
  while (std::getline(in, line)) {  // x y z mobility variance count; mobility "nan" if unknown
    const char* p = line.c_str();
    char* end = nullptr;
    double v[4];
    for (double& value : v) {
      value = std::strtod(p, &end);
      p = end;
    }
    if (std::isfinite(v[3])) z_mobility.emplace_back(v[2], v[3]);
  }
  return z_mobility;
}

// Issue 7's check, through the command a user runs: five_people.pcd alone, no
// --gravity. The end wall is the frame's largest plane; the floor must be the ground.
TEST(Cli, FivePeopleAloneMapsAWalkableFloorAndUntraversablePeople) {
  const std::string data = std::string(MOBMAP_SHARED_DATA_DIR) + "/pcl-kinect/five_people.pcd";
  if (!fs::exists(data)) GTEST_SKIP() << "shared data not found at " << data;
  const std::string dir = tempDir("five");
  const Result b = run("build " + data + " --out " + dir + "/m.ot --quiet");
  ASSERT_EQ(b.code, 0) << b.out;
  ASSERT_EQ(run("export " + dir + "/m.ot --pcd " + dir + "/s.pcd").code, 0);
  const auto z_mobility = scoredVoxelHeights(dir + "/s.pcd");
  // The map frame has z up and the camera at the origin: the floor about 1.24 m below
  // (data README; 1.31 m as fitted at this range).
  int on_floor = 0, walkable = 0, upright = 0, blocked = 0;
  for (const auto& [zz, mm] : z_mobility) {
    if (std::abs(zz + 1.30) <= 0.06) {
      ++on_floor;
      walkable += mm >= 0.75;
    } else if (zz > -1.0 && zz < 0.3) {  // 0.3 to 1.6 m above the floor: people, walls, doors
      ++upright;
      blocked += mm < 0.5;
    }
  }
  ASSERT_GT(on_floor, 500) << b.out;
  EXPECT_GT(walkable, 0.75 * on_floor) << walkable << " of " << on_floor;
  ASSERT_GT(upright, 3000);
  EXPECT_GT(blocked, 0.95 * upright) << blocked << " of " << upright;
  // Reach from the camera: the floor it first sees 2-3 m ahead, most of it reachable
  // around the people.
  const Result reach = run("reach " + dir + "/m.ot --json");
  ASSERT_EQ(reach.code, 0) << reach.out;
  const auto rj = nlohmann::json::parse(reach.out);
  EXPECT_NEAR(rj["start"]["place"][2].get<double>(), -1.30, 0.06) << rj.dump();
  EXPECT_GT(rj["reachable"]["places"].get<double>(), 0.75 * rj["standable"]["places"].get<double>()) << rj.dump();
  fs::remove_all(dir);
}

TEST(Cli, LoungeFloorIsWalkableWithGravityFoundFromTheFloor) {
  const std::string data = std::string(MOBMAP_SHARED_DATA_DIR) + "/3dmatch-lounge/seq-01";
  if (!fs::exists(data)) GTEST_SKIP() << "shared data not found at " << data;
  const std::string dir = tempDir("lounge");
  fs::create_directories(dir);
  const Result b = run("build " + data + " --out " + dir + "/m.ot --quiet");
  ASSERT_EQ(b.code, 0) << b.out;
  EXPECT_NE(b.out.find("from the floor in"), std::string::npos) << b.out;
  ASSERT_EQ(run("export " + dir + "/m.ot --pcd " + dir + "/s.pcd").code, 0);
  const auto z_mobility = scoredVoxelHeights(dir + "/s.pcd");
  ASSERT_GT(z_mobility.size(), 1000u);
  // Heights in 4 cm bands; the floor is the lowest band holding a tenth of the voxels.
  std::map<int, int> bands;
  for (const auto& [zz, mm] : z_mobility) ++bands[static_cast<int>(std::floor(zz / 0.04))];
  int floor_band = 0;
  for (const auto& [band, n] : bands) {
    if (n * 10 >= static_cast<int>(z_mobility.size())) {
      floor_band = band;
      break;
    }
  }
  int on_floor = 0, walkable = 0;
  for (const auto& [zz, mm] : z_mobility) {
    if (std::abs(static_cast<int>(std::floor(zz / 0.04)) - floor_band) > 1) continue;
    ++on_floor;
    walkable += mm >= 0.75;
  }
  ASSERT_GT(on_floor, 500);
  EXPECT_GT(walkable, 0.75 * on_floor) << walkable << " of " << on_floor;
  fs::remove_all(dir);
}

// `info` lists every walkable level in height order, however many: on the corridor the
// floor, all four stair treads (17 cm apart) and the box tops, which the scene puts at
// known heights (a tread's voxels have their top faces up to one voxel above it).
TEST(Cli, InfoListsEveryStairTreadAsAWalkableLevel) {
  const std::string dir = tempDir("all-levels");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 240 --noise none --quiet").code, 0);
  ASSERT_EQ(run("build " + dir + "/seq --frames 0:239:4 --out " + dir + "/m.ot --quiet").code, 0);
  const Result info = run("info " + dir + "/m.ot --json");
  ASSERT_EQ(info.code, 0) << info.out;
  const auto levels = nlohmann::json::parse(info.out)["walkable_levels"];
  std::vector<double> z;
  for (const auto& l : levels) {
    z.push_back(l["z_m"].get<double>());
    EXPECT_GE(l["share"].get<double>(), 0.005) << levels.dump();
  }
  EXPECT_TRUE(std::is_sorted(z.begin(), z.end())) << levels.dump();
  for (const double tread : {0.0, 0.17, 0.34, 0.51, 0.6, 0.68}) {
    EXPECT_TRUE(std::any_of(z.begin(), z.end(), [&](double l) { return l >= tread - 0.005 && l <= tread + 0.025; }))
        << "no level at " << tread << ": " << levels.dump();
  }
  // The text lists the same levels, in the same order.
  const Result text = run("info " + dir + "/m.ot");
  std::string listed;
  for (std::size_t i = 0; i < levels.size(); ++i) {
    char item[64];
    std::snprintf(item, sizeof item, "%s z = %.2f m (%.0f %%)", i ? "," : "", z[i], 100 * levels[i]["share"].get<double>());
    listed += item;
  }
  EXPECT_NE(text.out.find("share of them):" + listed + "\n"), std::string::npos) << listed << "\n" << text.out;
  fs::remove_all(dir);
}

// `info`'s walkable levels on the real kitchen (frames 40-100, every third, which show
// most floor): the floor about 1.47 m and the table top about 0.77 m below the world
// origin along gravity (data README), the floor holding most walkable voxels.
TEST(Cli, InfoAndReachFindTheRedkitchenFloorAndTableTop) {
  const std::string data = std::string(MOBMAP_SHARED_DATA_DIR) + "/7scenes-redkitchen";
  if (!fs::exists(data)) GTEST_SKIP() << "shared data not found at " << data;
  const std::string dir = tempDir("levels");
  // The heights the data README gives are along its gravity-direction.txt, which lies 2
  // degrees from the floor: taken as given here (refined, the floor reads ~5 cm lower).
  const Result b = run("build " + data + " --frames 40:100:3 --out " + dir + "/m.ot --gravity-refine off --quiet");
  ASSERT_EQ(b.code, 0) << b.out;
  const Result info = run("info " + dir + "/m.ot --json");
  ASSERT_EQ(info.code, 0) << info.out;
  const auto levels = nlohmann::json::parse(info.out)["walkable_levels"];
  ASSERT_GE(levels.size(), 2u) << levels.dump();
  EXPECT_NEAR(levels[0]["z_m"].get<double>(), -1.47, 0.03) << levels.dump();
  bool table = false;
  for (const auto& l : levels) table = table || std::abs(l["z_m"].get<double>() + 0.77) < 0.03;
  EXPECT_TRUE(table) << levels.dump();
  const Result text = run("info " + dir + "/m.ot");
  EXPECT_NE(text.out.find("walkable levels (surface tops with mobility >= 0.75, one per column and run; share of them): z = -1.4"), std::string::npos)
      << text.out;
  // Reach from the first camera position starts on the floor, not on the table top
  // nearer the camera, and cannot climb the 0.7 m to the table, which can be stood on.
  const Result reach = run("reach " + dir + "/m.ot --json --png " + dir + "/reach.png");
  ASSERT_EQ(reach.code, 0) << reach.out;
  const auto rj = nlohmann::json::parse(reach.out);
  EXPECT_NEAR(rj["start"]["place"][2].get<double>(), -1.47, 0.05) << rj.dump();
  EXPECT_EQ(rj["start"]["rule"], "largest-level");
  EXPECT_GT(rj["reachable"]["area_m2"].get<double>(), 0.5) << rj.dump();
  bool table_unreachable = false;
  for (const auto& l : rj["unreachable_levels"]) table_unreachable = table_unreachable || std::abs(l["z_m"].get<double>() + 0.77) < 0.05;
  EXPECT_TRUE(table_unreachable) << rj.dump();
  EXPECT_TRUE(fs::exists(dir + "/reach.png"));
  // On real data too, the reachable surfaces never shrink as the limits loosen: a higher
  // step, a lower mobility (each --pcd row's flags, and the area).
  {
    std::map<std::array<double, 3>, PlaceFlags> before;
    double area = 0;
    for (const auto& [step, mob] : {std::pair{0.06, 0.8}, {0.1, 0.7}, {0.15, 0.5}, {0.2, 0.4}, {0.3, 0.3}}) {
      char opts[96];
      std::snprintf(opts, sizeof opts, " --max-step %.2f --min-mobility %.2f --json --pcd ", step, mob);
      const Result loose = run("reach " + dir + "/m.ot" + opts + dir + "/mono.pcd");
      ASSERT_EQ(loose.code, 0) << loose.out;
      const double a = nlohmann::json::parse(loose.out)["reachable"]["area_m2"].get<double>();
      EXPECT_GE(a, area) << step;
      area = a;
      const auto now = readPlaces(dir + "/mono.pcd");
      for (const auto& [p, f] : before) {
        if (f.reachable) {
          EXPECT_TRUE(now.at(p).reachable) << step << ": " << p[0] << " " << p[1] << " " << p[2];
        }
      }
      before = now;
    }
  }
  // Started on the table top (the nearest place below a point 0.25 m above its middle),
  // the floor is out of reach.
  const Result on_table = run("reach " + dir + "/m.ot --json --from -0.58 1.62 -0.5 --start-radius 0.3");
  ASSERT_EQ(on_table.code, 0) << on_table.out;
  const auto tj = nlohmann::json::parse(on_table.out);
  EXPECT_NEAR(tj["start"]["place"][2].get<double>(), -0.77, 0.05) << tj.dump();
  bool floor_unreachable = false;
  for (const auto& l : tj["unreachable_levels"]) floor_unreachable = floor_unreachable || std::abs(l["z_m"].get<double>() + 1.47) < 0.05;
  EXPECT_TRUE(floor_unreachable) << tj.dump();
  // query --reach answers the same for points and soles: 5 cm above each start place,
  // snapped down; soles centred there. The note (standard error) names the start.
  const auto& f = rj["start"]["place"];
  const auto& t = tj["start"]["place"];
  char lines[256];
  std::snprintf(lines, sizeof lines, "%.3f %.3f %.3f\n%.3f %.3f %.3f\n", f[0].get<double>(), f[1].get<double>(),
                f[2].get<double>() + 0.05, t[0].get<double>(), t[1].get<double>(), t[2].get<double>() + 0.05);
  std::ofstream(dir + "/points.txt") << lines;
  std::snprintf(lines, sizeof lines, "%.3f %.3f %.3f 0 0.1 0.06\n%.3f %.3f %.3f 0 0.1 0.06\n", f[0].get<double>(),
                f[1].get<double>(), f[2].get<double>(), t[0].get<double>(), t[1].get<double>(), t[2].get<double>());
  std::ofstream(dir + "/soles.txt") << lines;
  // The JSON answers among the lines (standard error is merged in by run()).
  const auto answers = [](const std::string& out) {
    std::vector<nlohmann::json> js;
    std::istringstream in(out);
    for (std::string l; std::getline(in, l);) {
      if (!l.empty() && l[0] == '{') js.push_back(nlohmann::json::parse(l));
    }
    return js;
  };
  for (const bool from_table : {false, true}) {
    const std::string start = from_table ? " --from -0.58 1.62 -0.5 --start-radius 0.3" : "";
    const Result points = run("query " + dir + "/m.ot --snap 0.2 --reach --json" + start + " < " + dir + "/points.txt");
    ASSERT_EQ(points.code, 0) << points.out;
    EXPECT_NE(points.out.find(from_table ? "map frame (nearest rule)" : "map frame (largest-level rule)"), std::string::npos)
        << points.out;
    const auto pj = answers(points.out);
    ASSERT_EQ(pj.size(), 2u) << points.out;
    EXPECT_NEAR(pj[0]["reach"]["place"][2].get<double>(), f[2].get<double>(), 0.021) << pj[0].dump();  // a voxel top vs a sole's plane
    EXPECT_NEAR(pj[1]["reach"]["place"][2].get<double>(), t[2].get<double>(), 0.021) << pj[1].dump();
    EXPECT_TRUE(pj[0]["reach"]["standable"].get<bool>() && pj[1]["reach"]["standable"].get<bool>());
    EXPECT_EQ(pj[0]["reach"]["reachable"].get<bool>(), !from_table) << pj[0].dump();
    EXPECT_EQ(pj[1]["reach"]["reachable"].get<bool>(), from_table) << pj[1].dump();
    const Result soles = run("query " + dir + "/m.ot --feet --reach --json" + start + " < " + dir + "/soles.txt");
    ASSERT_EQ(soles.code, 0) << soles.out;
    const auto sj = answers(soles.out);
    ASSERT_EQ(sj.size(), 2u) << soles.out;
    EXPECT_TRUE(sj[from_table ? 1 : 0]["reach"]["reachable"].get<bool>()) << sj[0].dump() << sj[1].dump();
    EXPECT_FALSE(sj[from_table ? 0 : 1]["reach"]["reachable"].get<bool>()) << sj[0].dump() << sj[1].dump();
  }
  fs::remove_all(dir);
}

// MAP.json is plain text beside the map and may be edited or damaged: the tools that
// read it back name the file and the entry, instead of a JSON type error or a silent
// non-rigid map frame.
// --depth-scale reads depth in the unit given; depth that reads implausibly (here
// millimetres taken for centimetres: ten times too far, all beyond the range) is named
// with the unit that fits, by analyze and by build, which writes no map. What the range
// took is reported and recorded.
TEST(Cli, DepthInAnotherUnitIsNamedWithTheScaleThatFits) {
  const std::string dir = tempDir("depth-unit");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 4 --noise none --quiet").code, 0);
  const std::string png = dir + "/seq/frame-000000.depth.png";
  const Result wrong = run("analyze " + png + " --depth-scale 100");
  EXPECT_EQ(wrong.code, 0) << wrong.out;
  EXPECT_NE(wrong.out.find("warning: " + png + ": the depth looks like it is in another unit: read at 100 units per metre"),
            std::string::npos)
      << wrong.out;
  EXPECT_NE(wrong.out.find("; --depth-scale 1000 (millimetres) puts the median at"), std::string::npos) << wrong.out;
  const Result right = run("analyze " + png + " --json");
  ASSERT_EQ(right.code, 0) << right.out;
  EXPECT_EQ(right.out.find("warning"), std::string::npos) << right.out;
  const auto j = nlohmann::json::parse(right.out.substr(right.out.find('{')));
  EXPECT_GT(j["range"]["valid_points"].get<long long>(), 100000);
  EXPECT_EQ(j["range"]["max_range_m"], 3.0);
  EXPECT_LE(j["range"]["beyond_max_range"].get<long long>(), j["range"]["valid_points"].get<long long>());
  EXPECT_EQ(run("analyze " + png + " --depth-scale 0").code, 2);
  const Result built_wrong = run("build " + dir + "/seq --out " + dir + "/w.ot --depth-scale 100 --quiet");
  EXPECT_EQ(built_wrong.code, 1) << built_wrong.out;
  EXPECT_NE(built_wrong.out.find("--depth-scale 1000 (millimetres) puts the median at"), std::string::npos) << built_wrong.out;
  EXPECT_FALSE(fs::exists(dir + "/w.ot"));
  const Result built = run("build " + dir + "/seq --out " + dir + "/m.ot --depth-scale 1000");
  ASSERT_EQ(built.code, 0) << built.out;
  EXPECT_NE(built.out.find("range: "), std::string::npos) << built.out;
  std::ifstream in(dir + "/m.json");
  const nlohmann::json meta = nlohmann::json::parse(in);
  EXPECT_EQ(meta["depth_units_per_m"], 1000.0);
  EXPECT_GT(meta["points_in_view"].get<long long>(), 4 * 100000);
  EXPECT_LT(meta["points_beyond_range"].get<long long>(), meta["points_in_view"].get<long long>());
  fs::remove_all(dir);
}

// --intrinsics takes a ROS or OpenCV camera file as well as the matrix text, with the
// same result; --fov stands in for an unknown calibration and excludes --intrinsics.
TEST(Cli, CameraFilesAndFieldOfViewAreTakenAsIntrinsics) {
  const std::string dir = tempDir("camera-files");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 1 --noise none --quiet").code, 0);
  const std::string png = dir + "/seq/frame-000000.depth.png";
  std::ofstream(dir + "/cam.yml") << "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n"
                                     "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
                                     "   data: [ 585., 0., 320., 0., 585., 240., 0., 0., 1. ]\n";
  const auto segments = [&](const std::string& options) {
    const Result r = run("analyze " + png + " --json " + options);
    EXPECT_EQ(r.code, 0) << r.out;
    return nlohmann::json::parse(r.out.substr(r.out.find('{')))["segments"];
  };
  const nlohmann::json from_text = segments("--intrinsics " + dir + "/seq/camera-intrinsics.txt");
  ASSERT_FALSE(from_text.empty());
  EXPECT_EQ(segments("--intrinsics " + dir + "/cam.yml"), from_text);
  // The simulator's Kinect: fx 585 at 640 pixels is a field of view of 2 atan(320 / 585).
  // --fov gives the camera fx = fy = 320 / tan(fov / 2) centred at (319.5, 239.5).
  const double fov = 2 * std::atan(320.0 / 585.0) * 180.0 / M_PI;
  const double f = 0.5 * 640 / std::tan(0.5 * fov * M_PI / 180.0);
  EXPECT_NEAR(f, 585.0, 1e-9);
  char fov_option[64], same[160];
  std::snprintf(fov_option, sizeof fov_option, "--fov %.17g", fov);
  std::snprintf(same, sizeof same, "--intrinsics %.17g,%.17g,319.5,239.5", f, f);
  EXPECT_EQ(segments(fov_option), segments(same));
  const Result both = run("analyze " + png + " --fov 60 --intrinsics " + dir + "/cam.yml");
  EXPECT_EQ(both.code, 2) << both.out;
  EXPECT_NE(both.out.find("excludes"), std::string::npos) << both.out;
  fs::remove_all(dir);
}

// A gravity file 4 degrees off the floor (as a real sequence's was): by default build
// refines it to the floor found within 10 degrees, so the floor lies level in the map;
// with --gravity-refine off it is kept and the floor climbs across the map. Both the
// given and the used gravity are recorded; --gravity floor takes the floor's outright.
TEST(Cli, AGravityFileOffTheFloorIsRefinedToIt) {
  const std::string dir = tempDir("gravity-refine");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 120 --noise none --quiet").code, 0);
  const double tilt = 4.0 * M_PI / 180.0;
  std::ofstream(dir + "/seq/gravity-direction.txt") << "0 " << std::sin(tilt) << " " << -std::cos(tilt) << "\n";
  const auto build = [&](const std::string& name, const std::string& options) {
    const Result r = run("build " + dir + "/seq --frames 0:119:3 --out " + dir + "/" + name + ".ot --quiet " + options);
    EXPECT_EQ(r.code, 0) << r.out;
    std::ifstream in(dir + "/" + name + ".json");
    return std::make_pair(r, nlohmann::json::parse(in));
  };
  const auto angleToTruth = [](const nlohmann::json& g) {
    const Eigen::Vector3d d(g[0].get<double>(), g[1].get<double>(), g[2].get<double>());
    return std::acos(std::clamp(d.normalized().dot(Eigen::Vector3d(0, 0, -1)), -1.0, 1.0)) * 180.0 / M_PI;
  };
  // The floor's share of the walkable voxels in its level (2 cm either side).
  const auto floorShare = [&](const std::string& name) {
    const Result info = run("info " + dir + "/" + name + ".ot --json");
    EXPECT_EQ(info.code, 0) << info.out;
    const nlohmann::json j = nlohmann::json::parse(info.out);
    double most = 0;
    for (const auto& l : j["walkable_levels"]) most = std::max(most, l["share"].get<double>());
    return most;
  };
  const auto [refined_run, refined] = build("refined", "");
  EXPECT_LT(angleToTruth(refined["gravity_down_world"]), 0.3) << refined.dump();
  EXPECT_NEAR(angleToTruth(refined["gravity_given_world"]), 4.0, 1e-4);
  EXPECT_NEAR(refined["gravity_floor_angle_deg"].get<double>(), 4.0, 0.3);
  EXPECT_NE(refined["gravity_source"].get<std::string>().find("gravity-direction.txt, refined to the floor"), std::string::npos)
      << refined.dump();
  EXPECT_NE(refined_run.out.find("refined to the floor"), std::string::npos) << refined_run.out;  // said even with --quiet
  EXPECT_NE(refined_run.out.find("gravity (down): (0.0000, 0.0698, -0.9976) given, ("), std::string::npos) << refined_run.out;
  const auto [kept_run, kept] = build("kept", "--gravity-refine off");
  EXPECT_NEAR(angleToTruth(kept["gravity_down_world"]), 4.0, 1e-4);
  EXPECT_NEAR(kept["gravity_floor_angle_deg"].get<double>(), 4.0, 0.3);
  EXPECT_GT(floorShare("refined"), 0.8);
  EXPECT_LT(floorShare("kept"), 0.5);
  const auto [floor_run, floor] = build("floor", "--gravity floor");
  EXPECT_LT(angleToTruth(floor["gravity_down_world"]), 0.3) << floor.dump();
  EXPECT_FALSE(floor.contains("gravity_given_world"));
  EXPECT_NE(floor["gravity_source"].get<std::string>().find("the floor in"), std::string::npos) << floor.dump();
  // --gravity X,Y,Z is refined the same way.
  const auto [given_run, given] = build("given", "--gravity 0," + std::to_string(std::sin(tilt)) + "," + std::to_string(-std::cos(tilt)));
  EXPECT_LT(angleToTruth(given["gravity_down_world"]), 0.3) << given.dump();
  EXPECT_NE(given["gravity_source"].get<std::string>().find("`gravity`, refined"), std::string::npos) << given.dump();
  EXPECT_EQ(run("build " + dir + "/seq --out " + dir + "/x.ot --gravity-refine maybe").code, 2);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mobmap::cli_test
