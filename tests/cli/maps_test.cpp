// Maps over time: damaged metadata, --extend, plan, inputs never overwritten, one writer per map.
#include "cli_support.hpp"

namespace mobmap::cli_test {
namespace {

TEST(Cli, DamagedMapMetadataIsReportedByFileAndEntry) {
  const std::string dir = tempDir("meta");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 2 --noise none --quiet").code, 0);
  ASSERT_EQ(run("build " + dir + "/seq --out " + dir + "/m.ot --quiet").code, 0);
  std::ifstream in(dir + "/m.json");
  const nlohmann::json good = nlohmann::json::parse(in);
  const std::string ot = dir + "/m.ot", json = dir + "/m.json";
  const auto damage = [&](const std::function<void(nlohmann::json&)>& edit) {
    nlohmann::json m = good;
    edit(m);
    std::ofstream(json) << m.dump();
  };
  struct Case {
    std::function<void(nlohmann::json&)> edit;
    std::string message;
  };
  const std::vector<Case> cases = {
      {[](nlohmann::json& m) { m["frames"] = "many"; }, "\"frames\" must be a non-negative whole number"},
      {[](nlohmann::json& m) { m["frames"] = -3; }, "\"frames\" must be a non-negative whole number"},
      {[](nlohmann::json& m) { m["R_map_world"][2][2] = 5.0; }, "\"R_map_world\" is not a rotation"},
      {[](nlohmann::json& m) { m["R_map_world"][0] = {1, 0}; }, "\"R_map_world\" must be 3 rows of 3 finite numbers"},
      {[](nlohmann::json& m) { m["R_map_world"] = {{-1, 0, 0}, {0, 1, 0}, {0, 0, 1}}; }, "reflection"},
      {[](nlohmann::json& m) { m["trajectory_map"][1] = {0, 0, "a"}; }, "\"trajectory_map\" entry 1 must be [x, y, z]"},
      {[](nlohmann::json& m) { m["trajectory_map"][0] = {1e300, 0, 0}; }, "\"trajectory_map\" entry 0"},
      {[](nlohmann::json& m) { m["trajectory_map"] = 7; }, "\"trajectory_map\" must be a list"},
      {[](nlohmann::json& m) { m = nlohmann::json::array({1, 2}); }, "expected a JSON object"},
      {[](nlohmann::json& m) { m["gravity_down_world"] = {0, 0, 0}; }, "\"gravity_down_world\" must be [x, y, z]"},
      {[](nlohmann::json& m) { m["earlier_runs"] = 5; }, "\"earlier_runs\" must be a list"},
      {[](nlohmann::json& m) { m["earlier_runs"] = {{{"frames_in_run", -1}}}; },
       "\"earlier_runs\" entry 0: \"frames_in_run\" must be a non-negative whole number"},
  };
  for (const Case& c : cases) {
    damage(c.edit);
    for (const std::string& cmd : {"info " + ot, "query " + ot + " 0 0 0", "export " + ot + " --png " + dir + "/t.png"}) {
      const Result r = run(cmd);
      EXPECT_EQ(r.code, 1) << cmd << "\n" << r.out;
      EXPECT_NE(r.out.find("m.json: "), std::string::npos) << cmd << "\n" << r.out;
      EXPECT_NE(r.out.find(c.message), std::string::npos) << cmd << "\n" << r.out;
    }
  }
  // Rounded to 4 digits by hand: still a rotation within the tolerance of pose files.
  damage([](nlohmann::json& m) {
    for (auto& row : m["R_map_world"]) {
      for (auto& x : row) x = std::round(x.get<double>() * 1e4) / 1e4;
    }
  });
  EXPECT_EQ(run("query " + ot + " 0 0 0 --input-frame world").code, 0);
  // A frame count at the top of int: extending it would overflow to a negative count
  // (an unreadable map). Refused before the run, the map unchanged.
  damage([](nlohmann::json& m) { m["frames"] = 2147483647; });
  const std::string ot_bytes = fileBytes(ot), json_bytes = fileBytes(json);
  const Result full = run("build " + dir + "/seq --out " + ot + " --extend --quiet");
  EXPECT_EQ(full.code, 1) << full.out;
  EXPECT_NE(full.out.find(json + ": says the map holds 2147483647 frames; 2 more would pass the 2147483647 a map counts"),
            std::string::npos)
      << full.out;
  EXPECT_EQ(fileBytes(ot), ot_bytes);
  EXPECT_EQ(fileBytes(json), json_bytes);
  // Intrinsics recorded with fx 0: overlay names MAP.json, not an --intrinsics never given.
  damage([](nlohmann::json& m) { m["depth_intrinsics"]["fx"] = 0; });
  const Result k = run("overlay " + ot + " --frame 0 --out " + dir + "/o.png");
  EXPECT_EQ(k.code, 1) << k.out;
  EXPECT_NE(k.out.find(json + ": \"depth_intrinsics\" of the run that read"), std::string::npos) << k.out;
  EXPECT_NE(k.out.find("must have fx and fy > 0"), std::string::npos) << k.out;
  EXPECT_EQ(run("overlay " + ot + " --frame 0 --out " + dir + "/o.png --intrinsics 585,585,320,240").code, 0);
  fs::remove(json);  // no metadata: the map alone still answers
  const Result bare = run("info " + ot);
  EXPECT_EQ(bare.code, 0) << bare.out;
  EXPECT_NE(bare.out.find("no metadata"), std::string::npos) << bare.out;
  fs::remove_all(dir);
}

// `build --extend`: a map built in two runs is the map of one run over the same frames,
// byte for byte, and MAP.json keeps both runs. Failed extensions leave the map as it was.
TEST(Cli, ExtendingAMapGivesTheMapOfOneRunByteForByte) {
  const std::string dir = tempDir("extend");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 6 --quiet").code, 0);
  const Result whole = run("build " + dir + "/seq --out " + dir + "/one.ot --quiet");
  ASSERT_EQ(whole.code, 0) << whole.out;
  const std::string two = dir + "/two.ot";
  ASSERT_EQ(run("build " + dir + "/seq --out " + two + " --frames 0:2 --quiet").code, 0);
  const Result more = run("build " + dir + "/seq --out " + two + " --frames 3:5 --extend --quiet");
  ASSERT_EQ(more.code, 0) << more.out;
  EXPECT_NE(more.out.find("the map now holds 6 frames from 2 runs"), std::string::npos) << more.out;
  for (const char* suffix : {".ot", ".bt", ".octovis.ot"}) {
    const std::string a = fileBytes(dir + "/one" + suffix), b = fileBytes(dir + "/two" + suffix);
    EXPECT_FALSE(a.empty()) << suffix;
    EXPECT_TRUE(a == b) << suffix << " differs between one run and two";
  }
  const auto one_meta = nlohmann::json::parse(fileBytes(dir + "/one.json"));
  const auto meta = nlohmann::json::parse(fileBytes(dir + "/two.json"));
  EXPECT_EQ(meta["frames"], 6);
  EXPECT_EQ(meta["frames_in_run"], 3);
  EXPECT_EQ(meta["frame_numbers"], nlohmann::json({3, 5}));
  ASSERT_EQ(meta["earlier_runs"].size(), 1u);
  EXPECT_EQ(meta["earlier_runs"][0]["frames_in_run"], 3);
  EXPECT_EQ(meta["earlier_runs"][0]["frame_numbers"], nlohmann::json({0, 2}));
  EXPECT_FALSE(meta["earlier_runs"][0].contains("trajectory_map"));
  EXPECT_EQ(meta["trajectory_map"], one_meta["trajectory_map"]);
  EXPECT_EQ(meta["R_map_world"], one_meta["R_map_world"]);
  const Result info = run("info " + two);
  ASSERT_EQ(info.code, 0) << info.out;
  EXPECT_NE(info.out.find("built in 2 runs, 6 frames in the map"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("run 1: "), std::string::npos) << info.out;
  const Result top = run("export " + two + " --png " + dir + "/top.png");  // one path piece per run
  EXPECT_EQ(top.code, 0) << top.out;
  EXPECT_TRUE(fs::exists(dir + "/top.png"));

  // The same frames again: said, since each would then count twice.
  for (const char* suffix : {".ot", ".json"}) fs::copy_file(dir + "/two" + suffix, dir + "/again" + suffix);
  const Result again = run("build " + dir + "/seq --out " + dir + "/again.ot --frames 2:3 --extend --quiet");
  ASSERT_EQ(again.code, 0) << again.out;
  EXPECT_NE(again.out.find("note: run 1 of " + dir + "/again.ot already fused frames 0..2 of this input, which overlap the "
                           "frames selected now (2..3)"),
            std::string::npos) << again.out;
  EXPECT_NE(again.out.find("note: run 2 of " + dir + "/again.ot already fused frames 3..5"), std::string::npos) << again.out;
  EXPECT_EQ(more.out.find("note: run"), std::string::npos) << more.out;  // 3:5 after 0:2: no overlap

  const std::string before = fileBytes(two), before_json = fileBytes(dir + "/two.json");
  const Result missing = run("build " + dir + "/seq --out " + dir + "/none.ot --extend --quiet");
  EXPECT_EQ(missing.code, 2);
  EXPECT_NE(missing.out.find("none.ot does not exist"), std::string::npos) << missing.out;
  const Result both = run("build " + dir + "/seq --out " + two + " --extend --force --quiet");
  EXPECT_EQ(both.code, 2) << both.out;
  const Result res = run("build " + dir + "/seq --out " + two + " --extend --resolution 0.05 --quiet");
  EXPECT_EQ(res.code, 2);
  EXPECT_NE(res.out.find("keeps its own"), std::string::npos) << res.out;
  const Result tilted = run("build " + dir + "/seq --out " + two + " --extend --gravity 0,1,0 --quiet");
  EXPECT_EQ(tilted.code, 2);
  EXPECT_NE(tilted.out.find("world frame of that map"), std::string::npos) << tilted.out;
  // A frame that cannot be read stops the run before anything is written.
  fs::copy(dir + "/seq", dir + "/broken", fs::copy_options::recursive);
  std::ofstream(dir + "/broken/frame-000004.depth.png") << "not a png";
  const Result broken = run("build " + dir + "/broken --out " + two + " --extend --quiet");
  EXPECT_EQ(broken.code, 1);
  EXPECT_NE(broken.out.find("frame-000004.depth.png"), std::string::npos) << broken.out;
  EXPECT_TRUE(fileBytes(two) == before);
  EXPECT_TRUE(fileBytes(dir + "/two.json") == before_json);
  // Without its metadata the map frame is unknown: refused, naming the file.
  fs::remove(dir + "/one.json");
  const Result bare = run("build " + dir + "/seq --out " + dir + "/one.ot --extend --quiet");
  EXPECT_EQ(bare.code, 1);
  EXPECT_NE(bare.out.find("one.json: missing"), std::string::npos) << bare.out;
  fs::remove_all(dir);
}

// The robot options of `reach` and `query --reach` that change which places count
// (--clearance, --max-gap, --min-mobility), the picture size (--max-pixels), the
// evaluation tolerance and the demo's frame step, each checked against what it must do.
// `mobmap plan` as a planner's program calls it: the JSON it keeps, alternating feet
// within the robot's limits, the same plan given in the world frame, exit 3 with the
// reason when the goal cannot be stood on, and errors for bad input.
TEST(Cli, PlanGivesFootstepsOrTheReasonThereAreNone) {
  const std::string dir = tempDir("plan");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 24 --quiet").code, 0);  // Kinect noise, rounded edges
  const std::string map = dir + "/m.ot";
  ASSERT_EQ(run("build " + dir + "/seq --frames 0:23:2 --out " + map + " --quiet").code, 0);
  const std::string across = " --from 1.2 0 0 --to 2.6 0.3 0";
  const Result ok = run("plan " + map + across + " --json --png " + dir + "/plan.png");
  ASSERT_EQ(ok.code, 0) << ok.out;
  const auto j = nlohmann::json::parse(ok.out);
  ASSERT_TRUE(j["found"].get<bool>());
  EXPECT_FALSE(j.contains("reason"));
  for (const char* key : {"cost", "length_m", "expansions", "planning_time_s", "steps", "max_step_height_m"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  const auto& steps = j["footsteps"];
  ASSERT_GE(steps.size(), 4u);
  for (std::size_t i = 0; i < steps.size(); ++i) {
    for (const char* key : {"x", "y", "z", "yaw", "min_mobility", "tilt_deg"}) EXPECT_TRUE(steps[i][key].is_number()) << key;
    EXPECT_NEAR(steps[i]["z"].get<double>(), 0.02, 0.03) << i;  // the floor's voxel tops
    if (i == 0) continue;
    EXPECT_NE(steps[i]["foot"], steps[i - 1]["foot"]) << i;
    const double dx = steps[i]["x"].get<double>() - steps[i - 1]["x"].get<double>();
    const double dy = steps[i]["y"].get<double>() - steps[i - 1]["y"].get<double>();
    EXPECT_LE(std::hypot(dx, dy), 0.4 + 1e-9) << i;  // --max-stride
  }
  const auto& last = steps[steps.size() - 1], before_last = steps[steps.size() - 2];
  const double to_goal = std::min(std::hypot(last["x"].get<double>() - 2.6, last["y"].get<double>() - 0.3),
                                  std::hypot(before_last["x"].get<double>() - 2.6, before_last["y"].get<double>() - 0.3));
  EXPECT_LE(to_goal, 0.1 + 1e-9);  // --goal-tolerance
  EXPECT_TRUE(fs::exists(dir + "/plan.png"));
  // The corridor's world frame is its map frame (z up): the same footsteps.
  const Result world = run("plan " + map + across + " --json --input-frame world");
  ASSERT_EQ(world.code, 0) << world.out;
  const auto w = nlohmann::json::parse(world.out);
  EXPECT_EQ(w["frame"], "world");
  EXPECT_EQ(w["footsteps"].size(), steps.size());
  // A goal the robot cannot stand on (the 15-degree ramp, mobility 0.75, under 0.9).
  const Result poor = run("plan " + map + " --from 1.2 0 0 --to 3.0 -0.9 0.08 --min-mobility 0.9 --json");
  EXPECT_EQ(poor.code, 3) << poor.out;
  const auto pj = nlohmann::json::parse(poor.out);
  EXPECT_FALSE(pj["found"].get<bool>());
  EXPECT_NE(pj["reason"].get<std::string>().find("cannot be stood on"), std::string::npos) << poor.out;
  EXPECT_NE(pj["reason"].get<std::string>().find("--min-mobility 0.9 (mean "), std::string::npos) << poor.out;  // as given
  // The text gives each footstep what the standability rule checks: the mean mobility
  // under the sole and the share under --min-mobility, as the JSON does.
  const Result listed = run("plan " + map + across);
  ASSERT_EQ(listed.code, 0) << listed.out;
  EXPECT_NE(listed.out.find("the share under --min-mobility 0.5 (a sole stands on at most 10 % of it)"), std::string::npos)
      << listed.out;
  for (std::size_t i = 0; i < steps.size(); ++i) {
    const double poor_share = steps[i]["poor_fraction"].get<double>(), mean = steps[i]["mean_mobility"].get<double>();
    EXPECT_LE(poor_share, 0.1 + 1e-9) << i;
    EXPECT_GE(mean, steps[i]["min_mobility"].get<double>()) << i;
    char line[96];
    std::snprintf(line, sizeof line, "mobility %.2f mean, %3.0f %% poor", mean, 100 * poor_share);
    EXPECT_NE(listed.out.find(line), std::string::npos) << line << "\n" << listed.out;
  }
  EXPECT_EQ(listed.out.find("mobility >="), std::string::npos) << listed.out;
  const Result text = run("plan " + map + " --from 1.2 0 0 --to 3.0 -0.9 0.08 --min-mobility 0.9");
  EXPECT_EQ(text.code, 3);
  EXPECT_NE(text.out.find("no plan: the goal"), std::string::npos) << text.out;
  // Bad input: a clear error, exit 1 for the map's content, 2 for usage.
  const Result outside = run("plan " + map + " --from 1.2 0 0 --to 50 0 0");
  EXPECT_EQ(outside.code, 1);
  EXPECT_NE(outside.out.find(map + ": the goal (50.00, 0.00, 0.00) has no surface"), std::string::npos) << outside.out;
  for (const auto& [options, field] : {std::pair<std::string, std::string>{" --to nan 0 0", "--to"},
                                       {" --to 2 0 0 --sole -1 0.1", "error: --sole is -1 ("},
                                       {" --to 2 0 0 --max-step 0.01", "error: --max-step is 0.01 (must be at least two voxels"},
                                       {" --to 2 0 0 --weight 0.5", "error: --weight is 0.5 ("},
                                       {" --to 2 0 0 --png " + map, "a picture's name must end in .png, .svg or .pdf"}}) {
    const Result bad = run("plan " + map + " --from 1.2 0 0" + options);
    EXPECT_EQ(bad.code, 2) << options << ": " << bad.out;
    EXPECT_NE(bad.out.find(field), std::string::npos) << bad.out;
  }
  fs::remove_all(dir);
}

// A noise-free simulated corridor of `frames` frames in DIR/seq and its map DIR/m.ot.
std::string simulatedMap(const std::string& dir, int frames) {
  const Result sim = run("simulate --out " + dir + "/seq --frames " + std::to_string(frames) + " --noise none --quiet");
  EXPECT_EQ(sim.code, 0) << sim.out;
  const Result built = run("build " + dir + "/seq --out " + dir + "/m.ot --quiet");
  EXPECT_EQ(built.code, 0) << built.out;
  return dir + "/m.ot";
}

// `query --feet` and `query --feet --reach` give one known share for the same sole (the
// surface each sample rests on has a mobility), on floor, ramps, box and stair edges of
// the simulated corridor with Kinect noise; a point beyond what the map can hold is said
// to be outside it, not an unknown voxel.
TEST(Cli, QueryGivesOneKnownShareAndSaysWhenAPointIsOutsideTheMap) {
  const std::string dir = tempDir("known");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 48 --quiet").code, 0);
  const std::string map = dir + "/m.ot";
  ASSERT_EQ(run("build " + dir + "/seq --frames 0:47:2 --out " + map + " --quiet").code, 0);
  {
    std::ofstream soles(dir + "/soles.txt");
    for (double x = 0.6; x < 4.5; x += 0.17) {
      for (double y = -1.2; y <= 1.2; y += 0.23) soles << x << " " << y << " 0.1 " << x * 3 << " 0.25 0.12\n";
    }
  }
  const Result plain = run("query " + map + " --feet --json < " + dir + "/soles.txt");
  const Result reach = run("query " + map + " --feet --reach --json < " + dir + "/soles.txt");
  ASSERT_EQ(plain.code, 0) << plain.out;
  ASSERT_EQ(reach.code, 0) << reach.out;
  const auto lines = [](const std::string& out) {
    std::vector<nlohmann::json> js;
    std::istringstream in(out);
    for (std::string l; std::getline(in, l);) {
      if (!l.empty() && l[0] == '{') js.push_back(nlohmann::json::parse(l));
    }
    return js;
  };
  const auto a = lines(plain.out), b = lines(reach.out);
  ASSERT_EQ(a.size(), b.size());
  ASSERT_GT(a.size(), 200u);
  int partial = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const double known = a[i]["known_fraction"].get<double>();
    EXPECT_DOUBLE_EQ(b[i]["known_fraction"].get<double>(), known) << i;
    EXPECT_NEAR(b[i]["reach"]["support_fraction"].get<double>(), known, 1e-12) << a[i].dump() << "\n" << b[i].dump();
    partial += known > 0 && known < 1;
  }
  EXPECT_GT(partial, 10);  // edges and holes, where the shares could differ
  // Far outside: said so, in text and JSON; a point in the map is not.
  const Result far = run("query " + map + " 1e30 0 0");
  EXPECT_EQ(far.code, 0) << far.out;
  EXPECT_NE(far.out.find("outside the map: (1e+30, 0, 0) lies beyond the +-655.36 m a map of 0.02 m voxels spans"),
            std::string::npos)
      << far.out;
  const Result far_json = run("query " + map + " 0 1e30 0 --json");
  EXPECT_TRUE(nlohmann::json::parse(far_json.out)["outside_map"].get<bool>()) << far_json.out;
  const Result near = run("query " + map + " 1 0 0.01 --json");
  EXPECT_FALSE(nlohmann::json::parse(near.out)["outside_map"].get<bool>()) << near.out;
  const Result edge = run("query " + map + " 655 0 0 --json");  // in the tree's range, never seen
  EXPECT_FALSE(nlohmann::json::parse(edge.out)["outside_map"].get<bool>()) << edge.out;
  EXPECT_EQ(nlohmann::json::parse(edge.out)["state"], "unknown") << edge.out;
  fs::remove_all(dir);
}

// No writer replaces one of its own inputs: the map, its companion files, the frame it
// reads, the table it scores with, or another of its outputs. Files are compared as
// files (a symbolic link, a hard link or another spelling is the same file).
TEST(Cli, NoCommandWritesOverItsOwnInputs) {
  const std::string dir = tempDir("self-overwrite");
  const std::string map = simulatedMap(dir, 4);
  const std::string pcd = dir + "/s.pcd";
  ASSERT_EQ(run("export " + map + " --pcd " + pcd).code, 0);
  const std::string depth = dir + "/seq/frame-000000.depth.png";
  const std::string table = dir + "/t.csv";
  {
    std::ofstream(table) << "slope,roughness,mobility\n";
    std::ofstream(dir + "/t.png") << "slope,roughness,mobility\n";  // a table with a picture's name
    std::ofstream(dir + "/c.json") << "{}\n";
  }
  fs::create_symlink(fs::absolute(map), dir + "/link.ot");
  fs::create_hard_link(dir + "/m.json", dir + "/hard.json");
  const std::vector<std::string> guarded = {map,   dir + "/m.bt", dir + "/m.octovis.ot", dir + "/m.json",
                                            depth, pcd,           table,                 dir + "/c.json", dir + "/t.png"};
  std::map<std::string, std::string> before;
  for (const auto& f : guarded) before[f] = fileBytes(f);
  const std::string spelled = dir + "/seq/../m.ot";
  // A picture's option that names an input that is no picture: its extension alone refuses it.
  const std::string kNotAPicture = "a picture's name must end in .png, .svg or .pdf";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"export " + map + " --png " + map, kNotAPicture},
      {"export " + map + " --pcd " + spelled, "is the map"},
      {"export " + map + " --png " + dir + "/link.ot", kNotAPicture},
      {"export " + map + " --png " + dir + "/m.json", kNotAPicture},
      {"export " + map + " --png " + dir + "/hard.json", kNotAPicture},
      {"export " + map + " --png " + dir + "/a.png --pcd " + dir + "/seq/../a.png", "are the same file"},
      {"reach " + map + " --png " + dir + "/m.bt", kNotAPicture},
      {"reach " + map + " --pcd " + dir + "/m.octovis.ot", "is the map's octovis export"},
      {"reach " + map + " --octovis " + map, "is the map"},
      {"plan " + map + " --from 1.2 0 0 --to 2 0 0 --png " + dir + "/m.json", kNotAPicture},
      {"overlay " + map + " --frame 0 --out " + depth, "is the frame's file"},
      {"overlay " + map + " --frame 0 --out " + dir + "/m.bt", kNotAPicture},
      {"analyze " + depth + " --overlay " + depth, "is the input"},
      {"analyze " + dir + "/seq --frame 0 --overlay " + depth, "is the frame's file"},
      {"analyze " + pcd + " --segments " + pcd, "--segments " + pcd + " is the input"},
      {"analyze " + pcd + " --segments " + dir + "/x.pcd --overlay " + dir + "/x.pcd", kNotAPicture},
      {"analyze " + dir + "/seq --frame 0 --segments " + dir + "/x.png --overlay " + dir + "/x.png", "are the same file"},
      {"score --plot " + dir + "/t.png --table " + dir + "/t.png", "--plot " + dir + "/t.png is --table " + dir + "/t.png"},
      {"score --plot " + table + " --table " + table, kNotAPicture},
      {"build " + dir + "/seq --config " + dir + "/c.json --out " + dir + "/c.ot", "--out's metadata " + dir + "/c.json is --config"},
  };
  for (const auto& [command, expected] : cases) {
    const Result r = run(command);
    EXPECT_EQ(r.code, 2) << command << "\n" << r.out;
    EXPECT_NE(r.out.find(expected), std::string::npos) << command << "\n" << r.out;
    if (expected != kNotAPicture) {
      EXPECT_TRUE(r.out.find("choose another path") != std::string::npos ||
                  r.out.find("give each output its own path") != std::string::npos)
          << r.out;
    }
  }
  for (const auto& f : guarded) EXPECT_EQ(fileBytes(f), before[f]) << f << " changed";
  // Distinct outputs are written as before.
  ASSERT_EQ(run("export " + map + " --png " + dir + "/top.png --pcd " + dir + "/top.pcd").code, 0);
  EXPECT_TRUE(fs::exists(dir + "/top.png") && fs::exists(dir + "/top.pcd"));
  fs::remove_all(dir);
}

// Two writers of one map: the second fails at once, naming the process that holds the
// map's lock, and the map keeps the first one's frames. The test process holds the lock
// itself, as a running `build` would, so nothing depends on timing.
TEST(Cli, ASecondWriterOfAMapFailsAtOnceNamingTheHolder) {
  const std::string dir = tempDir("lock");
  const std::string map = simulatedMap(dir, 4);
  const std::string ot = fileBytes(map), json = fileBytes(dir + "/m.json");
  const std::string holder = "is being written by another process (pid " + std::to_string(::getpid()) + " holds " + dir + "/m.lock)";
  {
    const mobmap::mapping::MapLock held(map);
    for (const char* options : {" --extend", " --force"}) {
      const Result r = run("build " + dir + "/seq --out " + map + options + " --quiet");
      EXPECT_EQ(r.code, 1) << options << ": " << r.out;
      EXPECT_NE(r.out.find(map + ": " + holder), std::string::npos) << r.out;
    }
    // A fresh map at a path being written by another build: refused too (it used to
    // pass the "exists" check while the first build was still running).
    const mobmap::mapping::MapLock other(dir + "/new.ot");
    const Result fresh = run("build " + dir + "/seq --out " + dir + "/new.ot --quiet");
    EXPECT_EQ(fresh.code, 1) << fresh.out;
    EXPECT_FALSE(fs::exists(dir + "/new.ot"));
  }
  EXPECT_EQ(fileBytes(map), ot);
  EXPECT_EQ(fileBytes(dir + "/m.json"), json);
  const Result extended = run("build " + dir + "/seq --out " + map + " --extend --quiet");
  ASSERT_EQ(extended.code, 0) << extended.out;
  EXPECT_NE(extended.out.find("the map now holds 8 frames from 2 runs"), std::string::npos) << extended.out;
  EXPECT_FALSE(fs::exists(dir + "/m.lock"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mobmap::cli_test
