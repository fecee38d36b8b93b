#pragma once
// The bag tests' fixture (tests/cli/bags_test.cpp, hostile_bags_test.cpp): a simulated
// sequence and its 7-Scenes map, bags written from it by implementations other than
// mobmap's (tests/recordings), and what the tests read back.
#include "cli_support.hpp"

#include <sys/resource.h>

#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/mapping/mobility_octree.hpp"

namespace mobmap::cli_test {

inline const std::string kFixtures = std::string(MOBMAP_SOURCE_DIR) + "/tests/recordings";
inline constexpr const char* kBuild = " --voxel 0.02 -q";

class Bags : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!fs::exists(kFixtures + "/node_modules/@mcap/core")) {
      skip_ = "the bag writers are not installed: run `npm ci --prefix tests/recordings` (scripts/setup.sh does)";
      return;
    }
    dir_ = tempDir("bags");
    fs::create_directories(dir_);
    const Result sim = run("simulate --out " + dir_ + "/seq --frames 12 -q");
    ASSERT_EQ(sim.code, 0) << sim.out;
    const Result ref = run("build " + dir_ + "/seq --out " + dir_ + "/ref.ot" + kBuild);
    ASSERT_EQ(ref.code, 0) << ref.out;
  }
  static void TearDownTestSuite() {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  void SetUp() override {
    if (!skip_.empty()) GTEST_SKIP() << skip_;
  }

  // Writes dir_/NAME.mcap (or, with --feed, the messages for make_db3.py) with write_bag.mjs.
  static std::string writeBag(const std::string& name, const std::string& options) {
    const std::string out = dir_ + "/" + name;
    const Result r = runShell("node " + kFixtures + "/write_bag.mjs --seq " + dir_ + "/seq " +
                              (options.find("--feed") == std::string::npos ? "--out " + out + " " : "") + options);
    EXPECT_EQ(r.code, 0) << r.out;
    return out;
  }
  // A ROS 2 bag folder in sqlite3 storage.
  static std::string writeDb3(const std::string& name, const std::string& options) {
    const std::string feed = dir_ + "/" + name + ".jsonl";
    writeBag(name, "--feed " + feed + " " + options);
    const Result r = runShell("python3 " + kFixtures + "/make_db3.py " + feed + " " + dir_ + "/" + name);
    EXPECT_EQ(r.code, 0) << r.out;
    return dir_ + "/" + name;
  }
  static Result build(const std::string& input, const std::string& out, const std::string& options = "") {
    return run("build " + input + " --out " + out + kBuild + " " + options);
  }
  static std::string ref() { return dir_ + "/ref.ot"; }

  static inline std::string dir_;
  static inline std::string skip_;
};

inline std::size_t leafCount(const std::string& path) {
  const auto tree = mapping::loadMobilityMap(path);
  std::size_t n = 0;
  for (auto it = tree->begin_leafs(), end = tree->end_leafs(); it != end; ++it) n += tree->isNodeOccupied(*it) ? 1 : 0;
  return n;
}

// Leaves (key -> mobility) of a map file.
inline std::map<std::array<double, 3>, double> leaves(const std::string& path) {
  std::map<std::array<double, 3>, double> out;
  const auto tree = mapping::loadMobilityMap(path);
  for (auto it = tree->begin_leafs(), end = tree->end_leafs(); it != end; ++it) {
    if (tree->isNodeOccupied(*it) && it->hasMobility()) out[{it.getX(), it.getY(), it.getZ()}] = it->mobility();
  }
  return out;
}

// Peak resident memory (KiB) of `mobmap ARGS`, from the kernel's accounting of that
// process alone (wait4).
inline long peakRssKib(const std::string& args) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    // Under AddressSanitizer (scripts/sanitize.sh) freed memory is held back in a
    // quarantine that grows with the churn, not with what the program keeps: off here.
    ::execl("/bin/sh", "sh", "-c",
            ("ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}quarantine_size_mb=0 " + std::string(MOBMAP_EXE) + " " + args + " > /dev/null 2>&1")
                .c_str(),
            static_cast<char*>(nullptr));
    ::_exit(127);
  }
  int status = 0;
  struct rusage usage {};
  if (::wait4(pid, &status, 0, &usage) != pid || !WIFEXITED(status) || WEXITSTATUS(status) != 0) return -1;
  return usage.ru_maxrss;
}

}  // namespace mobmap::cli_test
