// `mobmap build` on ROS 2 bags written by implementations other than mobmap's: MCAP by
// the npm registry's @mcap/core, CDR by @foxglove/rosmsg2-serialization, .db3 by
// Python's sqlite3 (tests/recordings). Each must give the map the same frames give in
// the 7-Scenes layout, and each kind of broken recording a clear error or warning.
#include "bags_support.hpp"

#include <set>

namespace mobmap::cli_test {
namespace {

TEST_F(Bags, McapInEveryLayoutGivesTheSevenScenesMapByteForByte) {
  const std::vector<std::pair<std::string, std::string>> variants = {
      {"zstd", "--chunks zstd"},
      {"lz4", "--chunks lz4"},
      {"plain-no-summary", "--chunks plain --summary no"},
      {"unchunked", "--chunks none"},
      {"unchunked-no-summary", "--chunks none --summary no"},
      {"compressed-depth", "--depth compressed16"},
      {"colour-beside", "--colour"},
  };
  for (const auto& [name, options] : variants) {
    SCOPED_TRACE(name);
    const std::string bag = writeBag(name + ".mcap", options);
    const Result r = build(bag, dir_ + "/" + name + ".ot");
    ASSERT_EQ(r.code, 0) << r.out;
    EXPECT_EQ(fileBytes(dir_ + "/" + name + ".ot"), fileBytes(ref())) << "the map differs from the 7-Scenes layout's";
  }
}

TEST_F(Bags, SqliteBagFolderAndFileGiveTheSameMap) {
  const std::string bag = writeDb3("db3bag", "--layout camera");
  for (const std::string& input : {bag, bag + "/db3bag_0.db3"}) {
    SCOPED_TRACE(input);
    const Result r = build(input, dir_ + "/db3.ot", "--force");
    ASSERT_EQ(r.code, 0) << r.out;
    EXPECT_EQ(fileBytes(dir_ + "/db3.ot"), fileBytes(ref()));
  }
}

// The camera on a moving base: map -> odom (turned and shifted), odom -> base_link
// sampled 5 ms either side of each image (interpolating to its true pose), and the
// static mounting base_link -> camera_link -> optical frame on /tf_static.
TEST_F(Bags, CameraOnAMovingBaseIsPosedThroughTheTfChain) {
  for (const std::string world : {"map", "odom"}) {
    SCOPED_TRACE(world);
    const std::string bag = writeBag("base-" + world + ".mcap", "--layout base --world " + world);
    const std::string out = dir_ + "/base-" + world + ".ot";
    const Result r = build(bag, out);
    ASSERT_EQ(r.code, 0) << r.out;
    EXPECT_EQ(fileBytes(out), fileBytes(ref()));
    const auto meta = nlohmann::json::parse(fileBytes(dir_ + "/base-" + world + ".json"));
    EXPECT_EQ(meta["world_frame"], world);
    EXPECT_EQ(meta["depth_topic"], "/camera/depth/image_raw");
    EXPECT_EQ(meta["camera_info_topic"], "/camera/depth/camera_info");
    EXPECT_NE(meta["gravity_source"].get<std::string>().find("REP 105"), std::string::npos) << meta["gravity_source"];
  }
  const std::string bag = writeDb3("base-db3", "--layout base");
  const Result r = build(bag, dir_ + "/base-db3.ot");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(fileBytes(dir_ + "/base-db3.ot"), fileBytes(ref()));
}

// --poses replaces the TF tree: a TUM trajectory matched to the images' stamps.
TEST_F(Bags, PosesGivenReplaceTheTfTree) {
  const std::string bag = writeBag("poses.mcap", "--layout base --world tilted --tilt 30");
  std::ofstream tum(dir_ + "/poses.txt");
  tum.precision(17);
  for (int i = 0; i < 12; ++i) {
    char name[64];
    std::snprintf(name, sizeof name, "/seq/frame-%06d.pose.txt", i);
    std::ifstream in(dir_ + name);
    Eigen::Matrix4d m;
    for (int k = 0; k < 16; ++k) in >> m(k / 4, k % 4);
    const Eigen::Quaterniond q(Eigen::Matrix3d(m.topLeftCorner<3, 3>()));
    // The images' stamps (1700000000 s + i / 30 s in nanoseconds, as write_bag.mjs rounds
    // them) in seconds, as the trajectory is looked up.
    const auto ns = 1700000000LL * 1000000000LL + std::llround(i * 1e9 / 30.0);
    tum << static_cast<double>(ns) * 1e-9 << " " << m(0, 3) << " " << m(1, 3) << " " << m(2, 3) << " " << q.x()
        << " " << q.y() << " " << q.z() << " " << q.w() << "\n";
  }
  tum.close();
  const Result r = build(bag, dir_ + "/poses.ot", "--poses " + dir_ + "/poses.txt --gravity 0,0,-1");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(leafCount(dir_ + "/poses.ot"), leafCount(ref()));
  const auto meta = nlohmann::json::parse(fileBytes(dir_ + "/poses.json"));
  EXPECT_EQ(meta["frames"], 12);
  EXPECT_FALSE(meta.contains("skipped")) << meta["skipped"];
  EXPECT_FALSE(meta.contains("world_frame"));
  EXPECT_TRUE(meta.contains("poses"));
}

// analyze and overlay read a bag's frame N as build numbers it: the same answers as the
// 7-Scenes layout's frame N (the bag has no colour images: the overlays are drawn on depth).
TEST_F(Bags, AnalyzeAndOverlayReadTheBagsFrames) {
  const std::string bag = writeBag("analyze.mcap", "--layout base");
  auto withoutTimes = [](nlohmann::json j) {
    j.erase("input");
    j.erase("total_ms");
    for (auto& stage : j["stages"]) stage.erase("ms");
    return j;
  };
  const Result a = run("analyze " + bag + " --frame 4 --json");
  const Result b = run("analyze " + dir_ + "/seq --frame 4 --json");
  ASSERT_EQ(a.code, 0) << a.out;
  ASSERT_EQ(b.code, 0) << b.out;
  EXPECT_EQ(withoutTimes(jsonLine(a.out)), withoutTimes(jsonLine(b.out)));
  ASSERT_EQ(build(bag, dir_ + "/analyze.ot").code, 0);
  const Result o1 = run("overlay " + dir_ + "/analyze.ot --frame 4 --background depth --out " + dir_ + "/bag-overlay.png");
  const Result o2 = run("overlay " + ref() + " --frame 4 --background depth --out " + dir_ + "/ref-overlay.png");
  ASSERT_EQ(o1.code, 0) << o1.out;
  ASSERT_EQ(o2.code, 0) << o2.out;
  EXPECT_EQ(fileBytes(dir_ + "/bag-overlay.png"), fileBytes(dir_ + "/ref-overlay.png"));
}

// ROS 1 bags written by Debian's rosbag_storage with the sensor_msgs and tf2_msgs types.
TEST_F(Bags, Ros1BagsInEveryCompressionGiveTheSameMap) {
#ifndef MOBMAP_WRITE_BAG1
  GTEST_SKIP() << "the ROS 1 bag writer is not built (librosbag-storage-dev is not installed)";
#else
  // The pre-tf2 TF type (tf/tfMessage, as in the TUM RGB-D dataset's bags) poses the frames as tf2's does.
  for (const std::string options : {"--compression none", "--compression bz2", "--compression lz4", "--layout base",
                                    "--tf old", "--tf old --layout base", "--layout base --world odom"}) {
    SCOPED_TRACE(options);
    const std::string bag = dir_ + "/ros1.bag";
    const Result w = runShell(std::string(MOBMAP_WRITE_BAG1) + " --seq " + dir_ + "/seq --out " + bag + " " + options);
    ASSERT_EQ(w.code, 0) << w.out;
    const Result r = build(bag, dir_ + "/ros1.ot", "--force");
    ASSERT_EQ(r.code, 0) << r.out;
    EXPECT_EQ(fileBytes(dir_ + "/ros1.ot"), fileBytes(ref()));
  }
  const Result info = run("info " + dir_ + "/ros1.bag --json");
  ASSERT_EQ(info.code, 0) << info.out;
  EXPECT_EQ(jsonLine(info.out)["format"], "ROS 1 bag");
  EXPECT_EQ(jsonLine(info.out)["world_frame"], "odom");
  EXPECT_FALSE(jsonLine(info.out).contains("recovered")) << info.out;  // closed with its index: nothing to say
  // Cut short, a ROS 1 bag has lost its index (written at its end): its chunks are read
  // one after another up to the cut, and the warning says so.
  const std::string bytes = fileBytes(dir_ + "/ros1.bag");
  std::ofstream(dir_ + "/cut.bag", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  const Result cut = build(dir_ + "/cut.bag", dir_ + "/cut.ot");
  ASSERT_EQ(cut.code, 0) << cut.out;
  EXPECT_NE(cut.out.find("recovered: " + dir_ + "/cut.bag: a ROS 1 bag without its index"), std::string::npos) << cut.out;
  EXPECT_NE(cut.out.find("warning: the recording ends early (" + dir_ + "/cut.bag: "), std::string::npos) << cut.out;
  const auto meta = nlohmann::json::parse(fileBytes(dir_ + "/cut.json"));
  EXPECT_GT(meta["frames"].get<int>(), 2);
  EXPECT_LT(meta["frames"].get<int>(), 12);
  EXPECT_NE(meta["recovered"].get<std::string>().find("as `rosbag reindex` would"), std::string::npos);
#endif
}

// A world frame that is not z up: gravity from the IMU's still readings, taken to the
// world frame through TF; moving readings (3 m/s^2 more than g) are left out.
TEST_F(Bags, ImuGivesGravityWhenTheWorldFrameDoesNot) {
  const std::string bag = writeBag("imu.mcap", "--world tilted --tilt 20 --imu");
  const Result r = build(bag, dir_ + "/imu.ot");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto meta = nlohmann::json::parse(fileBytes(dir_ + "/imu.json"));
  EXPECT_EQ(meta["world_frame"], "tilted");  // the root of the camera's tree
  const double a = 20.0 * M_PI / 180.0;
  const auto& down = meta["gravity_down_world"];
  EXPECT_NEAR(down[0].get<double>(), 0.0, 1e-6);
  EXPECT_NEAR(down[1].get<double>(), std::sin(a), 1e-6);
  EXPECT_NEAR(down[2].get<double>(), -std::cos(a), 1e-6);
  EXPECT_NE(meta["gravity_source"].get<std::string>().find("the IMU on /camera/imu (12 of 24 readings taken while still"),
            std::string::npos)
      << meta["gravity_source"];
  // The same map as the 7-Scenes layout's, leaf for leaf: the map frame is z up either way.
  EXPECT_EQ(leafCount(dir_ + "/imu.ot"), leafCount(ref()));
  // Asked for by name where the world frame would have given it.
  const Result named = run("info " + writeBag("imu-map.mcap", "--imu") + " --imu-topic /camera/imu --json");
  ASSERT_EQ(named.code, 0) << named.out;
  EXPECT_NE(jsonLine(named.out)["gravity_source"].get<std::string>().find("the IMU on /camera/imu"), std::string::npos);
  const Result missing = build(dir_ + "/imu-map.mcap", dir_ + "/none.ot", "--imu-topic /imu/data");
  EXPECT_EQ(missing.code, 1) << missing.out;
  EXPECT_NE(missing.out.find("has no Imu topic /imu/data (its Imu topics: /camera/imu)"), std::string::npos) << missing.out;
}

// A bag is read as it is fused: memory does not grow with its length. The long bag holds
// 20 times the images of the short one (over 80 MB more, more than the map takes).
TEST_F(Bags, MemoryDoesNotGrowWithTheRecordingsLength) {
  const std::string shorter = writeBag("short.mcap", "--chunks lz4");
  const std::string longer = writeBag("long.mcap", "--chunks lz4 --repeat 20");
  const auto extra_kib = static_cast<long>((fs::file_size(longer) - fs::file_size(shorter)) / 1024);
  ASSERT_GT(extra_kib, 60 * 1024);
  const long info_short = peakRssKib("info " + shorter), info_long = peakRssKib("info " + longer);
  ASSERT_GT(info_short, 0);
  ASSERT_GT(info_long, 0);
  EXPECT_LT(info_long - info_short, 8 * 1024) << "info: " << info_short << " KiB for the short bag, " << info_long << " for the long";
  // The same 4 images fused from either bag.
  const long build_short = peakRssKib("build " + shorter + " --out " + dir_ + "/mem-short.ot --voxel 0.02 --frames 0:11:3");
  const long build_long = peakRssKib("build " + longer + " --out " + dir_ + "/mem-long.ot --voxel 0.02 --frames 0:11:3");
  ASSERT_GT(build_short, 0);
  ASSERT_GT(build_long, 0);
  EXPECT_LT(build_long - build_short, 8 * 1024) << "build: " << build_short << " KiB, " << build_long << " KiB";
  EXPECT_EQ(fileBytes(dir_ + "/mem-short.ot"), fileBytes(dir_ + "/mem-long.ot"));
}

// `info RECORDING` lists the topics and the TF tree, and what build would choose.
TEST_F(Bags, InfoDescribesTheRecordingAndWhatBuildWouldRead) {
  const std::string bag = writeBag("info.mcap", "--layout base --colour");
  Result r = run("info " + bag + " --json");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto j = jsonLine(r.out);
  EXPECT_EQ(j["format"], "ROS 2 bag (MCAP)");
  std::map<std::string, std::pair<std::string, int>> topics;
  for (const auto& t : j["topics"]) topics[t["name"]] = {t["type"], t["count"]};
  EXPECT_EQ(topics["/camera/depth/image_raw"], std::make_pair(std::string("sensor_msgs/Image"), 12));
  EXPECT_EQ(topics["/camera/color/image_raw"], std::make_pair(std::string("sensor_msgs/Image"), 12));
  EXPECT_EQ(topics["/tf"], std::make_pair(std::string("tf2_msgs/TFMessage"), 24));
  EXPECT_EQ(topics["/tf_static"].second, 1);
  std::set<std::string> links;
  for (const auto& e : j["tf"]) links.insert(e["parent"].get<std::string>() + (e["static"] ? " => " : " -> ") + e["child"].get<std::string>());
  EXPECT_EQ(links, (std::set<std::string>{"map -> odom", "odom -> base_link", "base_link => camera_link",
                                          "camera_link => camera_depth_optical_frame"}));
  EXPECT_EQ(j["depth_topic"], "/camera/depth/image_raw");
  EXPECT_EQ(j["camera_info_topic"], "/camera/depth/camera_info");
  EXPECT_EQ(j["world_frame"], "map");
  EXPECT_EQ(j["camera_frame"], "camera_depth_optical_frame");
  EXPECT_EQ(j["frames"], 12);
  // What build cannot choose is said, not refused: the recording itself was read.
  r = run("info " + writeBag("info-two.mcap", "--second-camera") + " --json");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(jsonLine(r.out)["problem"].get<std::string>().find("2 depth image topics"), std::string::npos) << r.out;
  r = run("info " + bag);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("frames             12 of 12 depth images have a pose"), std::string::npos) << r.out;
  // A camera_info with distortion: undone (sources_test checks how), and said.
  r = run("info " + writeBag("distorted.mcap", "--frames 2 --distortion -0.1,0.01,0,0,0") + " --json");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(jsonLine(r.out)["distortion"], "plumb_bob distortion (k1 -0.1, k2 0.01, p1 0, p2 0, k3 0) undone");
}

// Depth in metres (32FC1, and compressedDepth's quantised inverse depth) is not the
// millimetres of the PNGs to the last bit: the same voxels, nearly, with the same mobility.
TEST_F(Bags, DepthInMetresGivesTheSameVoxels) {
  const auto reference = leaves(ref());
  ASSERT_GT(reference.size(), 1000u);
  for (const std::string depth : {"32FC1", "compressed32"}) {
    SCOPED_TRACE(depth);
    const std::string bag = writeBag(depth + ".mcap", "--depth " + depth);
    const Result r = build(bag, dir_ + "/" + depth + ".ot");
    ASSERT_EQ(r.code, 0) << r.out;
    const auto got = leaves(dir_ + "/" + depth + ".ot");
    std::size_t common = 0;
    double diff = 0.0;
    for (const auto& [key, m] : got) {
      const auto it = reference.find(key);
      if (it == reference.end()) continue;
      ++common;
      diff += std::abs(it->second - m);
    }
    const double share = static_cast<double>(common) / static_cast<double>(std::max(reference.size(), got.size()));
    EXPECT_GT(share, 0.97) << common << " voxels in common of " << reference.size() << " and " << got.size();
    EXPECT_LT(diff / static_cast<double>(common), 0.02);
  }
}

TEST_F(Bags, TopicsAreChosenOrAskedFor) {
  const std::string bag = writeBag("two-cameras.mcap", "--second-camera --colour");
  Result r = build(bag, dir_ + "/two.ot");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("2 depth image topics"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("/camera/depth/image_raw, /camera2/depth/image_raw"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("--depth-topic"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(dir_ + "/two.ot"));
  // The second camera's own camera_info (its namespace) is taken with it: the same
  // frames and poses, its intrinsics are the first camera's, so the same map.
  r = build(bag, dir_ + "/two.ot", "--depth-topic /camera2/depth/image_raw");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(fileBytes(dir_ + "/two.ot"), fileBytes(ref()));
  EXPECT_EQ(nlohmann::json::parse(fileBytes(dir_ + "/two.json"))["camera_info_topic"], "/camera2/depth/camera_info");
  // A colour topic is not depth.
  r = build(bag, dir_ + "/colour.ot", "--depth-topic /camera/color/image_raw");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("\"rgb8\" images, not depth"), std::string::npos) << r.out;
  r = build(bag, dir_ + "/colour.ot", "--depth-topic /nothing");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("has no image topic /nothing (its image topics: "), std::string::npos) << r.out;
  r = build(bag, dir_ + "/colour.ot", "--depth-topic /camera/depth/image_raw --camera-info-topic /none");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("has no camera_info topic /none (its camera_info topics: "), std::string::npos) << r.out;
  r = build(bag, dir_ + "/colour.ot", "--depth-topic /camera/depth/image_raw --world-frame base");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("--world-frame base is not in the TF tree (its frames: camera_depth_optical_frame, map)"), std::string::npos)
      << r.out;
  EXPECT_FALSE(fs::exists(dir_ + "/colour.ot"));
}

TEST_F(Bags, WrongRecordingsAreRefusedNamingTheFileAndTheProblem) {
  const std::vector<std::array<std::string, 3>> cases = {
      {"bigendian", "", "its pixels are big-endian"},
      {"step", "", "its step is 1278 bytes, less than a row of 640 16UC1 pixels (1280)"},
      {"size", "", "the image is 640x480 but its camera_info (/camera/depth/camera_info) is for 320x240"},
      {"cycle", "--layout base --world odom", "the TF tree has a cycle: "},
      {"no-static", "--layout base --world odom", "the recording has no /tf_static"},
      {"two-parents", "--layout base", "frame \"camera_link\" has two parents, \"base_link\" and \"odom\""},
  };
  for (const auto& [fault, options, message] : cases) {
    SCOPED_TRACE(fault);
    const std::string bag = writeBag("fault-" + fault + ".mcap", "--frames 3 --fault " + fault + " " + options);
    const Result r = build(bag, dir_ + "/fault.ot");
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_NE(r.out.find("error: " + bag + ": "), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(message), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(dir_ + "/fault.ot"));
  }
}

// A recording whose bytes end early or fail a check is read up to that point: the
// frames before it are mapped, and a warning (and MAP.json) says where it ended.
TEST_F(Bags, DamagedBytesEndTheRecordingWhereTheyAre) {
  const std::string bag = writeBag("plain.mcap", "--chunks plain --summary no");
  const std::string bytes = fileBytes(bag);
  struct Damage {
    std::string name, expect;
    std::function<std::string(std::string)> apply;
  };
  const std::vector<Damage> damages = {
      {"cut", "cut short", [](std::string b) { return b.substr(0, b.size() / 2); }},
      {"crc", "fail their CRC", [](std::string b) { b[b.size() / 2] = static_cast<char>(b[b.size() / 2] ^ 0x5a); return b; }},
  };
  for (const auto& d : damages) {
    SCOPED_TRACE(d.name);
    const std::string damaged = dir_ + "/damaged-" + d.name + ".mcap";
    std::ofstream(damaged, std::ios::binary) << d.apply(bytes);
    const std::string out = dir_ + "/damaged-" + d.name + ".ot";
    const Result r = build(damaged, out);
    ASSERT_EQ(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("warning: the recording ends early (" + damaged + ": "), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(d.expect), std::string::npos) << r.out;
    const auto meta = nlohmann::json::parse(fileBytes(dir_ + "/damaged-" + d.name + ".json"));
    EXPECT_GT(meta["frames"].get<int>(), 0);
    EXPECT_LT(meta["frames"].get<int>(), 12);
    EXPECT_NE(meta["skipped"].get<std::string>().find("ends early"), std::string::npos);
  }
  // Damage in a compressed chunk fails its decompression or its CRC.
  std::string zstd = fileBytes(writeBag("zstd-damaged.mcap", "--chunks zstd"));
  zstd[zstd.size() / 3] = static_cast<char>(zstd[zstd.size() / 3] ^ 0xff);
  std::ofstream(dir_ + "/zstd-damaged.mcap", std::ios::binary) << zstd;
  const Result r = build(dir_ + "/zstd-damaged.mcap", dir_ + "/zstd-damaged.ot");
  EXPECT_NE(r.out.find("is unreadable: "), std::string::npos) << r.out;
}

TEST_F(Bags, NotARecordingIsRefused) {
  const std::string fake = dir_ + "/fake.mcap";
  std::ofstream(fake) << "not an mcap file";
  Result r = build(fake, dir_ + "/fake.ot");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find(fake + ": not an MCAP file"), std::string::npos) << r.out;
  const std::string db = dir_ + "/fake.db3";
  std::ofstream(db) << "SQLite format 3";
  r = build(db, dir_ + "/fake.ot");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find(db + ": "), std::string::npos) << r.out;
  const std::string old = dir_ + "/old.bag";
  std::ofstream(old) << "#ROSBAG V1.2\n";
  r = build(old, dir_ + "/fake.ot");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find(old + ": a ROS 1 bag of format 1.2; mobmap reads format 2.0 (`rosbag fix` converts it)"), std::string::npos) << r.out;
  fs::create_directories(dir_ + "/emptybag");
  std::ofstream(dir_ + "/emptybag/metadata.yaml") << "rosbag2_bagfile_information:\n  relative_file_paths:\n    - ../../etc/passwd\n";
  r = build(dir_ + "/emptybag", dir_ + "/fake.ot");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("which is not a file inside the bag folder"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace mobmap::cli_test

namespace mobmap::cli_test {
namespace {

// --extrinsics: a sequence whose poses are a base's (odometry, a motion-capture body) and
// the camera's pose on the base give the map of the camera's own poses.
TEST(Extrinsics, PosesOfABaseAndTheCamerasMountingGiveTheCamerasMap) {
  const std::string dir = tempDir("extrinsics");
  ASSERT_EQ(run("simulate --out " + dir + "/cam --frames 6 -q").code, 0);
  ASSERT_EQ(run("build " + dir + "/cam --out " + dir + "/cam.ot --voxel 0.02 -q").code, 0);
  Eigen::Isometry3d T_base_camera = Eigen::Isometry3d::Identity();
  T_base_camera.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.2, 1.0, 0.3).normalized()).toRotationMatrix();
  T_base_camera.translation() = Eigen::Vector3d(0.3, -0.05, 0.8);
  fs::copy(dir + "/cam", dir + "/base");
  for (const auto& e : fs::directory_iterator(dir + "/base")) {
    const std::string name = e.path().string();
    if (name.size() < 9 || name.substr(name.size() - 9) != ".pose.txt") continue;
    std::ifstream in(name);
    Eigen::Matrix4d m;
    for (int i = 0; i < 16; ++i) in >> m(i / 4, i % 4);
    const Eigen::Matrix4d base = m * T_base_camera.inverse().matrix();
    std::ofstream out(name);
    out.precision(17);
    out << base << "\n";
  }
  const Eigen::Quaterniond q(T_base_camera.linear());
  char numbers[300];
  std::snprintf(numbers, sizeof numbers, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g", T_base_camera.translation().x(),
                T_base_camera.translation().y(), T_base_camera.translation().z(), q.x(), q.y(), q.z(), q.w());
  {
    std::ofstream yaml(dir + "/mount.yaml");
    yaml.precision(17);
    yaml << "T_base_camera:\n  translation: {x: " << T_base_camera.translation().x() << ", y: " << T_base_camera.translation().y()
         << ", z: " << T_base_camera.translation().z() << "}\n  rotation: {x: " << q.x() << ", y: " << q.y() << ", z: " << q.z()
         << ", w: " << q.w() << "}\n";
  }
  const auto reference = mapping::loadMobilityMap(dir + "/cam.ot");
  for (const std::string& spec : {std::string(numbers), dir + "/mount.yaml"}) {
    SCOPED_TRACE(spec);
    const Result r = run("build " + dir + "/base --out " + dir + "/base.ot --voxel 0.02 -q --force --extrinsics " + spec);
    ASSERT_EQ(r.code, 0) << r.out;
    const auto got = mapping::loadMobilityMap(dir + "/base.ot");
    // The poses are composed again, so the last bits may differ: the same voxels, the same mobility.
    std::size_t same = 0, total = 0;
    for (auto it = reference->begin_leafs(), end = reference->end_leafs(); it != end; ++it) {
      if (!reference->isNodeOccupied(*it) || !it->hasMobility()) continue;
      ++total;
      const auto* n = got->search(it.getKey());
      if (n && got->isNodeOccupied(n) && n->hasMobility() && std::abs(n->mobility() - it->mobility()) < 0.02) ++same;
    }
    EXPECT_GT(static_cast<double>(same), 0.99 * static_cast<double>(total)) << same << " of " << total;
    const auto meta = nlohmann::json::parse(fileBytes(dir + "/base.json"));
    EXPECT_TRUE(meta.contains("extrinsics"));
  }
  // Without the mounting, the map is another.
  ASSERT_EQ(run("build " + dir + "/base --out " + dir + "/plain.ot --voxel 0.02 -q").code, 0);
  EXPECT_NE(fileBytes(dir + "/plain.ot"), fileBytes(dir + "/cam.ot"));
  const Result bad = run("build " + dir + "/base --out " + dir + "/bad.ot --extrinsics 1,2,3");
  EXPECT_EQ(bad.code, 2) << bad.out;
  EXPECT_NE(bad.out.find("--extrinsics takes 7 numbers"), std::string::npos) << bad.out;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mobmap::cli_test
