// MAP.json: the typed record round trips, keeps what it does not know, reads what older
// versions wrote, and names the entry that is wrong.
#include "mobmap/mapping/gravity.hpp"
#include "mobmap/mapping/map_metadata.hpp"
#include "mobmap/mapping/mobility_map.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <unistd.h>

#include <algorithm>
#include <functional>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>

namespace mobmap::mapping {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

// A run with every entry set, values chosen so that a field read into the wrong member
// or a number rounded on the way would show.
MapRun fullRun(double salt) {
  MapRun r;
  r.format = "mobmap-map-metadata";
  r.tool = "mobmap 9.9.9";
  r.tree_type = "MobilityOcTree";
  r.input = "/data/run" + std::to_string(static_cast<int>(salt));
  r.frames_in_run = 17 + static_cast<int>(salt);
  r.frames_selected = 40;
  r.keyframes = KeyframeRecord{0.05, 5.0 + salt, 33};
  r.skipped = "2 files without a pose";
  r.recovered = "12 of its 40 messages recovered from bag_0.db3-wal";
  r.depth_intrinsics = DepthCameraRecord{585.5, 586.25, 320.125, 240.0625, 640, 480};
  r.poses = "/data/poses.txt";
  r.max_pose_gap_s = 0.05;
  r.frames_without_pose = 3;
  r.unreadable = {"frame 4: bad CRC", "frame 9: truncated"};
  r.frame_numbers = std::array<long long, 2>{5, 900};
  r.interrupted = true;
  r.checkpoint = true;
  r.resolution_m = 0.02;
  r.gravity_down_world = Eigen::Vector3d(0.1, 1.0 / 3.0, -0.9).normalized();
  r.gravity_source = "gravity-direction.txt";
  r.gravity_given_world = Eigen::Vector3d(0.0, 0.07, -0.99);
  r.gravity_floor_angle_deg = 3.7;
  r.R_map_world = gravityAlignment(*r.gravity_down_world);
  r.origin_world = Eigen::Vector3d(500100.0, -1e-17, 2.5 + salt);
  r.origin_source = "--origin";
  r.points_outside_map = 123456789012LL;
  r.frames_outside_map = 2;
  r.depth_units_per_m = 5000.0;
  r.points_in_view = 9876543210LL;
  r.points_beyond_range = 12345;
  r.seconds = 12.345678901234567;
  r.frames_per_second = 1.0 / 7.0;
  r.perception = PerceptionRecord{3.0, 0.02, 30, 16, 12.5, 13, 125, 0.05, 0.1, 38, 25, 8};
  r.mapping = MappingRecord{0.02, 4.0, 3, 20000.0, false};
  r.model = ModelRecord{std::string("gp"), std::string("paper"), 1.0, 0.1, 0.05};
  r.config = "/etc/mobmap.json";
  return r;
}

// Field by field, through their JSON form (what a reader of the file sees), and the
// members that hold no JSON.
void expectSameRun(const MapRun& a, const MapRun& b) {
  MapMetadata ma, mb;
  ma.latest = a;
  mb.latest = b;
  EXPECT_EQ(Json::parse(formatMapMetadata(ma)), Json::parse(formatMapMetadata(mb)));
  EXPECT_EQ(a.interrupted, b.interrupted);
  EXPECT_EQ(a.checkpoint, b.checkpoint);
  EXPECT_EQ(a.R_map_world.has_value(), b.R_map_world.has_value());
  if (a.R_map_world && b.R_map_world) {
    EXPECT_TRUE(*a.R_map_world == *b.R_map_world);  // bit for bit
  }
  EXPECT_EQ(a.origin_world.has_value(), b.origin_world.has_value());
  if (a.origin_world && b.origin_world) {
    EXPECT_TRUE(*a.origin_world == *b.origin_world);
  }
}

std::size_t lineCount(const std::string& t) { return static_cast<std::size_t>(std::count(t.begin(), t.end(), '\n')); }

TEST(MapMetadata, EveryEntryRoundTripsBitForBit) {
  MapMetadata m;
  m.latest = fullRun(2);
  m.earlier_runs = {fullRun(0), fullRun(1)};
  m.earlier_runs[0].other_entries = R"({"lab_note":"first floor","weights":[1,2]})";
  m.latest.other_entries = R"({"future_key":{"a":1}})";
  m.frames = 17 + 18 + 19;
  m.trajectory_map = {{0.1, -2.5, 1e-17}, {1.0 / 3.0, 2.0, 3.0}, {4.0, 5.0, -6.0}};
  const std::string text = formatMapMetadata(m);
  const MapMetadata back = parseMapMetadata(text, "m.json");
  EXPECT_TRUE(back.found);
  EXPECT_EQ(back.frames, m.frames);
  ASSERT_EQ(back.trajectory_map.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_TRUE(back.trajectory_map[i] == m.trajectory_map[i]) << i;
  ASSERT_EQ(back.earlier_runs.size(), 2u);
  expectSameRun(back.latest, m.latest);
  expectSameRun(back.earlier_runs[0], m.earlier_runs[0]);
  expectSameRun(back.earlier_runs[1], m.earlier_runs[1]);
  // Every entry was read into its own member: only the unknown ones are left over.
  EXPECT_EQ(back.earlier_runs[1].other_entries, "");
  EXPECT_EQ(Json::parse(back.earlier_runs[0].other_entries), Json::parse(m.earlier_runs[0].other_entries));
  EXPECT_EQ(Json::parse(back.latest.other_entries), Json::parse(m.latest.other_entries));
  EXPECT_EQ(back.latest.config, m.latest.config);
  EXPECT_EQ(back.latest.depth_intrinsics->cy, 240.0625);
  EXPECT_EQ(back.latest.perception->rough_smoothing_k, 8);
  EXPECT_EQ(back.latest.frames_per_second, 1.0 / 7.0);
  // Written again: the same bytes.
  EXPECT_EQ(formatMapMetadata(back), text);
  // Entries this version does not know are kept where they were.
  const Json j = Json::parse(text);
  EXPECT_EQ(j["future_key"]["a"], 1);
  EXPECT_EQ(j["earlier_runs"][0]["lab_note"], "first floor");
  EXPECT_FALSE(j["earlier_runs"][1].contains("lab_note"));
  EXPECT_EQ(j["frames_unreadable"], 2);  // the length of "unreadable"
  // The map frame the readers use.
  EXPECT_TRUE(back.hasFrame());
  EXPECT_LT((back.R_map_world() - *m.latest.R_map_world).norm(), 1e-15);
  EXPECT_TRUE(back.originWorld() == *m.latest.origin_world);
  EXPECT_EQ(back.runStarts(), (std::vector<std::size_t>{0, 17, 35}));
  ASSERT_EQ(back.runs().size(), 3u);
  EXPECT_EQ(back.runs().back(), &back.latest);
}

TEST(MapMetadata, OneLinePerCameraPositionAndNothingUnsetIsWritten) {
  MapMetadata m;
  m.frames = 2;
  const std::string empty_path = formatMapMetadata(m);
  // A run that recorded nothing: "frames", "interrupted" and an empty camera path.
  EXPECT_EQ(Json::parse(empty_path), (Json{{"frames", 2}, {"interrupted", false}, {"trajectory_map", Json::array()}}));
  m.trajectory_map = {{1, 2, 3}, {0.1, -2.5, 1e-17}};
  const std::string text = formatMapMetadata(m);
  EXPECT_EQ(lineCount(text), lineCount(empty_path) + 3);  // two rows and the closing bracket
  EXPECT_NE(text.find("\n  [0.1,-2.5,1e-17]\n ]\n}\n"), std::string::npos) << text;
  EXPECT_EQ(formatMapMetadata(parseMapMetadata(text, "m.json")), text);
}

// What a map from before runs, origins and the typed record looked like: read as it is,
// and extended into a record that counts its frames as its one run's.
TEST(MapMetadata, ReadsWhatOlderVersionsWroteAndExtendsIt) {
  const Json old{{"format", "mobmap-map-metadata"},
                 {"tool", "mobmap 0.3.0"},
                 {"frames", 12},
                 {"input", "/data/kitchen"},
                 {"R_map_world", {{1, 0, 0}, {0, 0, -1}, {0, 1, 0}}},
                 {"perception", {{"max_range_m", 3.0}}},
                 {"trajectory_map", {{0, 0, 1}, {0.5, 0, 1}}}};
  MapMetadata m = parseMapMetadata(old.dump(1), "old.json");
  EXPECT_EQ(m.frames, 12);
  EXPECT_FALSE(m.latest.frames_in_run);
  EXPECT_FALSE(m.latest.origin_world);
  EXPECT_TRUE(m.originWorld() == Eigen::Vector3d::Zero());
  EXPECT_FALSE(m.gravityDownWorld());
  ASSERT_TRUE(m.latest.perception);
  EXPECT_EQ(m.latest.perception->max_range_m, 3.0);
  EXPECT_FALSE(m.latest.perception->voxel_size_m);
  EXPECT_TRUE(m.R_map_world().isApprox(Eigen::Matrix3d(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()))));
  EXPECT_TRUE(m.latest.other_entries.empty());

  MapRun next;
  next.input = "/data/kitchen2";
  next.frames_in_run = 5;
  m.addRun(next, {{1, 0, 1}, {1.5, 0, 1}, {2, 0, 1}, {2.5, 0, 1}, {3, 0, 1}});
  EXPECT_EQ(m.frames, 17);
  ASSERT_EQ(m.earlier_runs.size(), 1u);
  EXPECT_EQ(m.earlier_runs[0].frames_in_run, 12);  // an old map's frames are its one run's
  EXPECT_EQ(m.earlier_runs[0].input, "/data/kitchen");
  EXPECT_EQ(m.latest.input, "/data/kitchen2");
  EXPECT_EQ(m.trajectory_map.size(), 7u);
  EXPECT_EQ(m.runStarts(), (std::vector<std::size_t>{0, 12}));
  const Json j = Json::parse(formatMapMetadata(m));
  EXPECT_EQ(j["frames"], 17);
  EXPECT_FALSE(j["earlier_runs"][0].contains("trajectory_map"));
  EXPECT_FALSE(j["earlier_runs"][0].contains("frames"));
  EXPECT_EQ(j["earlier_runs"][0]["R_map_world"], old["R_map_world"]);
}

// Every entry of the wrong type is refused with the file and the entry named.
TEST(MapMetadata, AMalformedEntryIsNamed) {
  MapMetadata good;
  good.latest = fullRun(0);
  good.earlier_runs = {fullRun(1)};
  good.frames = 35;
  good.trajectory_map = {{0, 0, 0}};
  const Json base = Json::parse(formatMapMetadata(good));
  ASSERT_NO_THROW(parseMapMetadata(base.dump(), "m.json"));
  int cases = 0;
  const auto refused = [&](const std::function<void(Json&)>& edit, const std::string& message) {
    ++cases;
    Json j = base;
    edit(j);
    try {
      parseMapMetadata(j.dump(), "dir/m.json");
      ADD_FAILURE() << "accepted: " << j.dump().substr(0, 300);
    } catch (const MapIoError& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind("dir/m.json: ", 0), 0u) << what;
      EXPECT_NE(what.find(message), std::string::npos) << what << "\nexpected: " << message;
    }
  };
  // Every top-level entry given a value of no type any entry takes: an object of an
  // object where a scalar goes, a string where an object or list goes.
  for (const auto& item : base.items()) {
    const std::string key = item.key();
    const Json wrong = item.value().is_object() || item.value().is_array() ? Json("x") : Json{{"a", {{"b", 1}}}};
    refused([&](Json& j) { j[key] = wrong; }, "\"" + key + "\"");
  }
  // And inside the records, the earlier runs' too.
  for (const char* record : {"keyframes", "depth_intrinsics", "perception", "mapping", "model"}) {
    for (const auto& item : base[record].items()) {
      const std::string key = item.key();
      refused([&](Json& j) { j[record][key] = Json::array(); }, "\"" + std::string(record) + "\": \"" + key + "\"");
      refused([&](Json& j) { j["earlier_runs"][0][record][key] = Json::array(); },
              "\"earlier_runs\" entry 0: \"" + std::string(record) + "\": \"" + key + "\"");
    }
  }
  refused([](Json& j) { j["frames"] = -3; }, "\"frames\" must be a non-negative whole number");
  refused([](Json& j) { j["frames"] = 4294967296LL; }, "\"frames\" must be a non-negative whole number");
  refused([](Json& j) { j["frames_selected"] = 1.5; }, "\"frames_selected\" must be a non-negative whole number");
  refused([](Json& j) { j["frame_numbers"] = {1, 2, 3}; }, "\"frame_numbers\" must be [first, last]");
  refused([](Json& j) { j["R_map_world"] = {{-1, 0, 0}, {0, 1, 0}, {0, 0, 1}}; }, "reflection");
  refused([](Json& j) { j["gravity_down_world"] = {0, 0, 0}; }, "\"gravity_down_world\" must be [x, y, z], finite and not zero");
  refused([](Json& j) { j["origin_world"] = {1, 2}; }, "\"origin_world\" must be [x, y, z], finite");
  refused([](Json& j) { j["unreadable"] = {"a", 2}; }, "\"unreadable\" must be a list of strings");
  refused([](Json& j) { j["trajectory_map"][0] = {1e300, 0, 0}; }, "\"trajectory_map\" entry 0");
  refused([](Json& j) { j["earlier_runs"][0] = 5; }, "\"earlier_runs\" entry 0: must be a run record");
  refused([](Json& j) { j["earlier_runs"][0]["frames_in_run"] = -1; },
          "\"earlier_runs\" entry 0: \"frames_in_run\" must be a non-negative whole number");
  refused([](Json& j) { j = Json::array({1, 2}); }, "expected a JSON object");
  EXPECT_GT(cases, 60);
  try {
    parseMapMetadata("{\"frames\": 1,", "m.json");
    ADD_FAILURE() << "accepted truncated JSON";
  } catch (const MapIoError& e) {
    EXPECT_NE(std::string(e.what()).find("m.json: not valid JSON"), std::string::npos) << e.what();
  }
}

// Nesting is bounded before parsing: 100,000 nested objects, even under a key nobody
// reads, overflowed the stack when the parsed value was copied.
TEST(MapMetadata, NestingPastTheLimitIsRefusedBeforeParsing) {
  MapMetadata good;
  good.latest = fullRun(0);
  std::string text = formatMapMetadata(good);
  text.resize(text.rfind('}'));
  const auto nested = [](int depth) { return std::string(depth, '[') + "1" + std::string(depth, ']'); };
  try {
    parseMapMetadata(text + ", \"extra\": " + nested(100000) + "}", "dir/deep.json");
    ADD_FAILURE() << "accepted 100,000 levels";
  } catch (const MapIoError& e) {
    EXPECT_NE(std::string(e.what()).find("dir/deep.json: not a map metadata file: arrays and objects are nested more than 64 deep"),
              std::string::npos)
        << e.what();
  }
  // 64 levels under an unknown key are kept, as any unknown entry is.
  const MapMetadata kept = parseMapMetadata(text + ", \"extra\": " + nested(63) + "}", "m.json");
  EXPECT_NE(kept.latest.other_entries.find(nested(63)), std::string::npos);
  // A NUL byte and what follows it is not taken for the end of the file.
  EXPECT_THROW(parseMapMetadata(formatMapMetadata(good) + std::string(1, '\0') + "junk", "m.json"), MapIoError);
}

// A MAP.json beside a map it does not describe (another resolution or tree type): its
// origin and rotation would be put on the wrong voxels.
TEST(MapMetadata, OneThatDescribesAnotherMapIsRefused) {
  MapMetadata meta;
  meta.found = true;
  meta.path = "dir/m.json";
  meta.latest.resolution_m = 0.04;
  const auto openWith = [&](const MapMetadata& m) { return openMap(std::make_unique<MobilityOcTree>(0.02), m); };
  try {
    (void)openWith(meta);
    ADD_FAILURE() << "opened a 2 cm tree with a MAP.json of 4 cm voxels";
  } catch (const MapIoError& e) {
    EXPECT_NE(std::string(e.what()).find("dir/m.json: records 0.04 m voxels, but the map beside it has 0.02 m voxels"),
              std::string::npos)
        << e.what();
  }
  meta.latest.resolution_m = 0.02;
  meta.latest.tree_type = "ColorOcTree";
  EXPECT_THROW((void)openWith(meta), MapIoError);
  meta.latest.tree_type = MobilityOcTree::kTreeType;
  EXPECT_NO_THROW((void)openWith(meta));
}

TEST(MapMetadata, SavedAtomicallyAndReadBesideTheMap) {
  const fs::path dir = fs::temp_directory_path() / ("mobmap_meta_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string ot = (dir / "m.ot").string();
  const MapMetadata none = readMapMetadata(ot);
  EXPECT_FALSE(none.found);
  EXPECT_EQ(none.path, (dir / "m.json").string());
  EXPECT_FALSE(none.hasFrame());
  MapMetadata m;
  m.latest = fullRun(3);
  m.frames = 20;
  saveMapMetadata(m, none.path);
  const MapMetadata back = readMapMetadata(ot);
  EXPECT_TRUE(back.found);
  EXPECT_EQ(formatMapMetadata(back), formatMapMetadata(m));
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += (void(e), 1);
  EXPECT_EQ(files, 1u);  // no temporary file left behind
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mobmap::mapping
