// Nothing lost: a map on disk survives the writer being killed mid-save, and Ctrl-C
// during `mobmap build` leaves a complete map of the frames fused so far.
#include "mobmap/mapping/mobility_map.hpp"

#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <random>
#include <sstream>
#include <thread>

extern char** environ;

namespace mobmap {
namespace {

namespace fs = std::filesystem;

std::string tempDir(const std::string& name) {
  const auto p = fs::temp_directory_path() / ("mobmap-rel-" + std::to_string(::getpid()) + "-" + name);
  fs::remove_all(p);
  fs::create_directories(p);
  return p.string();
}

mapping::MobilityOcTree bigTree(float shift) {
  mapping::MobilityOcTree t(0.02);
  for (int i = 0; i < 120; ++i) {
    for (int j = 0; j < 120; ++j) {
      for (int k = 0; k < 6; ++k) {
        auto* n = t.updateNode(octomap::point3d(i * 0.02f + shift, j * 0.02f, k * 0.02f), true);
        n->setMobility((i + j) % 10 / 10.0, 100, 1 + k);
      }
    }
  }
  return t;
}

TEST(NothingLost, KillingTheWriterMidSaveNeverLeavesAHalfWrittenMap) {
  const std::string dir = tempDir("kill");
  const std::string path = dir + "/map.ot";
  const auto first = bigTree(0.f);
  mapping::saveMobilityMap(first, path);
  const auto first_size = first.size();
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> delay_us(0, 40000);
  int loaded = 0;
  for (int round = 0; round < 25; ++round) {
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      // Alternate between two different maps, saving as fast as possible.
      const auto a = bigTree(1.f), b = bigTree(2.f);
      for (int i = 0;; ++i) mapping::saveMobilityMap(i % 2 ? a : b, path);
    }
    std::this_thread::sleep_for(std::chrono::microseconds(delay_us(rng) + 20000));
    ::kill(child, SIGKILL);
    int status = 0;
    ::waitpid(child, &status, 0);
    // Whatever moment the kill hit, the file is one complete map.
    std::unique_ptr<mapping::MobilityOcTree> back;
    ASSERT_NO_THROW(back = mapping::loadMobilityMap(path)) << "round " << round;
    EXPECT_GT(back->size(), first_size / 2);
    ++loaded;
  }
  EXPECT_EQ(loaded, 25);
  fs::remove_all(dir);
}

// `mobmap build` held at a chosen frame: with MOBMAP_STOP_AFTER_FRAMES=N in its
// environment it stops itself (SIGSTOP) once N frames are fused, reported and, with
// --checkpoint, saved. The test waits for that stop (waitpid WUNTRACED), so what it then
// does to the build happens at that frame whatever the machine's speed.
pid_t spawnHeldBuild(std::vector<std::string> args, int stop_after_frames) {
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::vector<std::string> env_strings = {"MOBMAP_STOP_AFTER_FRAMES=" + std::to_string(stop_after_frames)};
  for (char** e = environ; *e; ++e) env_strings.emplace_back(*e);
  std::vector<char*> envp;
  for (auto& e : env_strings) envp.push_back(e.data());
  envp.push_back(nullptr);
  posix_spawn_file_actions_t quiet;
  ::posix_spawn_file_actions_init(&quiet);
  ::posix_spawn_file_actions_addopen(&quiet, 1, "/dev/null", O_WRONLY, 0);
  pid_t pid = 0;
  const int spawned = ::posix_spawn(&pid, args[0].c_str(), &quiet, nullptr, argv.data(), envp.data());
  ::posix_spawn_file_actions_destroy(&quiet);
  if (spawned != 0) return -1;
  int status = 0;
  if (::waitpid(pid, &status, WUNTRACED) != pid || !WIFSTOPPED(status)) return -1;  // it must stop, not end
  return pid;
}

// Ctrl-C after the first frame: the map of that frame is saved, complete.
// Ctrl-C, SIGTERM (a service manager stopping it) and SIGHUP (its terminal closed) each
// save the frames fused so far and exit 128 + the signal's number.
class StopSignal : public ::testing::TestWithParam<int> {};

TEST_P(StopSignal, DuringBuildSavesTheFramesFusedSoFar) {
  const int sig = GetParam();
  const std::string dir = tempDir("signal" + std::to_string(sig));
  const std::string exe = MOBMAP_EXE;
  ASSERT_EQ(std::system((exe + " simulate --out " + dir + "/seq --frames 60 --noise none --quiet").c_str()), 0);
  const std::string map = dir + "/m.ot";
  const pid_t pid = spawnHeldBuild({exe, "build", dir + "/seq", "--out", map, "--quiet"}, 1);
  ASSERT_GT(pid, 0) << "the build did not stop after its first frame";
  ::kill(pid, sig);  // delivered when it continues, before it takes the next frame
  ::kill(pid, SIGCONT);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status)) << "ended by signal " << (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  EXPECT_EQ(WEXITSTATUS(status), 128 + sig);
  const auto tree = mapping::loadMobilityMap(map);  // complete and loadable
  EXPECT_GT(tree->size(), 100u);
  std::ifstream meta_in(dir + "/m.json");
  const auto meta = nlohmann::json::parse(meta_in);
  EXPECT_TRUE(meta["interrupted"].get<bool>());
  EXPECT_EQ(meta["frames"].get<int>(), 1);
  EXPECT_FALSE(fs::exists(dir + "/m.lock"));
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(NothingLost, StopSignal, ::testing::Values(SIGINT, SIGTERM, SIGHUP),
                         [](const ::testing::TestParamInfo<int>& p) {
                           return std::string(p.param == SIGINT ? "SIGINT" : p.param == SIGTERM ? "SIGTERM" : "SIGHUP");
                         });

std::string fileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// `build --checkpoint N` saves the map every N frames. Killed (-9) after a checkpoint,
// the run leaves a complete map of its first frames, and `--extend` with the rest
// finishes it: the same files as one uninterrupted run, byte for byte.
TEST(NothingLost, AKilledBuildResumesFromItsCheckpointToTheMapOfOneRun) {
  const std::string dir = tempDir("checkpoint");
  const std::string exe = MOBMAP_EXE;
  ASSERT_EQ(std::system((exe + " simulate --out " + dir + "/seq --frames 24 --noise none --quiet").c_str()), 0);
  ASSERT_EQ(std::system((exe + " build " + dir + "/seq --out " + dir + "/whole.ot --quiet > /dev/null").c_str()), 0);
  // Checkpoints along the way leave the final map as it would have been without.
  ASSERT_EQ(std::system((exe + " build " + dir + "/seq --out " + dir + "/steps.ot --checkpoint 5 --quiet > /dev/null").c_str()), 0);
  EXPECT_TRUE(fileBytes(dir + "/steps.ot") == fileBytes(dir + "/whole.ot"));

  const std::string map = dir + "/m.ot", json = dir + "/m.json";
  // Killed (SIGKILL) while held after frame 8, two frames past the checkpoint of 6.
  const pid_t pid = spawnHeldBuild({exe, "build", dir + "/seq", "--out", map, "--checkpoint", "6", "--quiet"}, 8);
  ASSERT_GT(pid, 0) << "the build did not stop after frame 8";
  ::kill(pid, SIGKILL);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status));
  const auto meta = nlohmann::json::parse(fileBytes(json));
  ASSERT_TRUE(meta.value("checkpoint", false)) << meta.dump();
  const int fused = meta["frames"].get<int>();
  ASSERT_EQ(fused, 6);
  EXPECT_EQ(meta["frame_numbers"], nlohmann::json({0, fused - 1}));
  EXPECT_GT(mapping::loadMobilityMap(map)->size(), 100u);  // complete and loadable

  const std::string rest = std::to_string(fused) + ":23";
  ASSERT_EQ(std::system((exe + " build " + dir + "/seq --out " + map + " --extend --frames " + rest + " --quiet > /dev/null").c_str()), 0);
  EXPECT_TRUE(fileBytes(map) == fileBytes(dir + "/whole.ot"));
  EXPECT_TRUE(fileBytes(dir + "/m.octovis.ot") == fileBytes(dir + "/whole.octovis.ot"));
  const auto done = nlohmann::json::parse(fileBytes(json));
  EXPECT_EQ(done["frames"], 24);
  EXPECT_FALSE(done.contains("checkpoint"));
  EXPECT_TRUE(done["earlier_runs"][0].value("checkpoint", false));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mobmap
