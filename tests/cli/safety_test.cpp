// Data safety: a map on disk is never half written; oversized frames, far coordinates, bad
// frames and bad numbers are caught.
#include "cli_support.hpp"

#include <sys/wait.h>
#include <unistd.h>

namespace mobmap::cli_test {
namespace {

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
  for (const char* p : {"1.5 0 0.0", "3.0 -0.9 0.08", "2.0 0.5 0.0"}) {
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

// Poses no robot has (1e15 m), and a stray first pose 1000 km from the rest, which
// placed the map there: refused with the diagnosis, no map written (they used to report
// every frame fused into a wrong map, or 1 of 6 fused with exit 0).
TEST(Cli, PosesThatAreNotMetresAndAStrayFirstPoseWriteNoMap) {
  const std::string dir = tempDir("stray");
  ASSERT_EQ(run("simulate --out " + dir + "/home --frames 6 --noise none --quiet").code, 0);
  fs::copy(dir + "/home", dir + "/huge");
  shiftPose(dir + "/huge", 2, Eigen::Vector3d(1e15, 0, 0));
  const Result huge = run("build " + dir + "/huge --out " + dir + "/huge.ot --quiet");
  EXPECT_EQ(huge.code, 1) << huge.out;
  EXPECT_NE(huge.out.find("frame-000002.pose.txt: not a rigid transform: translation"), std::string::npos) << huge.out;
  EXPECT_NE(huge.out.find("lies farther than 1e+08 m from the origin"), std::string::npos) << huge.out;
  EXPECT_FALSE(fs::exists(dir + "/huge.ot"));
  fs::copy(dir + "/home", dir + "/first");
  shiftPose(dir + "/first", 0, Eigen::Vector3d(1e6, 0, 0));
  const Result first = run("build " + dir + "/first --out " + dir + "/first.ot --quiet");
  EXPECT_EQ(first.code, 1) << first.out;
  EXPECT_NE(first.out.find("5 of 6 frames with points in range lie outside the map's extent"), std::string::npos) << first.out;
  EXPECT_NE(first.out.find("comes from the first camera position"), std::string::npos) << first.out;
  EXPECT_FALSE(fs::exists(dir + "/first.ot"));
  // What the message suggests works: the stray frame left out.
  EXPECT_EQ(run("build " + dir + "/first --out " + dir + "/first.ot --frames 1:5 --quiet").code, 0);
  fs::remove_all(dir);
}

// Files a command writes: a folder that does not exist is refused up front (plan --png
// used to create /nonexistent/dir); temporaries of a save killed before its rename are
// removed by the next save of the same files, those of a live process kept; simulate
// --force replaces a longer sequence whole.
TEST(Cli, OutputsGoIntoFoldersThatExistAndLeaveNothingStale) {
  const std::string dir = tempDir("outputs");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 6 --noise none --quiet").code, 0);
  ASSERT_EQ(run("build " + dir + "/seq --out " + dir + "/m.ot --quiet").code, 0);
  const Result png = run("plan " + dir + "/m.ot --from 1 0 0.1 --to 2 0 0.1 --png " + dir + "/no/such/plan.png");
  EXPECT_EQ(png.code, 1) << png.out;
  EXPECT_NE(png.out.find("plan.png: --png's folder " + dir + "/no/such does not exist"), std::string::npos) << png.out;
  EXPECT_EQ(png.out.find("footsteps"), std::string::npos) << "planned before refusing: " << png.out;
  EXPECT_FALSE(fs::exists(dir + "/no"));

  // A process that has ended (its PID is free) and one that runs (this test).
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  ::waitpid(child, nullptr, 0);
  const std::string dead = std::to_string(child), alive = std::to_string(::getpid());
  for (const std::string& name : {"m.ot.new." + dead, "m.json.new." + dead + ".tmp." + dead, "m.bt.tmp." + dead,
                                  "m.ot.new." + alive}) {
    std::ofstream(dir + "/" + name) << "left by a killed save";
  }
  ASSERT_EQ(run("build " + dir + "/seq --out " + dir + "/m.ot --force --quiet").code, 0);
  EXPECT_FALSE(fs::exists(dir + "/m.ot.new." + dead));
  EXPECT_FALSE(fs::exists(dir + "/m.json.new." + dead + ".tmp." + dead));
  EXPECT_FALSE(fs::exists(dir + "/m.bt.tmp." + dead));
  EXPECT_TRUE(fs::exists(dir + "/m.ot.new." + alive));

  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 2 --force --noise none --quiet").code, 0);
  int frames = 0;
  for (const auto& e : fs::directory_iterator(dir + "/seq")) frames += e.path().filename().string().rfind("frame-", 0) == 0;
  EXPECT_EQ(frames, 2 * 4);  // depth, colour, labels, pose of frames 0 and 1
  const Result rebuilt = run("build " + dir + "/seq --out " + dir + "/two.ot --quiet");
  EXPECT_NE(rebuilt.out.find("2 of 2 frames fused"), std::string::npos) << rebuilt.out;
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
  EXPECT_NE(pose.out.find("(--skip-bad-frames leaves such frames out)"), std::string::npos) << pose.out;
  EXPECT_EQ(pose.out.find("build 1/"), std::string::npos) << pose.out;
  EXPECT_FALSE(fs::exists(dir + "/m.ot"));
  // The depth image's checksum is found when the frame is decoded.
  const Result crc = run("build " + dir + "/bad --frames 0:3 --out " + dir + "/m.ot --quiet");
  EXPECT_EQ(crc.code, 1);
  EXPECT_NE(crc.out.find("frame-000002.depth.png: corrupt or truncated PNG (IDAT: CRC error) (--skip-bad-frames"),
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
}  // namespace mobmap::cli_test
