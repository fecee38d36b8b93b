// `mobmap serve`: its answers are the CLI's, bad requests are refused and the server goes
// on, a live map's frame count grows while queries are answered, the voxels are paged and
// coarsened faithfully, and the viewer draws the corridor's green floor and red walls in
// a real browser.
// Eigen before httplib: <resolv.h>, which httplib pulls in, defines _res, a name Eigen uses.
#include "io/png_io.hpp"
#include "serve/api.hpp"

#include "mobmap/mapping/layers.hpp"
#include "mobmap/mapping/mobility_map.hpp"

#include "serve_support.hpp"

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace mobmap::serve_test {
namespace {

namespace fs = std::filesystem;

// A screenshot's pixel in the colour of mobility 1 on viridis (yellow) or of mobility 0
// (dark purple), as the viewer's face shading leaves them.
bool isViridisYellow(const std::array<std::uint8_t, 3>& p) { return p[0] > 150 && p[1] > 150 && p[2] < 100; }
bool isViridisPurple(const std::array<std::uint8_t, 3>& p) { return p[1] < 60 && p[2] > p[1] + 30 && p[0] > p[1] + 20; }

// Points over the corridor and around it: on the floor, above it, in the walls, outside.
std::vector<std::array<double, 3>> probePoints(double step) {
  std::vector<std::array<double, 3>> points;
  for (double x = 0.5; x <= 3.51; x += step)
    for (double y = -1.6; y <= 1.61; y += step)
      for (double z : {0.01, 0.05, 0.3, 1.0}) points.push_back({x, y, z});
  points.push_back({1e6, -1e6, 3});  // far outside the map
  return points;
}

std::string asLines(const std::vector<std::vector<double>>& rows) {
  std::ostringstream out;
  out.precision(17);
  for (const auto& r : rows) {
    for (std::size_t i = 0; i < r.size(); ++i) out << (i ? " " : "") << r[i];
    out << "\n";
  }
  return out.str();
}

// The CLI's answers to `rows` given on standard input: one JSON line each.
std::vector<nlohmann::json> cliAnswers(const std::string& dir, const std::string& args,
                                       const std::vector<std::vector<double>>& rows) {
  const std::string input = dir + "/rows.txt";
  std::ofstream(input) << asLines(rows);
  const Result r = mobmap(args + " < " + input);
  EXPECT_EQ(r.code, 0) << r.out;
  return jsonLines(r.out);
}

// The library's height scan of `poses` (map frame) against a server's answer: the same
// floats, null where the library says NaN.
void expectScanIs(const nlohmann::json& body, const mapping::HeightScan& want) {
  ASSERT_EQ(body["nx"], want.nx);
  ASSERT_EQ(body["ny"], want.ny);
  for (const char* field : {"height", "mobility"}) {
    const std::vector<float>& values = std::string(field) == "height" ? want.height : want.mobility;
    ASSERT_EQ(body[field].size(), want.poses) << field;
    std::size_t at = 0;
    for (std::size_t p = 0; p < want.poses; ++p) {
      ASSERT_EQ(body[field][p].size(), static_cast<std::size_t>(want.ny));
      for (int j = 0; j < want.ny; ++j) {
        ASSERT_EQ(body[field][p][j].size(), static_cast<std::size_t>(want.nx));
        for (int i = 0; i < want.nx; ++i, ++at) {
          const nlohmann::json& v = body[field][p][j][i];
          if (std::isnan(values[at])) {
            EXPECT_TRUE(v.is_null()) << field << " pose " << p << " point " << i << ", " << j;
          } else {
            ASSERT_TRUE(v.is_number()) << field << " pose " << p << " point " << i << ", " << j;
            EXPECT_EQ(static_cast<float>(v.get<double>()), values[at]) << field << " pose " << p << " point " << i << ", " << j;
          }
        }
      }
    }
  }
}

// A noise-free corridor of 40 frames (walls and a box in view) mapped with its origin
// moved, so that the world and map frames differ; built once for the suite.
struct CorridorWithOrigin {
  static constexpr const char* kName = "corridor";
  static constexpr int kFrames = 40;
  static constexpr const char* kBuild = "--origin 0.5 0.25 -0.1";
};
using ServedCorridor = MappedCorridor<CorridorWithOrigin>;

TEST_F(ServedCorridor, PointAndSoleAnswersAreTheClis) {
  ServeProcess server({"serve", map(), "--port", "0"}, dir() + "/points.err");
  ASSERT_TRUE(server.started());
  const int port = server.port();
  ASSERT_GT(port, 0) << server.output();
  auto c = client(port);

  std::vector<std::vector<double>> points;
  for (const auto& p : probePoints(0.25)) points.push_back({p[0], p[1], p[2]});
  std::vector<std::vector<double>> soles;
  for (double x = 0.6; x <= 3.41; x += 0.4)
    for (double y = -1.2; y <= 1.21; y += 0.6)
      for (double yaw : {0.0, 0.7}) soles.push_back({x, y, 0.05, yaw, 0.25, 0.12});
  int surfaces = 0, supported = 0;
  for (const std::string frame : {"map", "world"}) {
    for (const double snap : {-1.0, 0.3}) {
      nlohmann::json request{{"points", points}, {"frame", frame}};
      std::string snap_arg;
      if (snap >= 0) {
        request["snap"] = snap;
        snap_arg = " --snap 0.3";
      }
      const Reply r = post(*c, "/api/query", request.dump());
      ASSERT_EQ(r.status, 200) << r.raw;
      const auto cli = cliAnswers(dir(), "query " + map() + " --json --input-frame " + frame + snap_arg, points);
      ASSERT_EQ(cli.size(), points.size());
      ASSERT_EQ(r.body["answers"].size(), points.size());
      for (std::size_t i = 0; i < points.size(); ++i) {
        EXPECT_EQ(r.body["answers"][i], cli[i]) << frame << " snap " << snap << " point " << i;
        surfaces += cli[i]["state"] == "surface";
      }
      EXPECT_EQ(r.body["frames"], 40);

      nlohmann::json feet{{"soles", soles}, {"frame", frame}};
      if (snap >= 0) feet["snap"] = snap;
      const Reply f = post(*c, "/api/foot", feet.dump());
      ASSERT_EQ(f.status, 200) << f.raw;
      const auto cli_feet = cliAnswers(dir(), "query " + map() + " --feet --json --input-frame " + frame + snap_arg, soles);
      ASSERT_EQ(cli_feet.size(), soles.size());
      for (std::size_t i = 0; i < soles.size(); ++i) {
        EXPECT_EQ(f.body["answers"][i], cli_feet[i]) << frame << " snap " << snap << " sole " << i;
        supported += !cli_feet[i]["support_plane"].is_null();
      }
    }
  }
  // The comparison covered surfaces and supported soles, not only empty space.
  EXPECT_GT(surfaces, 100);
  EXPECT_GT(supported, 50);
  EXPECT_EQ(server.stop(), 0);
}

TEST_F(ServedCorridor, HeightScansAreTheLibrarys) {
  ServeProcess server({"serve", map(), "--port", "0"}, dir() + "/scan.err");
  const int port = server.port();
  ASSERT_GT(port, 0) << server.output();
  auto c = client(port);
  const mapping::MobilityMap library = mapping::openMap(map());
  // Bases over the floor, the ramps, the box and the stairs, facing four ways.
  std::vector<std::vector<double>> poses;
  for (double x = 0.6; x <= 3.41; x += 0.7)
    for (double y = -1.2; y <= 1.21; y += 0.8) poses.push_back({x, y, 0.45, 0.6 * x + y});
  std::vector<mapping::HeightScanPose> in_map;
  for (const auto& p : poses) in_map.push_back({p[0], p[1], p[2], p[3]});
  for (const std::string frame : {"map", "world"}) {
    for (const auto& [size, resolution] : {std::make_pair(std::array<double, 2>{1.6, 1.0}, 0.1),
                                          std::make_pair(std::array<double, 2>{0.4, 0.3}, 0.02)}) {
      nlohmann::json request{{"poses", poses}, {"frame", frame}, {"size", size}, {"resolution", resolution}};
      if (frame == "world") {
        // The same bases given in the world frame.
        for (std::size_t i = 0; i < poses.size(); ++i) {
          const Eigen::Vector3d w = library.mapToWorld({poses[i][0], poses[i][1], poses[i][2]});
          const double yaw = library.mapYawToWorld(poses[i][3]);
          request["poses"][i] = {w.x(), w.y(), w.z(), yaw};
        }
      }
      const Reply r = post(*c, "/api/height_scan", request.dump());
      ASSERT_EQ(r.status, 200) << r.raw.substr(0, 300);
      EXPECT_EQ(r.body["frames"], 40);
      const mapping::HeightScan want = library.heightScan(in_map, {size[0], size[1], resolution});
      if (frame == "map") {
        expectScanIs(r.body, want);
        continue;
      }
      // Through the world frame the poses carry rounding: the heights agree to a micrometre.
      std::size_t known = 0, at = 0;
      for (const auto& pose : r.body["height"])
        for (const auto& row : pose)
          for (const auto& v : row) {
            ASSERT_EQ(v.is_null(), std::isnan(want.height[at])) << "point " << at;
            if (!v.is_null()) {
              EXPECT_NEAR(v.get<double>(), want.height[at], 1e-5) << "point " << at;
              ++known;
            }
            ++at;
          }
      EXPECT_EQ(at, want.height.size());
      EXPECT_GT(known, at / 3);
    }
  }
  // The default grid is legged_gym's 17 x 11.
  const Reply d = post(*c, "/api/height_scan", R"({"poses": [[1.5, 0, 0.45, 0]]})");
  ASSERT_EQ(d.status, 200) << d.raw;
  EXPECT_EQ(d.body["nx"], 17);
  EXPECT_EQ(d.body["ny"], 11);
  EXPECT_EQ(server.stop(), 0);
}

// "reach" in a request answers as `query --reach`: from the map's first camera position by
// default, or from a point with the robot's limits; the same for soles.
TEST_F(ServedCorridor, ReachAnswersAreTheClis) {
  ServeProcess server({"serve", map(), "--port", "0"}, dir() + "/reach.err");
  const int port = server.port();
  ASSERT_GT(port, 0) << server.output();
  auto c = client(port);
  std::vector<std::vector<double>> points;
  for (const auto& p : probePoints(0.25)) points.push_back({p[0], p[1], p[2]});
  std::vector<std::vector<double>> soles;
  for (double x = 0.6; x <= 3.41; x += 0.2)
    for (double y = -1.2; y <= 1.21; y += 0.3) soles.push_back({x, y, 0.05, 0.3, 0.25, 0.12});
  struct Case {
    std::string frame;
    nlohmann::json reach;
    std::string cli;
  };
  const std::vector<Case> cases{
      {"world", true, "--reach"},
      {"map", {{"from", {1.0, 0.0, 0.1}}, {"max_step_m", 0.12}, {"min_mobility", 0.6}},
       "--reach --from 1 0 0.1 --max-step 0.12 --min-mobility 0.6"},
  };
  int reachable = 0, unreachable = 0;
  for (const Case& k : cases) {
    const Reply r = post(*c, "/api/query", nlohmann::json{{"points", points}, {"frame", k.frame}, {"reach", k.reach}}.dump());
    ASSERT_EQ(r.status, 200) << r.raw.substr(0, 300);
    const auto cli = cliAnswers(dir(), "query " + map() + " --json --input-frame " + k.frame + " " + k.cli, points);
    ASSERT_EQ(cli.size(), points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
      EXPECT_EQ(r.body["answers"][i], cli[i]) << k.cli << " point " << i;
      const nlohmann::json& place = cli[i]["reach"];
      reachable += place["reachable"] == true;
      unreachable += place["reachable"] == false;
    }
    const Reply f = post(*c, "/api/foot", nlohmann::json{{"soles", soles}, {"frame", k.frame}, {"reach", k.reach}}.dump());
    ASSERT_EQ(f.status, 200) << f.raw.substr(0, 300);
    const auto cli_feet = cliAnswers(dir(), "query " + map() + " --feet --json --input-frame " + k.frame + " " + k.cli, soles);
    ASSERT_EQ(cli_feet.size(), soles.size());
    for (std::size_t i = 0; i < soles.size(); ++i) EXPECT_EQ(f.body["answers"][i], cli_feet[i]) << k.cli << " sole " << i;
  }
  EXPECT_GT(reachable, 50);
  EXPECT_GT(unreachable, 50);  // no surface under the point, or one the robot cannot get onto
  // No place to start from, an unknown robot field, a bad start rule: 400.
  for (const char* bad : {R"({"points": [[1,0,0]], "reach": {"from": [40, 40, 0]}})",
                          R"({"points": [[1,0,0]], "reach": {"max_steps": 0.2}})",
                          R"({"points": [[1,0,0]], "reach": {"start": "anywhere"}})",
                          R"({"points": [[1,0,0]], "reach": {"max_step_m": -1}})", R"({"points": [[1,0,0]], "reach": 3})"}) {
    const Reply r = post(*c, "/api/query", bad);
    EXPECT_EQ(r.status, 400) << bad << ": " << r.raw;
  }
  EXPECT_EQ(server.stop(), 0);
}

TEST_F(ServedCorridor, PlanAndInfoAreTheClis) {
  ServeProcess server({"serve", map(), "--port", "0"}, dir() + "/plan.err");
  const int port = server.port();
  ASSERT_GT(port, 0) << server.output();
  auto c = client(port);
  // The CLI's plan without its time, which no two runs share.
  const auto untimed = [](nlohmann::json j) {
    EXPECT_TRUE(j.contains("planning_time_s"));
    j.erase("planning_time_s");
    return j;
  };
  for (const std::string frame : {"map", "world"}) {
    const Reply r = post(*c, "/api/plan",
                         nlohmann::json{{"from", {1.0, 0.0, 0.1}}, {"to", {2.6, 0.3, 0.1}}, {"frame", frame},
                                        {"max_step_m", 0.12}, {"sole_length_m", 0.22}, {"sole_width_m", 0.11}}
                             .dump());
    ASSERT_EQ(r.status, 200) << r.raw;
    const Result cli = mobmap("plan " + map() + " --from 1 0 0.1 --to 2.6 0.3 0.1 --input-frame " + frame +
                              " --max-step 0.12 --sole 0.22 0.11 --json");
    ASSERT_EQ(cli.code, 0) << cli.out;
    const nlohmann::json expected = untimed(jsonLines(cli.out).at(0));
    EXPECT_EQ(untimed(r.body), expected) << frame;
    EXPECT_TRUE(expected["found"].get<bool>());
    EXPECT_GT(expected["footsteps"].size(), 4u);
  }
  // No way there: found false, with the reason the CLI gives, each front naming the
  // limits its own way: the API by its JSON keys, the CLI by its flags.
  const Reply none = post(*c, "/api/plan", R"({"from":[1,0,0.1],"to":[2.6,0.3,0.1],"max_stride_m":0.05})");
  const Result cli_none = mobmap("plan " + map() + " --from 1 0 0.1 --to 2.6 0.3 0.1 --max-stride 0.05 --json");
  ASSERT_EQ(none.status, 200) << none.raw;
  nlohmann::json api_none = untimed(none.body);
  const nlohmann::json cli_answer = untimed(jsonLines(cli_none.out).at(0));
  const std::string api_reason = api_none["reason"].get<std::string>(), cli_reason = cli_answer["reason"].get<std::string>();
  EXPECT_NE(api_reason.find("try a larger `max_stride_m` or `goal_tolerance_m`"), std::string::npos) << api_reason;
  EXPECT_NE(cli_reason.find("try a larger --max-stride or --goal-tolerance"), std::string::npos) << cli_reason;
  api_none["reason"] = cli_reason;
  EXPECT_EQ(api_none, cli_answer);

  const Reply info = get(*c, "/api/info");
  ASSERT_EQ(info.status, 200);
  const Result cli_info = mobmap("info " + map() + " --json");
  nlohmann::json served = info.body;
  EXPECT_EQ(served["frames"], 40);
  EXPECT_EQ(served["building"], false);
  served.erase("frames");
  served.erase("building");
  EXPECT_EQ(served, jsonLines(cli_info.out).at(0));

  // The camera path is MAP.json's.
  const Reply path = get(*c, "/api/camera_path");
  ASSERT_EQ(path.status, 200);
  EXPECT_EQ(path.body["positions"], info.body["metadata"]["trajectory_map"]);
  EXPECT_EQ(server.stop(), 0);
}

TEST_F(ServedCorridor, BadRequestsAreRefusedAndTheServerGoesOn) {
  ServeProcess server({"serve", map(), "--port", "0", "--max-batch", "100"}, dir() + "/bad.err");
  const int port = server.port();
  ASSERT_GT(port, 0) << server.output();
  auto c = client(port);
  struct Bad {
    std::string path, body;
    int status;
  };
  std::string many = "{\"points\":[";
  for (int i = 0; i < 101; ++i) many += std::string(i ? "," : "") + "[1,0,0]";
  many += "]}";
  const std::string nested = std::string(100000, '[') + std::string(100000, ']');
  const std::vector<Bad> bad{
      {"/api/query", "{\"points\": [[1,0,0]", 400},          // cut short
      {"/api/query", "", 400},                               // empty
      {"/api/query", "[[1,0,0]]", 400},                      // not an object
      {"/api/query", "{}", 400},                             // no points
      {"/api/query", R"({"points": [[1,0]]})", 400},         // two numbers
      {"/api/query", R"({"points": [1,0,0]})", 400},         // not an array of points
      {"/api/query", R"({"points": [["1",0,0]]})", 400},     // a string
      {"/api/query", R"({"points": [[NaN,0,0]]})", 400},     // NaN is not JSON
      {"/api/query", R"({"points": [[1e999,0,0]]})", 400},   // infinite
      {"/api/query", R"({"points": [[null,0,0]]})", 400},
      {"/api/query", R"({"points": [[1,0,0]], "frame": "moon"})", 400},
      {"/api/query", R"({"points": [[1,0,0]], "snap": -1})", 400},
      {"/api/query", R"({"points": [[1,0,0]], "snapp": 1})", 400},  // a misspelt field
      {"/api/query", "{\"points\": [[1,0,0]], \"\x9f\x87\xa0\": 1}", 400},  // a field that is not UTF-8
      {"/api/query", many, 413},                                    // over --max-batch
      {"/api/query", nested, 400},
      {"/api/foot", R"({"soles": [[1,0,0,0,0,0.1]]})", 400},        // a sole of no length
      {"/api/foot", R"({"soles": [[1,0,0,0,0.2,11]]})", 400},       // wider than 10 m
      {"/api/foot", R"({"soles": [[1,0,0,0,0.2]]})", 400},
      {"/api/plan", R"({"to": [2,0,0.1]})", 400},
      {"/api/plan", R"({"from": [1,0,0.1], "to": [2,0,0.1], "max_step_m": "high"})", 400},
      {"/api/plan", R"({"from": [1,0,0.1], "to": [2,0,0.1], "max_step_m": -1})", 400},
      {"/api/plan", R"({"from": [1,0,0.1], "to": [2,0,0.1], "wings": 2})", 400},
      {"/api/plan", R"({"from": [1,0,0.1], "to": [2,0,0.1], "time_limit_s": 1e9})", 400},
      {"/api/plan", R"({"from": [50,50,0.1], "to": [2,0,0.1]})", 400},  // no surface at the start
      {"/api/height_scan", R"({"poses": [[1,0,0.4]]})", 400},           // three numbers
      {"/api/height_scan", R"({"poses": [[1,0,0.4,null]]})", 400},
      {"/api/height_scan", R"({"poses": [[1,0,0.4,0]], "resolution": 0})", 400},
      {"/api/height_scan", R"({"poses": [[1,0,0.4,0]], "size": [1e9, 1]})", 400},
      {"/api/height_scan", R"({"poses": [[1,0,0.4,0]], "size": [1]})", 400},
      {"/api/height_scan", R"({"poses": [[1,0,0.4,0]], "grid": 1})", 400},
      {"/api/height_scan", R"({"poses": [[1,0,0.4,0]], "size": [10, 10], "resolution": 0.01})", 413},  // 1 million points
      {"/api/nothing", "{}", 404},
  };
  for (const Bad& b : bad) {
    const Reply r = post(*c, b.path, b.body);
    EXPECT_EQ(r.status, b.status) << b.path << " " << b.body.substr(0, 80) << ": " << r.raw;
    EXPECT_TRUE(r.body.is_object() && r.body["error"].is_string()) << r.raw.substr(0, 200);
    // Still serving, and still right.
    const Reply ok = post(*c, "/api/query", R"({"points": [[1.2,0,0.05]], "snap": 0.3, "frame": "world"})");
    ASSERT_EQ(ok.status, 200) << "after " << b.body.substr(0, 80);
    EXPECT_EQ(ok.body["answers"][0]["state"], "surface");
  }
  const std::vector<std::pair<std::string, int>> bad_gets{
      {"/api/query", 405},          {"/nothing/here", 404},          {"/api/voxels?max=0", 400},
      {"/api/voxels?max=abc", 400}, {"/api/voxels?level=16", 400},   {"/api/voxels?limit=1e3", 400},
      {"/api/voxels?offset=-1", 400}, {"/api/voxels?limit=3000000", 413},
  };
  for (const auto& [path, status] : bad_gets) {
    const Reply r = get(*c, path);
    EXPECT_EQ(r.status, status) << path << ": " << r.raw;
    EXPECT_TRUE(r.body.is_object() && r.body["error"].is_string()) << path;
  }
  // A body over the server's 16 MiB: refused before it is read.
  const Reply huge = post(*c, "/api/query", std::string(17u << 20, ' '));
  EXPECT_EQ(huge.status, 413);
  auto c2 = client(port);
  EXPECT_EQ(get(*c2, "/api/info").status, 200);
  EXPECT_EQ(server.stop(), 0);
}

// A port in use is an error, not a second server sharing it; so is an address that is
// not this machine's. (`timeout`: a server that did start would otherwise serve forever.)
TEST_F(ServedCorridor, APortInUseIsRefused) {
  ServeProcess server({"serve", map(), "--port", "0"}, dir() + "/port.err");
  const int port = server.port();
  ASSERT_GT(port, 0) << server.output();
  const Result second = runShell("timeout 120 " + std::string(MOBMAP_EXE) + " serve " + map() + " --port " + std::to_string(port));
  EXPECT_EQ(second.code, 2) << second.out;
  EXPECT_NE(second.out.find("cannot listen on 127.0.0.1:" + std::to_string(port)), std::string::npos) << second.out;
  const Result elsewhere = runShell("timeout 120 " + std::string(MOBMAP_EXE) + " serve " + map() + " --port 0 --bind 192.0.2.1");
  EXPECT_EQ(elsewhere.code, 2) << elsewhere.out;
  auto c = client(port);
  EXPECT_EQ(get(*c, "/api/info").status, 200);  // the first still serves
  EXPECT_EQ(server.stop(), 0);
}

// The API keeps no map alive once a newer one is published: a live mapper whose old
// snapshot were held would have to copy the map to fuse the next frame.
TEST(ServeApi, HoldsNoMapOnceANewerOneIsPublished) {
  app::serve::ServedMap first;
  first.map = std::make_shared<const mapping::MobilityMap>();
  const std::weak_ptr<const mapping::MobilityMap> first_map = first.map;
  app::serve::MapSource source(std::move(first));
  const app::serve::Api api("live.ot", source);
  EXPECT_EQ(api.handle("GET", "/api/info", {}, "").status, 200);  // figures cached for the first map
  EXPECT_EQ(api.handle("GET", "/api/voxels", {}, "").status, 200);
  app::serve::ServedMap second;
  second.map = std::make_shared<const mapping::MobilityMap>();
  second.frames = 1;
  source.publish(std::move(second));
  EXPECT_TRUE(first_map.expired());
  const auto info = nlohmann::json::parse(api.handle("GET", "/api/info", {}, "").body);
  EXPECT_EQ(info["frames"], 1);  // and the figures are the new map's
}

// The voxels a viewer draws: every occupied voxel once at the finest level, pages that
// add up to the whole, and coarser grids whose cells hold the lowest known mobility of
// the voxels in them (brute force over the finest cells).
TEST_F(ServedCorridor, VoxelsArePagedAndCoarsenedFaithfully) {
  const mapping::MobilityMap loaded = mapping::openMap(map());
  const auto& tree = loaded.tree();
  const std::vector<app::serve::Cell> fine = app::serve::surfaceCells(tree, 0);
  std::size_t occupied = 0;
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) {
    if (!tree.isNodeOccupied(*it)) continue;
    occupied += static_cast<std::size_t>(std::lround(std::pow(it.getSize() / tree.getResolution(), 3)));
  }
  ASSERT_EQ(fine.size(), occupied);
  for (const auto& cell : fine) {
    const mapping::PointQuery q = loaded.query(cell.centre);
    ASSERT_EQ(q.state, mapping::VoxelState::kSurface);
    ASSERT_NEAR((q.centre - cell.centre).norm(), 0.0, 1e-4 + q.size_m);
    if (q.has_mobility) {
      ASSERT_FLOAT_EQ(cell.mobility, static_cast<float>(q.mobility));
    } else {
      ASSERT_TRUE(std::isnan(cell.mobility));
    }
  }
  const double res = tree.getResolution();
  for (int level : {1, 3}) {
    const double size = res * std::ldexp(1.0, level);
    std::map<std::array<long, 3>, float> expected;  // cell -> lowest known mobility (NaN: none)
    for (const auto& f : fine) {
      const std::array<long, 3> k{std::lround(std::floor(f.centre.x() / size)), std::lround(std::floor(f.centre.y() / size)),
                                  std::lround(std::floor(f.centre.z() / size))};
      auto [it, inserted] = expected.emplace(k, f.mobility);
      if (!inserted && !std::isnan(f.mobility) && !(it->second <= f.mobility)) it->second = f.mobility;
    }
    const auto coarse = app::serve::surfaceCells(tree, level);
    ASSERT_EQ(coarse.size(), expected.size()) << "level " << level;
    for (const auto& cell : coarse) {
      const std::array<long, 3> k{std::lround(std::floor(cell.centre.x() / size)),
                                  std::lround(std::floor(cell.centre.y() / size)),
                                  std::lround(std::floor(cell.centre.z() / size))};
      const auto it = expected.find(k);
      ASSERT_NE(it, expected.end());
      if (std::isnan(it->second)) {
        EXPECT_TRUE(std::isnan(cell.mobility));
      } else {
        EXPECT_FLOAT_EQ(cell.mobility, it->second);
      }
    }
  }

  // Over HTTP: pages of 5000 add up to the finest grid; a cap on the count coarsens it.
  ServeProcess server({"serve", map(), "--port", "0"}, dir() + "/voxels.err");
  const int port = server.port();
  ASSERT_GT(port, 0) << server.output();
  auto c = client(port);
  std::vector<double> all;
  std::size_t offset = 0;
  for (int pages = 0;; ++pages) {
    ASSERT_LT(pages, 1000);
    const Reply r = get(*c, "/api/voxels?level=0&limit=5000&offset=" + std::to_string(offset));
    ASSERT_EQ(r.status, 200) << r.raw.substr(0, 200);
    EXPECT_EQ(r.body["total"], fine.size());
    for (const auto& v : r.body["voxels"]) all.push_back(v.is_null() ? NAN : v.get<double>());
    if (r.body["next"].is_null()) break;
    offset = r.body["next"].get<std::size_t>();
  }
  ASSERT_EQ(all.size(), 4 * fine.size());
  for (std::size_t i = 0; i < fine.size(); ++i) {
    for (int a = 0; a < 3; ++a) ASSERT_NEAR(all[4 * i + a], fine[i].centre(a), 1e-4);
    if (std::isnan(fine[i].mobility)) {
      ASSERT_TRUE(std::isnan(all[4 * i + 3]));
    } else {
      ASSERT_NEAR(all[4 * i + 3], fine[i].mobility, 5e-4);
    }
  }
  const std::size_t cap = fine.size() / 10;
  const Reply capped = get(*c, "/api/voxels?max=" + std::to_string(cap));
  ASSERT_EQ(capped.status, 200);
  const int level = capped.body["level"];
  EXPECT_GE(level, 1);
  EXPECT_LE(capped.body["total"].get<std::size_t>(), cap);
  // The finest level under the cap: one level finer is over it.
  EXPECT_GT(app::serve::surfaceCells(tree, level - 1).size(), cap);
  EXPECT_DOUBLE_EQ(capped.body["cell_size_m"].get<double>(), res * std::ldexp(1.0, level));
  EXPECT_EQ(server.stop(), 0);
}

// Headless Chromium on a loaded machine now and then exits before the page has drawn
// (its DOM dump comes back empty): the command again, up to three times, until its output
// holds `marker` (the page's own report) or `file` exists. What the page reports is then
// checked as before.
Result chromiumUntil(const std::string& command, const std::string& marker, const std::string& file = "") {
  Result r;
  for (int attempt = 0; attempt < 3; ++attempt) {
    r = runShell(command);
    if (file.empty() ? r.out.find(marker) != std::string::npos : fs::exists(file) && fs::file_size(file) > 0) break;
    std::fprintf(stderr, "[ info ] chromium gave no %s on attempt %d; again\n", file.empty() ? marker.c_str() : file.c_str(), attempt + 1);
  }
  return r;
}

// Headless Chromium loads the viewer from the server and draws it with WebGL (SwiftShader):
// the page says it drew the map's 40 frames, the screenshot shows the corridor's floor in
// the colour of mobility 1 (viridis yellow) and its walls in that of 0 (dark purple), and
// a click shows the server's answer for the voxel hit.
TEST_F(ServedCorridor, ViewerDrawsTheFloorAndWallsInMobilityColoursInChromium) {
  if (runShell("command -v chromium").code != 0) {
    GTEST_SKIP() << "chromium is not installed (scripts/setup.sh installs it): the viewer is not drawn";
  }
  ServeProcess server({"serve", map(), "--port", "0"}, dir() + "/viewer.err");
  const int port = server.port();
  ASSERT_GT(port, 0) << server.output();
  auto c = client(port);
  // The page and three.js come from the server itself.
  const auto page = c->Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_NE(page->body.find("viewer.js"), std::string::npos);
  for (const char* asset : {"/three.min.js", "/OrbitControls.js", "/viewer.js"}) {
    const auto r = c->Get(asset);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200) << asset;
    EXPECT_GT(r->body.size(), 1000u) << asset;
  }

  const std::string url = "http://127.0.0.1:" + std::to_string(port) + "/";
  // Virtual time: the page's requests and frames complete before the capture, however
  // slow the machine.
  const std::string chromium = "timeout 600 chromium --headless --no-sandbox --use-angle=swiftshader "
                               "--enable-unsafe-swiftshader --hide-scrollbars --no-first-run --user-data-dir=" +
                               dir() + "/chromium --window-size=800,600 --virtual-time-budget=30000 ";
  const Result dom = chromiumUntil(chromium + "--dump-dom " + url, "data-drawn-frames=");
  ASSERT_NE(dom.out.find("data-drawn-frames=\"40\""), std::string::npos) << dom.out.substr(0, 3000);
  const std::string png = dir() + "/viewer.png";
  const Result shot = chromiumUntil(chromium + "--screenshot=" + png + " " + url, "", png);
  ASSERT_TRUE(fs::exists(png)) << shot.out;
  const app::ImageRgb image = app::readPngRgb(png);
  ASSERT_EQ(image.width, 800);
  ASSERT_EQ(image.height, 600);
  // Below the panels (the legend's colour bar would count): the scene only.
  std::size_t yellow = 0, purple = 0, scene = 0;
  for (int y = 120; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      const auto& p = image.pixels[static_cast<std::size_t>(y) * static_cast<std::size_t>(image.width) + static_cast<std::size_t>(x)];
      ++scene;
      yellow += isViridisYellow(p);
      purple += isViridisPurple(p);
    }
  }
  const double yellow_share = static_cast<double>(yellow) / scene, purple_share = static_cast<double>(purple) / scene;
  EXPECT_GT(yellow_share, 0.10) << "yellow (walkable floor) share of the scene";
  EXPECT_GT(purple_share, 0.005) << "dark purple (walls) share of the scene";
  EXPECT_GT(yellow_share, 3 * purple_share) << "the floor is most of what is seen";
  // The page took the scale from the server: the one the pictures draw with.
  const Reply scale = get(*c, "/api/colours");
  EXPECT_EQ(scale.body["scale"], "viridis");
  EXPECT_EQ(scale.body["stops"].size(), mapping::colourStops(mapping::ColourScale::kViridis).size());

  // A click in the middle of the view (the page clicks itself: ?click=0.5,0.5) lands on
  // the floor below the map's centre, and the page shows the server's answer for that voxel.
  const Result clicked = chromiumUntil(chromium + "--dump-dom '" + url + "?click=0.5,0.5'", "data-picked=");
  const auto at = clicked.out.find("data-picked=\"");
  ASSERT_NE(at, std::string::npos) << clicked.out.substr(0, 3000);
  std::string picked = clicked.out.substr(at + 13, clicked.out.find('"', at + 13) - (at + 13));
  for (const auto& [entity, text] : std::vector<std::pair<std::string, std::string>>{{"&quot;", "\""}, {"&lt;", "<"}, {"&gt;", ">"}, {"&amp;", "&"}}) {
    for (std::size_t k = picked.find(entity); k != std::string::npos; k = picked.find(entity, k + text.size())) {
      picked.replace(k, entity.size(), text);
    }
  }
  const nlohmann::json shown = nlohmann::json::parse(picked, nullptr, false);
  ASSERT_TRUE(shown.is_object()) << picked;
  EXPECT_EQ(shown["answer"]["state"], "surface");
  EXPECT_GT(shown["answer"]["mobility"].get<double>(), 0.9) << "the floor";
  const Reply direct = post(*c, "/api/query", nlohmann::json{{"points", {shown["centre"]}}}.dump());
  EXPECT_EQ(shown["answer"], direct.body["answers"][0]);
  EXPECT_EQ(server.stop(), 0);
}

// GET /api/layer: a level's elevation and mobility as the library makes them, at the
// finest power-of-two cell within `max`; headless Chromium draws it (?level=0) in
// elevation colours with the voxels hidden.
TEST_F(ServedCorridor, ALevelsElevationIsTheLibrarysAndTheViewerDrawsIt) {
  ServeProcess server({"serve", map(), "--port", "0"}, dir() + "/layer.err");
  const int port = server.port();
  ASSERT_GT(port, 0) << server.output();
  auto c = client(port);
  const mapping::MobilityMap library = mapping::openMap(map());
  const auto columns = library.surfaceColumns();
  const auto levels = mapping::layerLevels(*columns, 1.0);
  ASSERT_FALSE(levels.empty());
  for (const std::size_t max : {250000u, 2000u}) {
    const Reply r = get(*c, "/api/layer?level=0&max=" + std::to_string(max));
    ASSERT_EQ(r.status, 200) << r.raw.substr(0, 300);
    ASSERT_EQ(r.body["levels"].size(), levels.size());
    EXPECT_NEAR(r.body["z_m"].get<double>(), levels[0].z_m, 1e-5);
    const double cell = r.body["cell_m"];
    const mapping::LevelLayers want = mapping::levelLayers(*columns, levels[0], cell);
    ASSERT_EQ(r.body["cols"], want.cols);
    ASSERT_EQ(r.body["rows"], want.rows);
    EXPECT_LE(want.cols * want.rows, static_cast<int>(max) + want.cols + want.rows + 1);
    // The next finer cell would have been over `max` (unless this is the map's own).
    if (cell > library.tree().getResolution() * 1.5) {
      const mapping::LevelLayers finer = mapping::levelLayers(*columns, levels[0], cell / 2);
      EXPECT_GT(static_cast<std::size_t>(finer.cols) * finer.rows, max / 2);
    }
    for (int row = 0; row < want.rows; ++row) {
      for (int col = 0; col < want.cols; ++col) {
        const std::size_t at = want.index(row, col);
        const nlohmann::json& e = r.body["elevation"][row][col];
        ASSERT_EQ(e.is_null(), std::isnan(want.elevation[at])) << row << ", " << col;
        if (!e.is_null()) {
          ASSERT_EQ(static_cast<float>(e.get<double>()), want.elevation[at]);
        }
        const nlohmann::json& m = r.body["mobility"][row][col];
        ASSERT_EQ(m.is_null(), std::isnan(want.mobility[at]));
        if (!m.is_null()) {
          ASSERT_EQ(static_cast<float>(m.get<double>()), want.mobility[at]);
        }
      }
    }
  }
  EXPECT_EQ(get(*c, "/api/layer?level=" + std::to_string(levels.size())).status, 400);
  EXPECT_EQ(get(*c, "/api/layer?max=0").status, 400);
  EXPECT_EQ(get(*c, "/api/layer?max=abc").status, 400);
  EXPECT_EQ(get(*c, "/api/layer?max=1000001").status, 413);

  if (runShell("command -v chromium").code != 0) {
    GTEST_SKIP() << "chromium is not installed (scripts/setup.sh installs it): the level is not drawn";
  }
  const std::string url = "http://127.0.0.1:" + std::to_string(port) + "/?level=0";
  const std::string chromium = "timeout 600 chromium --headless --no-sandbox --use-angle=swiftshader "
                               "--enable-unsafe-swiftshader --hide-scrollbars --no-first-run --user-data-dir=" +
                               dir() + "/chromium-layer --window-size=800,600 --virtual-time-budget=30000 ";
  const Result dom = chromiumUntil(chromium + "--dump-dom '" + url + "'", "data-drawn-level=");
  ASSERT_NE(dom.out.find("data-drawn-level=\"0\""), std::string::npos) << dom.out.substr(0, 3000);
  const std::string png = dir() + "/level.png";
  const Result shot = chromiumUntil(chromium + "--screenshot=" + png + " '" + url + "'", "", png);
  ASSERT_TRUE(fs::exists(png)) << shot.out;
  const app::ImageRgb image = app::readPngRgb(png);
  std::size_t blue = 0, purple = 0, scene = 0;
  for (int y = 160; y < image.height; ++y) {  // below the panels
    for (int x = 0; x < image.width; ++x) {
      const auto& p = image.pixels[static_cast<std::size_t>(y) * static_cast<std::size_t>(image.width) + static_cast<std::size_t>(x)];
      ++scene;
      blue += p[2] > 150 && p[0] < 110 && p[1] < 140;
      purple += isViridisPurple(p);
    }
  }
  EXPECT_GT(static_cast<double>(blue) / scene, 0.10) << "the floor in the level's lowest colour";
  EXPECT_LT(static_cast<double>(purple) / scene, 0.002) << "the voxels (the walls' dark purple) are hidden";
  EXPECT_EQ(server.stop(), 0);
}

// serve --live: the frame count grows frame by frame while queries are answered (each
// frame waits for a line on the server's standard input), a snapshot answers as the map
// of the same frames built by `mobmap build`, and the saved map is served and answered
// as the CLI answers it.
TEST(ServeLive, FrameCountGrowsWhileQueriesAreAnswered) {
  const std::string dir = tempDir("live");
  const Result sim = mobmap("simulate --out " + dir + "/seq --frames 8 --noise none --quiet");
  ASSERT_EQ(sim.code, 0) << sim.out;
  ServeProcess server({"serve", "--live", dir + "/seq", "--out", dir + "/live.ot", "--port", "0", "--quiet"},
                      dir + "/live.err", {"MOBMAP_HOLD_FRAMES_ON_STDIN=1"});
  const int port = server.port();
  ASSERT_GT(port, 0) << server.output();
  auto c = client(port);
  std::vector<std::vector<double>> points;
  for (const auto& p : probePoints(0.5)) points.push_back({p[0], p[1], p[2]});
  const std::string request = nlohmann::json{{"points", points}, {"snap", 0.3}}.dump();

  // Asks /api/info until `frames` frames are in the map (the server says so; no clock).
  const auto waitForFrames = [&](int frames) {
    for (int polls = 0; polls < 1000000; ++polls) {
      const Reply r = get(*c, "/api/info");
      if (r.status != 200) return nlohmann::json();
      if (r.body["frames"] == frames) return r.body;
      EXPECT_LT(r.body["frames"].get<int>(), frames) << "frames fused before they were let go";
    }
    return nlohmann::json();
  };
  const nlohmann::json at_start = waitForFrames(0);
  ASSERT_TRUE(at_start.is_object());
  EXPECT_EQ(at_start["building"], true);
  EXPECT_EQ(at_start["surface_leaves"], 0);
  std::size_t surface_before = 0;
  for (int k = 1; k <= 8; ++k) {
    server.writeLine();  // let one more frame go
    const nlohmann::json info = waitForFrames(k);
    ASSERT_TRUE(info.is_object()) << "frame " << k;
    if (k < 8) {
      EXPECT_EQ(info["building"], true);  // after the last, the map may be saved already
    }
    EXPECT_GT(info["surface_leaves"].get<std::size_t>(), surface_before) << "frame " << k << " added nothing";
    surface_before = info["surface_leaves"].get<std::size_t>();
    const Reply r = post(*c, "/api/query", request);
    ASSERT_EQ(r.status, 200);
    EXPECT_EQ(r.body["frames"], k);
    ASSERT_EQ(r.body["answers"].size(), points.size());
    EXPECT_EQ(get(*c, "/api/camera_path").body["positions"].size(), static_cast<std::size_t>(k));
    if (k == 4) {
      // The snapshot answers as the map of frames 0..3 built by the CLI.
      const Result built = mobmap("build " + dir + "/seq --frames 0:3 --out " + dir + "/four.ot --quiet");
      ASSERT_EQ(built.code, 0) << built.out;
      const auto cli = cliAnswers(dir, "query " + dir + "/four.ot --json --snap 0.3", points);
      ASSERT_EQ(cli.size(), points.size());
      int surfaces = 0;
      for (std::size_t i = 0; i < points.size(); ++i) {
        const nlohmann::json& a = r.body["answers"][i];
        for (const char* field : {"state", "mobility", "variance", "count", "occupancy"}) {
          EXPECT_EQ(a.value(field, nlohmann::json()), cli[i].value(field, nlohmann::json())) << field << " at point " << i;
        }
        surfaces += cli[i]["state"] == "surface";
      }
      EXPECT_GT(surfaces, 20);
      // Height scans of the snapshot are the library's on the same map.
      const Reply scan = post(*c, "/api/height_scan", R"({"poses": [[1.5, 0, 0.45, 0], [2.5, 0.5, 0.45, 1]]})");
      ASSERT_EQ(scan.status, 200) << scan.raw;
      EXPECT_EQ(scan.body["frames"], 4);
      expectScanIs(scan.body, mapping::openMap(dir + "/four.ot").heightScan({{1.5, 0, 0.45, 0}, {2.5, 0.5, 0.45, 1}}));
    }
  }
  server.closeInput();
  ASSERT_NE(server.lineWith("saved "), "") << server.output();
  const Reply done = get(*c, "/api/info");
  EXPECT_EQ(done.body["frames"], 8);
  EXPECT_EQ(done.body["building"], false);
  EXPECT_EQ(done.body["metadata"]["frames"], 8);
  // The map on disk, served: the CLI's answers.
  const Reply r = post(*c, "/api/query", request);
  const auto cli = cliAnswers(dir, "query " + dir + "/live.ot --json --snap 0.3", points);
  ASSERT_EQ(cli.size(), points.size());
  for (std::size_t i = 0; i < points.size(); ++i) EXPECT_EQ(r.body["answers"][i], cli[i]) << "point " << i;
  EXPECT_EQ(server.stop(), 0);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mobmap::serve_test
