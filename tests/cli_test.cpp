// The `mobmap` executable as a user runs it: outputs, exit codes, error messages.
#include "mobmap/mapping/map_lock.hpp"

#include <Eigen/Core>

#include <nlohmann/json.hpp>
#include <octomap/ColorOcTree.h>

#include <gtest/gtest.h>

#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <memory>
#include <vector>
#include <sstream>
#include <string>

namespace {

namespace fs = std::filesystem;

struct Result {
  int code = -1;
  std::string out;  // stdout and stderr together
};

// Runs a shell command line with its standard error mixed into the output.
Result runShell(const std::string& command_line) {
  const std::string cmd = command_line + " 2>&1";
  Result r;
  FILE* pipe = ::popen(cmd.c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buf{};
  while (std::fgets(buf.data(), buf.size(), pipe)) r.out += buf.data();
  const int status = ::pclose(pipe);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

Result run(const std::string& args) { return runShell(std::string(MOBMAP_EXE) + " " + args); }

// run() with the size of any file the command writes limited to `kib` KiB (as `ulimit -f`
// sets) and SIGXFSZ ignored, so writes past it fail as on a full disk.
Result runWithFileSizeLimit(int kib, const std::string& args) {
  return runShell("trap '' XFSZ; ulimit -f " + std::to_string(2 * kib) + "; " + MOBMAP_EXE + " " + args);
}

std::string fileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

std::string tempDir(const std::string& name) {
  const auto p = fs::temp_directory_path() / ("mobmap-cli-" + std::to_string(::getpid()) + "-" + name);
  fs::remove_all(p);
  return p.string();
}

// The first line of `out` that is a JSON object (notes on standard error, which run() mixes in,
// may come first: query --reach, analyze).
nlohmann::json jsonLine(const std::string& out) {
  std::istringstream lines(out);
  std::string line;
  while (std::getline(lines, line))
    if (!line.empty() && line.front() == '{') return nlohmann::json::parse(line);
  ADD_FAILURE() << "no JSON line in: " << out;
  return nlohmann::json::object();
}

TEST(Cli, ScoreWithTheRuleTablePrintsTheTableValueAsJson) {
  const Result r = run("score --slope 15 --roughness 1.3 --model rule --json");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_DOUBLE_EQ(j["mobility"].get<double>(), 0.5);
  EXPECT_GT(j["variance"].get<double>(), 0.0);
}

TEST(Cli, ScoreWithTheGpIsCloseToTheTableAtACellCentre) {
  const Result r = run("score --slope 25 --roughness 1.1 --json");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NEAR(nlohmann::json::parse(r.out)["mobility"].get<double>(), 0.5, 0.1);
}

TEST(Cli, ScoreUsesAUserTable) {
  const std::string dir = tempDir("table");
  fs::create_directories(dir);
  std::ofstream(dir + "/q.csv") << "roughness\\slope,0,30\n1.0,0.9,0.4\n";
  const Result r = run("score --slope 35 --roughness 1.0 --model rule --table " + dir + "/q.csv --json");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_DOUBLE_EQ(nlohmann::json::parse(r.out)["mobility"].get<double>(), 0.4);
  std::ofstream(dir + "/bad.csv") << "roughness\\slope,0,30\n1.0,0.9\n";
  const Result bad = run("score --slope 35 --roughness 1.0 --table " + dir + "/bad.csv");
  EXPECT_EQ(bad.code, 1);
  EXPECT_NE(bad.out.find("bad.csv: line 2"), std::string::npos) << bad.out;
  fs::remove_all(dir);
}

TEST(Cli, ScoreErrorsAreClearWithUsageExitCodes) {
  const Result missing = run("score --slope 5 --roughness 1.0 --table /nonexistent/t.csv");
  EXPECT_EQ(missing.code, 1);
  EXPECT_NE(missing.out.find("/nonexistent/t.csv: no such file"), std::string::npos) << missing.out;
  const Result negative = run("score --slope -5 --roughness 1.0");
  EXPECT_EQ(negative.code, 2);
  EXPECT_NE(negative.out.find("--slope must be in [0, 180] degrees, got -5"), std::string::npos) << negative.out;
  const Result overhang = run("score --slope 500 --roughness 1.0");
  EXPECT_EQ(overhang.code, 2);
  EXPECT_NE(overhang.out.find("got 500"), std::string::npos) << overhang.out;
  // A surface is never smaller than its projection: A/A' < 1 cannot be measured.
  const Result smooth = run("score --slope 5 --roughness 0.5 --json");
  EXPECT_EQ(smooth.code, 2);
  EXPECT_NE(smooth.out.find("--roughness is the ratio A/A'"), std::string::npos) << smooth.out;
  EXPECT_NE(smooth.out.find("so >= 1; got 0.5"), std::string::npos) << smooth.out;
  EXPECT_EQ(run("score --slope 180 --roughness 1.0").code, 0);  // the bounds themselves are fine
  const Result nothing = run("score");
  EXPECT_EQ(nothing.code, 2);
  const Result unknown = run("frobnicate");
  EXPECT_EQ(unknown.code, 2);
}

TEST(Cli, ScorePlotWritesAPng) {
  const std::string dir = tempDir("plot");
  const Result r = run("score --plot " + dir + "/surface.png");
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream in(dir + "/surface.png", std::ios::binary);
  char sig[8] = {0};
  in.read(sig, 8);
  EXPECT_EQ(std::string(sig + 1, 3), "PNG");
  fs::remove_all(dir);
}

TEST(Cli, ScoreFitReportsHyperparameters) {
  const Result r = run("score --slope 10 --roughness 1.2 --fit --json");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_GT(j["fit"]["length_scale"].get<double>(), 0.0);
  EXPECT_TRUE(j["fit"]["log_marginal_likelihood"].is_number());
}

TEST(Cli, SimulateWritesTheSevenScenesLayoutAndRefusesToOverwrite) {
  const std::string dir = tempDir("sim");
  const Result r = run("simulate --scene corridor --out " + dir + " --frames 3 --noise none --seed 4 --quiet");
  ASSERT_EQ(r.code, 0) << r.out;
  for (const char* f : {"camera-intrinsics.txt", "gravity-direction.txt", "ground_truth.json",
                        "frame-000002.depth.png", "frame-000002.color.png", "frame-000002.labels.png",
                        "frame-000002.pose.txt"}) {
    EXPECT_TRUE(fs::exists(fs::path(dir) / f)) << f;
  }
  const Result again = run("simulate --out " + dir + " --frames 3 --quiet");
  EXPECT_EQ(again.code, 2);
  EXPECT_NE(again.out.find("--force"), std::string::npos);
  EXPECT_EQ(run("simulate --out " + dir + " --frames 3 --quiet --force").code, 0);
  const Result bad = run("simulate --out " + dir + " --noise loud");
  EXPECT_EQ(bad.code, 2);
  fs::remove_all(dir);
}

TEST(Cli, HelpListsTheSubcommands) {
  const Result r = run("--help");
  EXPECT_EQ(r.code, 0);
  for (const char* c : {"simulate", "score", "demo", "analyze", "build", "query", "info", "evaluate", "export", "overlay", "config"}) {
    EXPECT_NE(r.out.find(c), std::string::npos) << c;
  }
}

// The places `reach --pcd` writes (x y z mobility standable reachable, ASCII), keyed by
// their position. Every row has the six fields, the rows are as many as the header
// declares, and no two share a position.
struct PlaceFlags {
  double mobility = 0;
  bool standable = false, reachable = false;
};
std::map<std::array<double, 3>, PlaceFlags> readPlaces(const std::string& pcd_path) {
  std::ifstream pcd(pcd_path);
  std::string line;
  std::size_t rows = 0, declared = 0;
  while (std::getline(pcd, line) && line != "DATA ascii") {
    if (line.rfind("POINTS ", 0) == 0) declared = std::stoul(line.substr(7));
  }
  std::map<std::array<double, 3>, PlaceFlags> out;
  while (std::getline(pcd, line)) {
    std::istringstream in(line);
    std::vector<std::string> f{std::istream_iterator<std::string>(in), std::istream_iterator<std::string>()};
    EXPECT_EQ(f.size(), 6u) << line;
    if (f.size() != 6u) break;
    ++rows;
    // std::stod reads the "nan" of an unknown mobility, which >> would not.
    out[{std::stod(f[0]), std::stod(f[1]), std::stod(f[2])}] = {std::stod(f[3]), std::stoi(f[4]) == 1, std::stoi(f[5]) == 1};
  }
  EXPECT_EQ(rows, declared);
  EXPECT_EQ(out.size(), rows);
  return out;
}

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
  // --octovis: stock OctoMap reads it; as many purple voxels as standable places out of
  // reach, and the start place in its mobility colour (green on the floor).
  ASSERT_EQ(run("reach " + map + " --octovis " + dir + "/reach.octovis.ot").code, 0);
  {
    std::unique_ptr<octomap::AbstractOcTree> abstract(octomap::AbstractOcTree::read(dir + "/reach.octovis.ot"));
    auto* colour = dynamic_cast<octomap::ColorOcTree*>(abstract.get());
    ASSERT_NE(colour, nullptr);
    std::size_t purple = 0;
    for (auto it = colour->begin_leafs(); it != colour->end_leafs(); ++it) {
      purple += it->getColor() == octomap::ColorOcTreeNode::Color(150, 70, 210);
    }
    EXPECT_EQ(purple, rj["unreachable"]["places"].get<std::size_t>());
    const auto& start = rj["start"]["place"];
    const auto* at = colour->search(start[0].get<double>(), start[1].get<double>(), start[2].get<double>() - 0.01);
    ASSERT_NE(at, nullptr);
    EXPECT_GT(at->getColor().g, 150);
    EXPECT_EQ(at->getColor().b, 0);
  }
  const Result nowhere = run("reach " + map + " --from 50 50 0");
  EXPECT_EQ(nowhere.code, 1);
  EXPECT_NE(nowhere.out.find("no place for a 0.25 x 0.12 m sole to stand"), std::string::npos) << nowhere.out;
  const Result bad_step = run("reach " + map + " --max-step -0.1");
  EXPECT_EQ(bad_step.code, 2);
  EXPECT_NE(bad_step.out.find("max_step_m"), std::string::npos) << bad_step.out;
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
  EXPECT_NE(bad.out.find("voxel_size_m is 2"), std::string::npos) << bad.out;
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
  EXPECT_NE(bad.out.find("max_range_m"), std::string::npos) << bad.out;
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
  EXPECT_NE(bare.out.find("a depth PNG needs --intrinsics"), std::string::npos) << bare.out;
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
  EXPECT_NE(no_k.out.find("no camera-intrinsics.txt here or in the parent directory: pass --intrinsics fx,fy,cx,cy"),
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
  EXPECT_EQ(gm["gravity_source"].get<std::string>().rfind("--gravity (the floor in 6 of 6 sampled frames agrees within", 0), 0u)
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
  const Result text = run("info " + dir + "/m.ot");
  for (const char* tread : {"z = 0.18 m", "z = 0.35 m", "z = 0.51 m", "z = 0.69 m"}) {
    EXPECT_NE(text.out.find(tread), std::string::npos) << text.out;
  }
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
  EXPECT_NE(text.out.find("walkable levels (top faces of voxels >= 0.75, share of them): z = -1.4"), std::string::npos)
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
  EXPECT_NE(given["gravity_source"].get<std::string>().find("--gravity, refined"), std::string::npos) << given.dump();
  EXPECT_EQ(run("build " + dir + "/seq --out " + dir + "/x.ot --gravity-refine maybe").code, 2);
  fs::remove_all(dir);
}

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

// Width and height of a PNG, from its IHDR chunk (bytes 16-23, big-endian).
std::pair<int, int> pngSize(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  unsigned char b[24] = {};
  in.read(reinterpret_cast<char*>(b), sizeof b);
  if (!in) return {0, 0};
  const auto be = [&](int i) { return (b[i] << 24) | (b[i + 1] << 16) | (b[i + 2] << 8) | b[i + 3]; };
  return {be(16), be(20)};
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
  EXPECT_NE(pj["reason"].get<std::string>().find("--min-mobility 0.90"), std::string::npos) << poor.out;
  const Result text = run("plan " + map + " --from 1.2 0 0 --to 3.0 -0.9 0.08 --min-mobility 0.9");
  EXPECT_EQ(text.code, 3);
  EXPECT_NE(text.out.find("no plan: the goal"), std::string::npos) << text.out;
  // Bad input: a clear error, exit 1 for the map's content, 2 for usage.
  const Result outside = run("plan " + map + " --from 1.2 0 0 --to 50 0 0");
  EXPECT_EQ(outside.code, 1);
  EXPECT_NE(outside.out.find(map + ": the goal (50.00, 0.00, 0.00) has no surface"), std::string::npos) << outside.out;
  for (const auto& [options, field] : {std::pair<std::string, std::string>{" --to nan 0 0", "--to"},
                                       {" --to 2 0 0 --sole -1 0.1", "sole_length_m"},
                                       {" --to 2 0 0 --max-step 0.01", "max_step_m"},
                                       {" --to 2 0 0 --weight 0.5", "heuristic_weight"},
                                       {" --to 2 0 0 --png " + map, "is the map " + map}}) {
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
    std::ofstream(dir + "/c.json") << "{}\n";
  }
  fs::create_symlink(fs::absolute(map), dir + "/link.ot");
  fs::create_hard_link(dir + "/m.json", dir + "/hard.json");
  const std::vector<std::string> guarded = {map,   dir + "/m.bt", dir + "/m.octovis.ot", dir + "/m.json",
                                            depth, pcd,           table,                 dir + "/c.json"};
  std::map<std::string, std::string> before;
  for (const auto& f : guarded) before[f] = fileBytes(f);
  const std::string spelled = dir + "/seq/../m.ot";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"export " + map + " --png " + map, "--png " + map + " is the map " + map},
      {"export " + map + " --pcd " + spelled, "is the map"},
      {"export " + map + " --png " + dir + "/link.ot", "is the map"},
      {"export " + map + " --png " + dir + "/m.json", "is the map's metadata"},
      {"export " + map + " --png " + dir + "/hard.json", "is the map's metadata"},
      {"export " + map + " --png " + dir + "/a.png --pcd " + dir + "/seq/../a.png", "are the same file"},
      {"reach " + map + " --png " + dir + "/m.bt", "is the map's occupancy export"},
      {"reach " + map + " --pcd " + dir + "/m.octovis.ot", "is the map's octovis export"},
      {"reach " + map + " --octovis " + map, "is the map"},
      {"plan " + map + " --from 1.2 0 0 --to 2 0 0 --png " + dir + "/m.json", "is the map's metadata"},
      {"overlay " + map + " --frame 0 --out " + depth, "is the frame's file"},
      {"overlay " + map + " --frame 0 --out " + dir + "/m.bt", "is the map's occupancy export"},
      {"analyze " + depth + " --overlay " + depth, "is the input"},
      {"analyze " + dir + "/seq --frame 0 --overlay " + depth, "is the frame's file"},
      {"analyze " + pcd + " --segments " + pcd, "--segments " + pcd + " is the input"},
      {"analyze " + pcd + " --segments " + dir + "/x.pcd --overlay " + dir + "/x.pcd", "are the same file"},
      {"score --plot " + table + " --table " + table, "--plot " + table + " is --table " + table},
      {"build " + dir + "/seq --config " + dir + "/c.json --out " + dir + "/c.ot", "--out's metadata " + dir + "/c.json is --config"},
  };
  for (const auto& [command, expected] : cases) {
    const Result r = run(command);
    EXPECT_EQ(r.code, 2) << command << "\n" << r.out;
    EXPECT_NE(r.out.find(expected), std::string::npos) << command << "\n" << r.out;
    EXPECT_TRUE(r.out.find("choose another path") != std::string::npos ||
                r.out.find("give each output its own path") != std::string::npos)
        << r.out;
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
    for (const std::string& options : {" --extend", " --force"}) {
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
  for (const auto& [options, field] : {std::pair<const char*, const char*>{" --clearance -1", "clearance_m"},
                                       {" --max-gap 5", "max_gap_m"},
                                       {" --min-mobility 1.5", "min_mobility"}}) {
    for (const std::string& cmd : {"reach " + map, "query " + map + " 1 0 0 --reach"}) {
      const Result bad = run(cmd + options);
      EXPECT_EQ(bad.code, 2) << cmd << options << ": " << bad.out;
      EXPECT_NE(bad.out.find(field), std::string::npos) << bad.out;
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

// A disk that fills while the map is saved: build exits 1 naming the file, and the map
// files are all what they were (none, for a new map; the earlier run's, for --extend),
// with no temporary left beside them. An --extend run's new .ot beside the old .json
// would describe frames the metadata does not list.
TEST(Cli, AMapThatCannotBeSavedInFullLeavesTheFilesOnDiskAsTheyWere) {
  const std::string dir = tempDir("full");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 3 --noise none --quiet").code, 0);
  const std::string map = dir + "/maps/m.ot";
  const auto listing = [&] {
    std::map<std::string, std::string> files;  // name -> bytes
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir + "/maps", ec)) {
      std::string& bytes = files[e.path().filename().string()];
      if (!e.is_regular_file()) continue;
      std::ifstream in(e.path(), std::ios::binary);
      bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    return files;
  };
  const Result fresh = runWithFileSizeLimit(32, "build " + dir + "/seq --frames 0:0 --out " + map + " --quiet");
  EXPECT_EQ(fresh.code, 1) << fresh.out;
  EXPECT_NE(fresh.out.find("m.ot: write failed (disk full?); no file of the set was changed"), std::string::npos) << fresh.out;
  EXPECT_TRUE(listing().empty());
  ASSERT_EQ(run("build " + dir + "/seq --frames 0:0 --out " + map + " --quiet").code, 0);
  const auto before = listing();
  ASSERT_EQ(before.size(), 4u);
  ASSERT_GT(before.at("m.ot").size(), 32u * 1024);
  const Result extend = runWithFileSizeLimit(32, "build " + dir + "/seq --frames 1:2 --extend --out " + map + " --quiet");
  EXPECT_EQ(extend.code, 1) << extend.out;
  EXPECT_NE(extend.out.find("write failed (disk full?)"), std::string::npos) << extend.out;
  EXPECT_TRUE(listing() == before);  // byte for byte, and nothing else in the folder
  // A file of the set that could not be replaced (a directory in its place) is found
  // before the run, not after MAP.ot and MAP.bt have been replaced.
  fs::remove(dir + "/maps/m.octovis.ot");
  fs::create_directory(dir + "/maps/m.octovis.ot");
  const Result blocked = run("build " + dir + "/seq --frames 1:2 --extend --out " + map + " --quiet");
  EXPECT_EQ(blocked.code, 1) << blocked.out;
  EXPECT_NE(blocked.out.find("m.octovis.ot: is a directory"), std::string::npos) << blocked.out;
  EXPECT_EQ(listing().at("m.ot"), before.at("m.ot"));
  EXPECT_EQ(listing().at("m.bt"), before.at("m.bt"));
  fs::remove(dir + "/maps/m.octovis.ot");
  // Without the limit the same run goes through.
  ASSERT_EQ(run("build " + dir + "/seq --frames 1:2 --extend --out " + map + " --quiet").code, 0);
  EXPECT_GT(listing().at("m.ot").size(), before.at("m.ot").size());
  fs::remove_all(dir);
}

// A frame whose files cannot be read stops the run, before it starts when a cheap check
// finds it (a pose that is not rigid) and when it is decoded otherwise (a depth image
// with a bad checksum), naming the file and the way round it. With --skip-bad-frames the
// run leaves such frames out, says which, and gives the map of the frames left: byte
// for byte the map of the same sequence without those frames.
// A depth frame declaring 16384 x 16384 pixels (a valid header, no pixels behind it) in
// the middle of a sequence: named as too large, not decoded, and left out with
// --skip-bad-frames.
TEST(Cli, AnOversizedFrameIsNamedAndSkippable) {
  const std::string dir = tempDir("oversized");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 4 --noise none --quiet").code, 0);
  const std::string png = dir + "/seq/frame-000001.depth.png";
  std::string ihdr = "IHDR";
  for (std::uint32_t v : {16384u, 16384u}) {
    for (int shift : {24, 16, 8, 0}) ihdr.push_back(static_cast<char>(v >> shift));
  }
  ihdr += std::string{16, 0, 0, 0, 0};
  std::uint32_t crc = 0xFFFFFFFFu;
  for (unsigned char c : ihdr) {
    crc ^= c;
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  crc ^= 0xFFFFFFFFu;
  std::string bytes = std::string("\x89PNG\r\n\x1a\n", 8) + std::string{0, 0, 0, 13} + ihdr;
  for (int shift : {24, 16, 8, 0}) bytes.push_back(static_cast<char>(crc >> shift));
  bytes += std::string{0, 0, 0, 0} + "IDAT" + std::string{'\x35', '\xaf', '\x06', '\x1e'};  // empty, with its CRC
  bytes += std::string{0, 0, 0, 0} + "IEND" + std::string{'\xae', 'B', '`', '\x82'};
  std::ofstream(png, std::ios::binary) << bytes;
  const Result stop = run("build " + dir + "/seq --out " + dir + "/m.ot --quiet");
  EXPECT_EQ(stop.code, 1);
  EXPECT_NE(stop.out.find(png + ": the image is 16384x16384 pixels, larger than mobmap reads"), std::string::npos) << stop.out;
  EXPECT_FALSE(fs::exists(dir + "/m.ot"));
  const Result skip = run("build " + dir + "/seq --out " + dir + "/m.ot --quiet --skip-bad-frames");
  ASSERT_EQ(skip.code, 0) << skip.out;
  EXPECT_NE(skip.out.find("warning: skipped " + png + ": the image is 16384x16384"), std::string::npos) << skip.out;
  EXPECT_NE(skip.out.find("3 of 4 frames fused"), std::string::npos) << skip.out;
  fs::remove_all(dir);
}

// Adds `shift` to the translation of frame `n`'s pose in a 7-Scenes directory.
void shiftPose(const std::string& seq, int n, const Eigen::Vector3d& shift) {
  char name[64];
  std::snprintf(name, sizeof name, "/frame-%06d.pose.txt", n);
  std::ifstream in(seq + name);
  double m[4][4];
  for (auto& row : m) {
    for (double& x : row) in >> x;
  }
  ASSERT_TRUE(static_cast<bool>(in)) << seq + name;
  for (int i = 0; i < 3; ++i) m[i][3] += shift[i];
  std::ofstream out(seq + name);
  char line[200];
  for (const auto& row : m) {
    std::snprintf(line, sizeof line, "%.17g %.17g %.17g %.17g\n", row[0], row[1], row[2], row[3]);
    out << line;
  }
}

// World frames with large coordinates. The map is centred on an origin near the first
// camera (rounded to 100 m), so a sequence moved 2000 km away (UTM-sized poses) gives the
// map of the same sequence at home, and world-frame queries answer alike. Frames beyond
// the map's extent are reported, not counted as fused, and never make a map that the
// other commands refuse.
TEST(Cli, FarAwayCoordinatesGiveTheSameMapAndFramesOutsideAreReported) {
  const std::string dir = tempDir("far");
  ASSERT_EQ(run("simulate --out " + dir + "/home --frames 6 --noise none --quiet").code, 0);
  fs::copy(dir + "/home", dir + "/utm");
  const Eigen::Vector3d utm(2000000, 5000000, 300);
  for (int i = 0; i < 6; ++i) shiftPose(dir + "/utm", i, utm);
  ASSERT_EQ(run("build " + dir + "/home --out " + dir + "/home.ot --quiet").code, 0);
  const Result far = run("build " + dir + "/utm --out " + dir + "/utm.ot --quiet");
  ASSERT_EQ(far.code, 0) << far.out;  // it used to fail: "none of the 6 frames fused has a surface segment"
  EXPECT_NE(far.out.find("6 of 6 frames fused"), std::string::npos) << far.out;
  EXPECT_EQ(far.out.find("outside"), std::string::npos) << far.out;
  const auto meta = nlohmann::json::parse(fileBytes(dir + "/utm.json"));
  EXPECT_EQ(meta["origin_world"], nlohmann::json({2000000.0, 5000000.0, 300.0}));
  EXPECT_EQ(nlohmann::json::parse(fileBytes(dir + "/home.json"))["origin_world"], nlohmann::json({0.0, 0.0, 0.0}));
  // The same map, byte for byte: perception works in the camera frame and fusion moves
  // the poses to the origin in double precision before anything is rounded to float.
  EXPECT_GT(fileBytes(dir + "/home.ot").size(), 10000u);
  EXPECT_EQ(fileBytes(dir + "/utm.ot"), fileBytes(dir + "/home.ot"));
  // World-frame questions: the same answers at home and 2000 km away.
  for (const std::string& p : {"1.5 0 0.0", "3.0 -0.9 0.08", "2.0 0.5 0.0"}) {
    std::istringstream xyz(p);
    Eigen::Vector3d v;
    xyz >> v.x() >> v.y() >> v.z();
    const Eigen::Vector3d w = v + utm;
    char shifted[120];
    std::snprintf(shifted, sizeof shifted, "%.3f %.3f %.3f", w.x(), w.y(), w.z());
    const Result h = run("query " + dir + "/home.ot " + p + " --input-frame world --json");
    const Result u = run("query " + dir + "/utm.ot " + std::string(shifted) + " --input-frame world --json");
    ASSERT_EQ(h.code, 0) << h.out;
    ASSERT_EQ(u.code, 0) << u.out;
    const auto hj = jsonLine(h.out), uj = jsonLine(u.out);
    EXPECT_EQ(hj["state"], uj["state"]) << p;
    EXPECT_EQ(hj["mobility"], uj["mobility"]) << p;
  }
  const Result info = run("info " + dir + "/utm.ot");
  EXPECT_NE(info.out.find("map origin in the world frame: (2000000.000, 5000000.000, 300.000)"), std::string::npos) << info.out;
  // Plans asked and answered in the world frame come back in it.
  const Result plan = run("plan " + dir + "/utm.ot --from 2000001.2 5000000 300 --to 2000002.6 5000000.3 300 --input-frame world --json");
  ASSERT_EQ(plan.code, 0) << plan.out;
  const auto pj = nlohmann::json::parse(plan.out);
  EXPECT_NEAR(pj["footsteps"][0]["x"].get<double>(), 2000001.2, 0.5);

  // Frames 4 and 5 a kilometre away: outside the +-655 m the map reaches; reported per
  // frame and in the summary, not counted as fused, not in the camera path.
  fs::copy(dir + "/home", dir + "/split");
  for (int i : {4, 5}) shiftPose(dir + "/split", i, Eigen::Vector3d(1000, 0, 0));
  const Result split = run("build " + dir + "/split --out " + dir + "/split.ot --quiet");
  ASSERT_EQ(split.code, 0) << split.out;
  EXPECT_NE(split.out.find("warning: frame 4: "), std::string::npos) << split.out;
  EXPECT_NE(split.out.find("lie outside the map's extent (+-655 m around its origin (0.0, 0.0, 0.0) in the world frame) and "
                           "were left out: the frame adds nothing"),
            std::string::npos)
      << split.out;
  EXPECT_NE(split.out.find("4 of 6 frames fused"), std::string::npos) << split.out;
  EXPECT_NE(split.out.find("2 frames had no point inside and are not counted as fused"), std::string::npos) << split.out;
  const auto sj = nlohmann::json::parse(fileBytes(dir + "/split.json"));
  EXPECT_EQ(sj["frames"], 4);
  EXPECT_EQ(sj["frames_outside_map"], 2);
  EXPECT_GT(sj["points_outside_map"].get<long long>(), 10000);
  EXPECT_EQ(sj["trajectory_map"].size(), 4u);
  // One pose at 2000 km: the map build writes is one the other commands read.
  fs::copy(dir + "/home", dir + "/stray");
  shiftPose(dir + "/stray", 3, utm);
  const Result stray = run("build " + dir + "/stray --out " + dir + "/stray.ot --quiet");
  ASSERT_EQ(stray.code, 0) << stray.out;
  EXPECT_NE(stray.out.find("5 of 6 frames fused"), std::string::npos) << stray.out;
  for (const std::string& cmd : {"info " + dir + "/stray.ot", "query " + dir + "/stray.ot 1.5 0 0",
                                 "export " + dir + "/stray.ot --png " + dir + "/stray.png",
                                 "reach " + dir + "/stray.ot --from 1.2 0 0"}) {
    const Result r = run(cmd);
    EXPECT_EQ(r.code, 0) << cmd << "\n" << r.out;
  }
  // Every frame outside (a wrong --origin): no map, and the reason.
  const Result none = run("build " + dir + "/home --out " + dir + "/none.ot --origin 5000 0 0 --quiet");
  EXPECT_EQ(none.code, 1) << none.out;
  EXPECT_NE(none.out.find("all 6 frames with points in range lie outside the map's extent (+-655 m around its origin "
                          "(5000.0, 0.0, 0.0) in the world frame); no map written"),
            std::string::npos)
      << none.out;
  EXPECT_FALSE(fs::exists(dir + "/none.ot"));
  // --origin moves the map frame: the same voxels, shifted by whole voxels.
  ASSERT_EQ(run("build " + dir + "/home --out " + dir + "/moved.ot --origin 1 0 0 --quiet").code, 0);
  const auto q = [&](const std::string& map, const std::string& p) {
    return jsonLine(run("query " + map + " " + p + " --input-frame world --json").out);
  };
  EXPECT_EQ(q(dir + "/moved.ot", "1.5 0 0.0")["state"], q(dir + "/home.ot", "1.5 0 0.0")["state"]);
  EXPECT_EQ(run("build " + dir + "/home --out " + dir + "/moved.ot --extend --origin 0 0 0").code, 2);  // the map keeps its own
  fs::remove_all(dir);
}

TEST(Cli, SkipBadFramesLeavesOutUnreadableFramesAndMapsTheRest) {
  const std::string dir = tempDir("skipbad");
  ASSERT_EQ(run("simulate --out " + dir + "/bad --frames 6 --noise none --quiet").code, 0);
  fs::copy(dir + "/bad", dir + "/clean");
  // Frame 2: a depth image whose first IDAT chunk has a wrong CRC (libpng refuses it).
  const std::string png = dir + "/bad/frame-000002.depth.png";
  std::string bytes = fileBytes(png);
  const std::size_t idat = bytes.find("IDAT");
  ASSERT_NE(idat, std::string::npos);
  const auto byte = [&](std::size_t i) { return static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i])); };
  const std::uint32_t length = byte(idat - 4) << 24 | byte(idat - 3) << 16 | byte(idat - 2) << 8 | byte(idat - 1);
  bytes[idat + 4 + length + 3] = static_cast<char>(bytes[idat + 4 + length + 3] ^ 1);
  std::ofstream(png, std::ios::binary) << bytes;
  // Frame 4: a pose scaled by 2.
  std::ofstream(dir + "/bad/frame-000004.pose.txt") << "2 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";

  // Without the flag: the pose is found before any frame is processed.
  const Result pose = run("build " + dir + "/bad --out " + dir + "/m.ot");  // not a terminal: a log line per frame
  EXPECT_EQ(pose.code, 1);
  EXPECT_NE(pose.out.find("frame-000004.pose.txt: not a rigid transform"), std::string::npos) << pose.out;
  EXPECT_NE(pose.out.find("(build --skip-bad-frames leaves such frames out)"), std::string::npos) << pose.out;
  EXPECT_EQ(pose.out.find("build 1/"), std::string::npos) << pose.out;
  EXPECT_FALSE(fs::exists(dir + "/m.ot"));
  // The depth image's checksum is found when the frame is decoded.
  const Result crc = run("build " + dir + "/bad --frames 0:3 --out " + dir + "/m.ot --quiet");
  EXPECT_EQ(crc.code, 1);
  EXPECT_NE(crc.out.find("frame-000002.depth.png: corrupt or truncated PNG (IDAT: CRC error) (build --skip-bad-frames"),
            std::string::npos)
      << crc.out;
  EXPECT_FALSE(fs::exists(dir + "/m.ot"));

  // With it: both are left out and named; the other four frames make the map.
  const Result skip = run("build " + dir + "/bad --out " + dir + "/m.ot --quiet --skip-bad-frames");
  ASSERT_EQ(skip.code, 0) << skip.out;
  EXPECT_NE(skip.out.find("warning: skipped " + dir + "/bad/frame-000004.pose.txt: not a rigid"), std::string::npos) << skip.out;
  EXPECT_NE(skip.out.find("warning: skipped " + png + ": corrupt"), std::string::npos) << skip.out;
  EXPECT_NE(skip.out.find("4 of 6 frames fused"), std::string::npos) << skip.out;
  EXPECT_NE(skip.out.find("2 frames skipped as unreadable (--skip-bad-frames)"), std::string::npos) << skip.out;
  const auto meta = nlohmann::json::parse(fileBytes(dir + "/m.json"));
  EXPECT_EQ(meta["frames"], 4);
  EXPECT_EQ(meta["frames_selected"], 6);
  EXPECT_EQ(meta["frames_unreadable"], 2);
  ASSERT_EQ(meta["unreadable"].size(), 2u);
  EXPECT_EQ(meta["unreadable"][0].get<std::string>().rfind(dir + "/bad/frame-000004.pose.txt: ", 0), 0u) << meta;
  EXPECT_EQ(meta["unreadable"][1].get<std::string>().rfind(png + ": ", 0), 0u) << meta;
  for (const char* suffix : {"-000002", "-000004"}) {
    for (const char* kind : {".depth.png", ".color.png", ".labels.png", ".pose.txt"}) {
      fs::remove(dir + "/clean/frame" + suffix + kind);
    }
  }
  ASSERT_EQ(run("build " + dir + "/clean --out " + dir + "/clean.ot --quiet").code, 0);
  EXPECT_TRUE(fileBytes(dir + "/m.ot") == fileBytes(dir + "/clean.ot"));
  EXPECT_TRUE(fileBytes(dir + "/m.bt") == fileBytes(dir + "/clean.bt"));

  // Nothing readable: an error, no map.
  const Result none = run("build " + dir + "/bad --frames 2:2 --out " + dir + "/none.ot --quiet --skip-bad-frames");
  EXPECT_EQ(none.code, 1) << none.out;
  EXPECT_NE(none.out.find("no selected frame could be read (1 tried; the first: " + png), std::string::npos) << none.out;
  EXPECT_FALSE(fs::exists(dir + "/none.ot"));
  const Result no_pose = run("build " + dir + "/bad --frames 4:4 --out " + dir + "/none.ot --quiet --skip-bad-frames");
  EXPECT_EQ(no_pose.code, 1) << no_pose.out;
  EXPECT_NE(no_pose.out.find("no selected frame can be read (1 tried; the first: "), std::string::npos) << no_pose.out;
  EXPECT_FALSE(fs::exists(dir + "/none.ot"));
  // Not for a single frame.
  const Result single = run("build " + dir + "/clean/frame-000000.depth.png --out " + dir + "/one.ot --skip-bad-frames");
  EXPECT_EQ(single.code, 2) << single.out;
  EXPECT_NE(single.out.find("--skip-bad-frames is for sequences of files"), std::string::npos) << single.out;
  fs::remove_all(dir);
}

// Lengths, times and coordinates that are NaN or negative are usage errors (exit 2) naming
// the option, not quietly taken: NaN compares false with every bound, and a negative
// --snap used to mean "no snap" and a negative --max-pose-gap was accepted where it applies to nothing.
TEST(Cli, NonFiniteOrNegativeLengthsAndTimesAreUsageErrors) {
  const std::string dir = tempDir("domains");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 2 --noise none --quiet").code, 0);
  const std::string map = dir + "/m.ot";
  for (const std::string gap : {"nan", "-1", "inf"}) {
    const Result r = run("build " + dir + "/seq --out " + map + " --quiet --max-pose-gap " + gap);
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_NE(r.out.find("--max-pose-gap: must be a finite number >= 0, got '" + gap + "'"), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(map));
  }
  ASSERT_EQ(run("build " + dir + "/seq --out " + map + " --quiet --max-pose-gap 0").code, 0);
  // The floor under the first camera, 1.0 m ahead of it (the camera looks along +x).
  const Result ok = run("query " + map + " 1.0 0 0.3 --snap 0.5 --json");
  ASSERT_EQ(ok.code, 0) << ok.out;
  EXPECT_EQ(jsonLine(ok.out)["state"], "surface") << ok.out;
  for (const std::string snap : {"-1", "nan", "-0.5", "1x"}) {
    const Result r = run("query " + map + " 1.0 0 0.3 --snap " + snap);
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_NE(r.out.find("--snap: must be a finite number >= 0, got '" + snap + "'"), std::string::npos) << r.out;
  }
  for (const std::string xyz : {"1.0 0 nan", "inf 0 0.3"}) {
    const Result r = run("query " + map + " " + xyz);
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_NE(r.out.find("X Y Z: values must be finite"), std::string::npos) << r.out;
  }
  const Result overlay = run("overlay " + map + " --frame 1 --out " + dir + "/o.png --max-pose-gap -0.1");
  EXPECT_EQ(overlay.code, 2) << overlay.out;
  EXPECT_NE(overlay.out.find("--max-pose-gap: must be a finite number >= 0"), std::string::npos) << overlay.out;
  EXPECT_FALSE(fs::exists(dir + "/o.png"));
  fs::remove_all(dir);
}

}  // namespace
