// The `mobmap` executable as a user runs it: score, simulate, help.
#include "cli_support.hpp"

#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <sstream>
#include <vector>

namespace mobmap::cli_test {
namespace {

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
  EXPECT_NE(negative.out.find("--slope must be in [0, 180] degrees, got -5"), std::string::npos) << negative.out;
  const Result overhang = run("score --slope 500 --roughness 1.0");
  EXPECT_EQ(overhang.code, 2);
  EXPECT_NE(overhang.out.find("got 500"), std::string::npos) << overhang.out;
  // A surface is never smaller than its projection: A/A' < 1 cannot be measured.
  const Result smooth = run("score --slope 5 --roughness 0.5 --json");
  EXPECT_EQ(smooth.code, 2);
  EXPECT_NE(smooth.out.find("--roughness is the ratio A/A'"), std::string::npos) << smooth.out;
  EXPECT_NE(smooth.out.find("so >= 1; got 0.5"), std::string::npos) << smooth.out;
  EXPECT_EQ(run("score --slope 180 --roughness 1.0").code, 0);  // the bounds themselves are fine
  const Result nothing = run("score");
  EXPECT_EQ(nothing.code, 2);
  const Result unknown = run("frobnicate");
  EXPECT_EQ(unknown.code, 2);
}

TEST(Cli, ScorePlotWritesAPng) {
  const std::string dir = tempDir("plot");
  // Pictures go into folders that exist: a mistyped folder is refused, not created.
  const Result missing = run("score --plot " + dir + "/surface.png");
  EXPECT_EQ(missing.code, 1);
  EXPECT_NE(missing.out.find("surface.png: --plot's folder " + dir + " does not exist"), std::string::npos) << missing.out;
  EXPECT_FALSE(fs::exists(dir));
  fs::create_directories(dir);
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
  for (const char* c : {"simulate", "score", "demo", "analyze", "build", "query", "info", "evaluate", "export", "overlay", "config"}) {
    EXPECT_NE(r.out.find(c), std::string::npos) << c;
  }
}

// docs/CLI.md is the command reference: every subcommand `mobmap --help` lists has its
// section there, and every option a subcommand's --help lists is named there, so the
// two cannot drift apart.
TEST(Cli, EveryCommandAndEveryOptionOfHelpIsInTheCommandReference) {
  std::ifstream in(std::string(MOBMAP_SOURCE_DIR) + "/docs/CLI.md");
  ASSERT_TRUE(in) << "docs/CLI.md";
  const std::string doc((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const Result top = run("--help");
  ASSERT_EQ(top.code, 0);
  const std::size_t listed = top.out.find("Subcommands:");
  ASSERT_NE(listed, std::string::npos);
  std::istringstream lines(top.out.substr(listed));
  std::string line;
  std::getline(lines, line);
  int commands = 0, options = 0;
  while (std::getline(lines, line)) {
    std::istringstream words(line);
    std::string command;
    if (!(words >> command)) continue;
    ++commands;
    EXPECT_NE(doc.find("\n## " + command + "\n"), std::string::npos) << "no section for " << command;
    const Result help = run(command + " --help");
    ASSERT_EQ(help.code, 0) << command;
    // Option lines: indented, starting with the option's names ("-q,--quiet", "--out").
    std::istringstream help_lines(help.out);
    std::string h;
    while (std::getline(help_lines, h)) {
      static const std::regex option(R"(^\s+(?:-[A-Za-z],)?(--[a-z][a-z0-9-]*))");
      std::smatch m;
      if (!std::regex_search(h, m, option) || m[1] == "--help") continue;
      ++options;
      // The option as a whole name: "--frames" does not count for "--frame".
      const std::regex named(m[1].str() + "(?![a-z0-9-])");
      EXPECT_TRUE(std::regex_search(doc, named)) << command << " " << m[1] << " is not in docs/CLI.md";
    }
  }
  EXPECT_GE(commands, 15);
  EXPECT_GE(options, 200);
}

// Every Markdown link and image in README.md and docs/ that names a file of the
// repository points at one that exists.
TEST(Docs, EveryLinkInTheReadmeAndTheDocsResolves) {
  namespace fs = std::filesystem;
  const fs::path root = MOBMAP_SOURCE_DIR;
  std::vector<fs::path> pages = {root / "README.md"};
  for (const auto& e : fs::directory_iterator(root / "docs")) {
    if (e.path().extension() == ".md") pages.push_back(e.path());
  }
  static const std::regex link(R"(\]\(([^)\s]+)\))");
  int links = 0;
  for (const fs::path& page : pages) {
    std::ifstream in(page);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (auto it = std::sregex_iterator(text.begin(), text.end(), link); it != std::sregex_iterator(); ++it) {
      std::string target = (*it)[1];
      if (target.rfind('#', 0) == 0 || std::regex_search(target, std::regex("^[a-z]+:"))) continue;  // anchors, URLs
      target = target.substr(0, target.find('#'));
      ++links;
      EXPECT_TRUE(fs::exists(page.parent_path() / target)) << page.filename() << " links to " << target << ", which is missing";
    }
  }
  EXPECT_GE(links, 1);
}

}  // namespace
}  // namespace mobmap::cli_test
