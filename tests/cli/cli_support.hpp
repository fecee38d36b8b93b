#pragma once
// What the tests of the `mobmap` executable share: running it, reading what it writes.
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

namespace mobmap::cli_test {

namespace fs = std::filesystem;

struct Result {
  int code = -1;
  std::string out;  // stdout and stderr together
};

// Runs a shell command line with its standard error mixed into the output.
inline Result runShell(const std::string& command_line) {
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

inline Result run(const std::string& args) { return runShell(std::string(MOBMAP_EXE) + " " + args); }

// run() with the size of any file the command writes limited to `kib` KiB (as `ulimit -f`
// sets) and SIGXFSZ ignored, so writes past it fail as on a full disk.
inline Result runWithFileSizeLimit(int kib, const std::string& args) {
  return runShell("trap '' XFSZ; ulimit -f " + std::to_string(2 * kib) + "; " + MOBMAP_EXE + " " + args);
}

inline std::string fileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

inline std::string tempDir(const std::string& name) {
  const auto p = fs::temp_directory_path() / ("mobmap-cli-" + std::to_string(::getpid()) + "-" + name);
  fs::remove_all(p);
  return p.string();
}

// The first line of `out` that is a JSON object (notes on standard error, which run() mixes in,
// may come first: query --reach, analyze).
inline nlohmann::json jsonLine(const std::string& out) {
  std::istringstream lines(out);
  std::string line;
  while (std::getline(lines, line))
    if (!line.empty() && line.front() == '{') return nlohmann::json::parse(line);
  ADD_FAILURE() << "no JSON line in: " << out;
  return nlohmann::json::object();
}

// The places `reach --pcd` writes (x y z mobility standable reachable, ASCII), keyed by
// their position. Every row has the six fields, the rows are as many as the header
// declares, and no two share a position.
struct PlaceFlags {
  double mobility = 0;
  bool standable = false, reachable = false;
};
inline std::map<std::array<double, 3>, PlaceFlags> readPlaces(const std::string& pcd_path) {
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

// Width and height of a PNG, from its IHDR chunk (bytes 16-23, big-endian).
inline std::pair<int, int> pngSize(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  unsigned char b[24] = {};
  in.read(reinterpret_cast<char*>(b), sizeof b);
  if (!in) return {0, 0};
  const auto be = [&](int i) { return (b[i] << 24) | (b[i + 1] << 16) | (b[i + 2] << 8) | b[i + 3]; };
  return {be(16), be(20)};
}

}  // namespace mobmap::cli_test
