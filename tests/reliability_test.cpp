// Nothing lost: a map on disk survives the writer being killed mid-save, and Ctrl-C
// during `mobmap build` leaves a complete map of the frames fused so far.
#include "mobmap/mapping/mobility_map.hpp"

#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
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

TEST(NothingLost, CtrlCDuringBuildSavesTheFramesFusedSoFar) {
  const std::string dir = tempDir("sigint");
  const std::string exe = MOBMAP_EXE;
  ASSERT_EQ(std::system((exe + " simulate --out " + dir + "/seq --frames 60 --noise none --quiet").c_str()), 0);
  const std::string map = dir + "/m.ot";
  std::vector<std::string> args = {exe, "build", dir + "/seq", "--out", map, "--quiet"};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  ASSERT_EQ(::posix_spawn(&pid, exe.c_str(), nullptr, nullptr, argv.data(), environ), 0);
  std::this_thread::sleep_for(std::chrono::seconds(3));  // a few frames in, far from the 60
  ::kill(pid, SIGINT);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130);
  const auto tree = mapping::loadMobilityMap(map);  // complete and loadable
  EXPECT_GT(tree->size(), 100u);
  std::ifstream meta_in(dir + "/m.json");
  const auto meta = nlohmann::json::parse(meta_in);
  EXPECT_TRUE(meta["interrupted"].get<bool>());
  EXPECT_GT(meta["frames"].get<int>(), 0);
  EXPECT_LT(meta["frames"].get<int>(), 60);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mobmap
