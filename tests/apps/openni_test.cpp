// OpenNI2 inputs of `mobmap build` and `mobmap record`, for real and without hardware:
// OpenNI2's own Dummy device (the live path), no device at all, and a driver of ours
// (sim/openni) that serves the synthetic corridor as a live sensor, whose
// recordings OpenNI2's player plays back. The driver is loaded from a private folder
// (build/openni-sim) by pointing LD_LIBRARY_PATH at it.
#include "io/map_files.hpp"
#include "io/png_io.hpp"

#include "mobmap/perception/camera.hpp"
#include "mobmap/sim/corridor_scene.hpp"
#include "mobmap/sim/tum_pose.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

extern char** environ;

namespace mobmap {
namespace {

namespace fs = std::filesystem;

struct Outcome {
  int code = -1;
  std::string output;
};

// Runs mobmap with `env` prepended (VAR=value ...), capturing stdout and stderr.
Outcome mobmap(const std::string& env, const std::string& args) {
  const std::string cmd = env + " " + MOBMAP_EXE + " " + args + " 2>&1";
  Outcome r;
  FILE* p = ::popen(cmd.c_str(), "r");
  if (p == nullptr) return r;
  std::array<char, 4096> buf{};
  while (std::fgets(buf.data(), buf.size(), p) != nullptr) r.output += buf.data();
  const int status = ::pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

class OpenNi : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("mobmap-openni-" + std::to_string(::getpid()) + "-" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  static std::string simEnv(int frames) {
    return "LD_LIBRARY_PATH=" + std::string(MOBMAP_OPENNI_SIM_DIR) + " MOBMAP_SIM_FRAMES=" + std::to_string(frames);
  }
  // Records n frames of the test driver's corridor to c.oni with `mobmap record`.
  Outcome recordCorridor(int n) const {
    return mobmap(simEnv(n), "record --device mobmap-sim://corridor --frames " + std::to_string(n) + " --out " + path("c.oni"));
  }
  // Poses of corridor frames 0..n-1 at their device time stamps i/30 s.
  std::string writePoses(const sim::CorridorScene& scene, int n) const {
    const std::string p = path("poses.txt");
    std::ofstream out(p);
    for (int i = 0; i < n; ++i) sim::writeTumPoseLine(out, i / 30.0, scene.cameraPose(i));
    return p;
  }
  // The floor ahead of the walker's first position is found at z = 0 and traversable.
  static void expectFloorAhead(const std::string& map_path, const sim::CorridorScene& scene) {
    const auto map = mapping::openMap(map_path);
    const Eigen::Vector3d cam = scene.cameraPose(0).translation();
    const auto floor = map.snapDown(Eigen::Vector3d(cam.x() + 1.5, cam.y(), 0.1), 0.3);
    ASSERT_TRUE(floor);
    EXPECT_NEAR(floor->centre.z(), 0.0, map.tree().getResolution());
    ASSERT_TRUE(floor->has_mobility);
    EXPECT_GT(floor->mobility, 0.75);
  }
  static nlohmann::json metadata(const std::string& map_path) {
    std::ifstream in(map_path.substr(0, map_path.size() - 3) + ".json");
    return nlohmann::json::parse(in);
  }
  // Which of the corridor's first n frames a camera position of MAP.json's
  // trajectory_map ([x, y, z], the corridor's frame) was taken from: the one whose
  // camera lies within 0.1 mm of it, or -1 if none does.
  static int corridorFrameAt(const sim::CorridorScene& scene, int n, const nlohmann::json& position) {
    const Eigen::Vector3d at(position[0].get<double>(), position[1].get<double>(), position[2].get<double>());
    int best = 0;
    for (int i = 1; i < n; ++i) {
      if ((scene.cameraPose(i).translation() - at).norm() < (scene.cameraPose(best).translation() - at).norm()) best = i;
    }
    return (scene.cameraPose(best).translation() - at).norm() < 1e-4 ? best : -1;
  }
  fs::path dir_;
};

TEST_F(OpenNi, NoDeviceAttachedIsAClearErrorAndWritesNothing) {
  // A driver folder with only the .oni file driver, which never reports a device:
  // OpenNI2 starts and finds nothing, as on a machine with no sensor plugged in.
  const fs::path system_lib = fs::read_symlink(fs::path(MOBMAP_OPENNI_SIM_DIR) / "libOpenNI2.so.0");
  fs::create_directories(dir_ / "lib" / "OpenNI2" / "Drivers");
  fs::create_symlink(system_lib, dir_ / "lib" / "libOpenNI2.so.0");
  fs::create_symlink(system_lib.parent_path() / "OpenNI2" / "Drivers" / "libOniFile.so.0",
                     dir_ / "lib" / "OpenNI2" / "Drivers" / "libOniFile.so.0");
  const Outcome r = mobmap("LD_LIBRARY_PATH=" + path("lib"), "build --device --out " + path("m.ot"));
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("OpenNI2: no depth sensor is attached"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(path("m.ot")));
  const Outcome rec = mobmap("LD_LIBRARY_PATH=" + path("lib"), "record --out " + path("r.oni"));
  EXPECT_EQ(rec.code, 1) << rec.output;
  EXPECT_NE(rec.output.find("no depth sensor is attached"), std::string::npos) << rec.output;
  EXPECT_FALSE(fs::exists(path("r.oni")));
}

TEST_F(OpenNi, DummyDeviceFeedsTheLivePath) {
  // OpenNI2's Dummy device (320x240, no field of view): intrinsics must be given.
  const Outcome no_k = mobmap("", "build --device Dummy --frames 0:4 --out " + path("m.ot"));
  EXPECT_EQ(no_k.code, 1) << no_k.output;
  EXPECT_NE(no_k.output.find("give --intrinsics"), std::string::npos) << no_k.output;
  const Outcome r = mobmap("", "build --device Dummy --intrinsics 300,300,159.5,119.5 --frames 0:4 --quiet --out " + path("m.ot"));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(metadata(path("m.ot"))["frames"], 5);
  EXPECT_NE(r.output.find("5 of 5 frames fused"), std::string::npos) << r.output;
}

// The corridor camera is 1.35 m above the floor: with a 1 m range a live run has
// nothing to map, which is an error naming the device, and no file is written.
TEST_F(OpenNi, LiveSensorWithNothingInRangeIsAnErrorAndWritesNothing) {
  const Outcome r = mobmap(simEnv(30), "build --device mobmap-sim://corridor --frames 0:2 --max-range 1.0 --quiet --out " +
                                           path("m.ot"));
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("OpenNI2 device mobmap-sim://corridor: none of the 3 frames fused has a measured point between "
                          "0.3 and 1 m of the camera"),
            std::string::npos)
      << r.output;
  for (const char* f : {"m.ot", "m.bt", "m.octovis.ot", "m.json"}) EXPECT_FALSE(fs::exists(path(f))) << f;
}

// A sensor that opens but never sends a frame: build gives up after 5 s naming it;
// Ctrl-C while waiting stops build and record at once, and neither writes a file.
TEST_F(OpenNi, ASilentSensorTimesOutAndCtrlCStopsTheWaitAtOnce) {
  const auto started = std::chrono::steady_clock::now();
  const Outcome silent = mobmap(simEnv(0), "build --device mobmap-sim://corridor --quiet --out " + path("s.ot"));
  EXPECT_EQ(silent.code, 1) << silent.output;
  EXPECT_NE(silent.output.find("mobmap-sim://corridor: no depth frame within 5 s of starting its depth stream"),
            std::string::npos)
      << silent.output;
  EXPECT_GE(std::chrono::steady_clock::now() - started, std::chrono::seconds(5));
  // SIGINT once the command says Ctrl-C now stops it (its handler is in place and the
  // wait for the first frame is about to begin or has begun). Ending with the Ctrl-C
  // message, not the timeout's, shows the wait was cut short.
  const auto interrupt = [&](const std::string& args, const std::string& ready_line) {
    std::vector<std::string> env_strings = {"LD_LIBRARY_PATH=" + std::string(MOBMAP_OPENNI_SIM_DIR), "MOBMAP_SIM_FRAMES=0"};
    std::vector<char*> envp;
    for (auto& e : env_strings) envp.push_back(e.data());
    for (char** e = environ; *e != nullptr; ++e) envp.push_back(*e);
    envp.push_back(nullptr);
    std::istringstream words(args);
    std::vector<std::string> arg_strings{MOBMAP_EXE};
    for (std::string w; words >> w;) arg_strings.push_back(w);
    std::vector<char*> argv;
    for (auto& a : arg_strings) argv.push_back(a.data());
    argv.push_back(nullptr);
    int fds[2];
    Outcome r;
    if (::pipe(fds) != 0) return r;
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, fds[1], 1);
    posix_spawn_file_actions_adddup2(&actions, fds[1], 2);
    posix_spawn_file_actions_addclose(&actions, fds[0]);
    pid_t pid = 0;
    const int spawned = ::posix_spawn(&pid, MOBMAP_EXE, &actions, nullptr, argv.data(), envp.data());
    posix_spawn_file_actions_destroy(&actions);
    ::close(fds[1]);
    if (spawned != 0) {
      ::close(fds[0]);
      return r;
    }
    char c = 0;
    bool signalled = false;
    while (::read(fds[0], &c, 1) == 1) {
      r.output += c;
      if (!signalled && c == '\n' && r.output.find(ready_line) != std::string::npos) {
        ::kill(pid, SIGINT);
        signalled = true;
      }
    }
    ::close(fds[0]);
    int status = 0;
    ::waitpid(pid, &status, 0);
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    EXPECT_TRUE(signalled) << r.output;
    EXPECT_EQ(r.output.find("no depth frame within"), std::string::npos) << r.output;
    return r;
  };
  const Outcome build = interrupt("build --device mobmap-sim://corridor --out " + path("m.ot"),
                                  "reading OpenNI2 device mobmap-sim://corridor (Ctrl-C stops and saves the map)");
  EXPECT_EQ(build.code, 130) << build.output;
  EXPECT_NE(build.output.find("interrupted before any frame was fused: no map written"), std::string::npos) << build.output;
  for (const char* f : {"m.ot", "m.bt", "m.octovis.ot", "m.json"}) EXPECT_FALSE(fs::exists(path(f))) << f;
  const Outcome record = interrupt("record --device mobmap-sim://corridor --out " + path("r.oni"),
                                   "recording mobmap-sim://corridor to " + path("r.oni") + " (Ctrl-C stops");
  EXPECT_EQ(record.code, 1) << record.output;
  EXPECT_NE(record.output.find("mobmap-sim://corridor: stopped by Ctrl-C before the first depth frame arrived; nothing recorded"),
            std::string::npos)
      << record.output;
  EXPECT_FALSE(fs::exists(path("r.oni")));
}

TEST_F(OpenNi, RecordingsWithoutCroppingAreRejectedWithTheReason) {
  // The Dummy device reports no cropping property, so its recordings lack it, and
  // OpenNI2's player then drops every frame: refuse them instead of waiting forever.
  const Outcome rec = mobmap("", "record --device Dummy --frames 5 --out " + path("d.oni"));
  ASSERT_EQ(rec.code, 0) << rec.output;
  ASSERT_TRUE(fs::exists(path("d.oni")));
  const Outcome r = mobmap("", "build " + path("d.oni") + " --intrinsics 300,300,159.5,119.5 --out " + path("m.ot"));
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("d.oni: its depth stream was recorded without a cropping property"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(path("m.ot")));
}

TEST_F(OpenNi, LiveCorridorSensorWithPosesMapsTheKnownFloor) {
  const int device_frames = 900;  // 30 s: the device outlasts the run
  sim::CorridorParams p;
  p.frames = device_frames;
  p.noise = sim::NoiseModel::kNone;
  const sim::CorridorScene scene(p);
  const std::string poses = writePoses(scene, device_frames);
  // Frames are taken as they arrive (a slow consumer skips some): their time stamps
  // find their poses.
  const Outcome r = mobmap(simEnv(device_frames), "build --device mobmap-sim://corridor --intrinsics 585,585,320,240 --poses " +
                                                  poses + " --frames 0:7 --quiet --out " + path("m.ot"));
  ASSERT_EQ(r.code, 0) << r.output;
  const auto meta = metadata(path("m.ot"));
  EXPECT_EQ(meta["frames"], 8);
  expectFloorAhead(path("m.ot"), scene);
  // The frames the sensor sent while 8 were read: the first and last camera positions
  // (the map frame is the corridor's, z up) are those of device frames i0 and i1.
  const auto& path_map = meta["trajectory_map"];
  ASSERT_EQ(path_map.size(), 8u);
  const int first = corridorFrameAt(scene, device_frames, path_map[0]), last = corridorFrameAt(scene, device_frames, path_map[7]);
  EXPECT_GE(first, 0) << path_map[0];
  EXPECT_GE(last, 0) << path_map[7];
  const int sent = last - first + 1;
  if (sent > 8) {  // perception fell behind the 30 frames/s (on this machine, always)
    const std::string note = "mobmap-sim://corridor sent " + std::to_string(sent) + " depth frames while 8 were read: " +
                             std::to_string(sent - 8) + " arrived while perception was busy and were dropped";
    EXPECT_NE(r.output.find(note), std::string::npos) << r.output;
    EXPECT_NE(meta["skipped"].get<std::string>().find(note), std::string::npos) << meta["skipped"];
  } else {
    EXPECT_EQ(r.output.find("were dropped"), std::string::npos) << r.output;
  }
}

TEST_F(OpenNi, PosesOnAnotherClockAreAClearErrorAndWriteNothing) {
  const int n = 8;
  const Outcome rec = recordCorridor(n);
  ASSERT_EQ(rec.code, 0) << rec.output;
  // Poses stamped in Unix time while the recording's clock starts at 0.
  const std::string poses = path("unix.txt");
  {
    std::ofstream out(poses);
    for (int i = 0; i < n; ++i) out << 1700000000.0 + i / 30.0 << " 0 0 1 0 0 0 1\n";
  }
  const Outcome r = mobmap("", "build " + path("c.oni") + " --poses " + poses + " --quiet --out " + path("m.ot"));
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("unix.txt: none of the"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(path("m.ot")));
}

TEST_F(OpenNi, RecordedCorridorPlaysBackEveryFrameAndMapsTheKnownFloor) {
  const int n = 20;
  sim::CorridorParams p;
  p.frames = n;
  p.noise = sim::NoiseModel::kNone;
  const sim::CorridorScene scene(p);
  const Outcome rec = recordCorridor(n);
  ASSERT_EQ(rec.code, 0) << rec.output;
  // Played back without the driver: every recorded frame, in order, each with the pose
  // of its time stamp (none skipped), and field-of-view intrinsics.
  const Outcome r = mobmap("", "build " + path("c.oni") + " --poses " + writePoses(scene, n) + " --quiet --out " + path("m.ot"));
  ASSERT_EQ(r.code, 0) << r.output;
  const auto meta = metadata(path("m.ot"));
  EXPECT_GE(meta["frames"].get<int>(), n - 2);  // the recorder may miss the first frame or two
  EXPECT_FALSE(meta.contains("frames_without_pose")) << meta.dump();
  expectFloorAhead(path("m.ot"), scene);
  // overlay reads recording frame 5 as build did (poses and intrinsics from MAP.json)
  // and draws the map over its shaded depth: the floor in view is painted green.
  const Outcome ov = mobmap("", "overlay " + path("m.ot") + " --frame 5 --colours red-green --out " + path("ov.png"));
  ASSERT_EQ(ov.code, 0) << ov.output;
  const app::ImageRgb picture = app::readPngRgb(path("ov.png"));
  const auto& kj = meta["depth_intrinsics"];
  perception::PinholeIntrinsics k;
  k.fx = kj["fx"], k.fy = kj["fy"], k.cx = kj["cx"], k.cy = kj["cy"], k.width = kj["width"], k.height = kj["height"];
  ASSERT_EQ(picture.width, k.width);
  ASSERT_GT(picture.height, k.height);  // the frame, then the legend
  // Which corridor frame recording frame 5 is: the one whose pose the map's sixth camera
  // position is (the recorder may have missed the first frames).
  const int frame = corridorFrameAt(scene, n, meta["trajectory_map"][5]);
  ASSERT_GE(frame, 0) << meta["trajectory_map"][5];
  const auto view = scene.render(frame);
  int floor = 0, floor_green = 0;
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * k.width + u;
      const float z = view.exact_depth.depth_m[i];
      if (view.labels[i] == 0 || scene.surface(view.labels[i]).kind != sim::SurfaceKind::kFloor ||
          perception::backProject(k, u, v, z).norm() > 2.8) {
        continue;
      }
      // The base is the shaded depth of the recorded millimetres; recover the paint.
      const double z_mm = std::lround(z * 1000.0) / 1000.0;
      const int grey = static_cast<std::uint8_t>(std::clamp(250.0 - 40.0 * z_mm, 40.0, 240.0));
      const auto o = picture.pixels[i];
      const int red = (5 * o[0] - 2 * grey) / 3, green = (5 * o[1] - 2 * grey) / 3;
      ++floor;
      floor_green += green > red + 100;
    }
  }
  ASSERT_GT(floor, 20000);
  EXPECT_GT(floor_green, 0.9 * floor) << floor_green << " of " << floor;
  // A frame the recording does not hold, and one with no pose near its time stamp.
  const Outcome past = mobmap("", "overlay " + path("m.ot") + " --frame " + path("c.oni") + ":" + std::to_string(n + 5) +
                                      " --out " + path("no.png"));
  EXPECT_EQ(past.code, 1) << past.output;
  EXPECT_NE(past.output.find("c.oni: holds "), std::string::npos) << past.output;
  const std::string few = path("few.txt");
  {
    std::ofstream out(few);
    for (int i = 0; i < 3; ++i) sim::writeTumPoseLine(out, i / 30.0, scene.cameraPose(i));
  }
  const Outcome unposed = mobmap("", "overlay " + path("m.ot") + " --frame 12 --poses " + few + " --out " + path("no.png"));
  EXPECT_EQ(unposed.code, 1) << unposed.output;
  EXPECT_NE(unposed.output.find("frame 12: no pose within --max-pose-gap"), std::string::npos) << unposed.output;
  EXPECT_FALSE(fs::exists(path("no.png")));
}

}  // namespace
}  // namespace mobmap
