// The `mobmap` executable as a user runs it: outputs, exit codes, error messages.
#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

namespace {

namespace fs = std::filesystem;

struct Result {
  int code = -1;
  std::string out;  // stdout and stderr together
};

Result run(const std::string& args) {
  const std::string cmd = std::string(MOBMAP_EXE) + " " + args + " 2>&1";
  Result r;
  FILE* pipe = ::popen(cmd.c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buf{};
  while (std::fgets(buf.data(), buf.size(), pipe)) r.out += buf.data();
  const int status = ::pclose(pipe);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::string tempDir(const std::string& name) {
  const auto p = fs::temp_directory_path() / ("mobmap-cli-" + std::to_string(::getpid()) + "-" + name);
  fs::remove_all(p);
  return p.string();
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
  EXPECT_NE(negative.out.find("must be finite and >= 0"), std::string::npos) << negative.out;
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
  for (const char* c : {"simulate", "score", "demo"}) EXPECT_NE(r.out.find(c), std::string::npos) << c;
}

}  // namespace
