// The README as a newcomer reads it: after the demo, every command in its code blocks
// runs as written (in a directory holding the demo's outputs, with the executable the
// build made), and the picture at its top is there with the script that draws it.
#include "cli_support.hpp"

#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

namespace mobmap::cli_test {
namespace {

namespace fs = std::filesystem;

std::string readText(const fs::path& path) {
  std::ifstream in(path);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// The command lines of the README's ```sh blocks, comments cut off.
std::vector<std::string> readmeCommands(const std::string& readme) {
  std::vector<std::string> commands;
  std::istringstream lines(readme);
  std::string line;
  bool in_block = false;
  while (std::getline(lines, line)) {
    if (line.rfind("```", 0) == 0) {
      in_block = !in_block && line == "```sh";
      continue;
    }
    if (!in_block) continue;
    const std::size_t comment = line.find(" #");
    if (comment != std::string::npos) line.erase(comment);
    while (!line.empty() && line.back() == ' ') line.pop_back();
    if (!line.empty()) commands.push_back(line);
  }
  return commands;
}

// Runs a server command line in `dir` until it says where it listens, then stops it
// with Ctrl-C; its exit status.
int serveUntilListening(const std::string& dir, const std::string& command_line, std::string& out) {
  int from_child[2];
  if (::pipe(from_child) != 0) return -1;
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::dup2(from_child[1], 1);
    ::dup2(from_child[1], 2);
    ::close(from_child[0]);
    const std::string shell = "cd '" + dir + "' && exec " + command_line;
    ::execl("/bin/sh", "sh", "-c", shell.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  ::close(from_child[1]);
  while (out.find("http://") == std::string::npos) {
    pollfd pfd{from_child[0], POLLIN, 0};
    if (::poll(&pfd, 1, 120000) != 1) break;  // a guard against a hang, not a timing test
    char buf[512];
    const ssize_t n = ::read(from_child[0], buf, sizeof buf);
    if (n <= 0) break;
    out.append(buf, static_cast<std::size_t>(n));
  }
  ::kill(pid, SIGINT);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ::close(from_child[0]);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

TEST(Newcomer, EveryCommandInTheReadmeRunsAsWrittenAfterTheDemo) {
  const fs::path source = MOBMAP_SOURCE_DIR;
  const std::string readme = readText(source / "README.md");
  ASSERT_FALSE(readme.empty());
  // The picture at the top, and the script that draws it.
  const std::size_t image = readme.find("](docs/images/");
  ASSERT_NE(image, std::string::npos) << "the README has no picture";
  const std::string picture = readme.substr(image + 2, readme.find(')', image) - image - 2);
  EXPECT_TRUE(fs::exists(source / picture)) << picture;
  EXPECT_NE(readme.find("scripts/readme_picture.sh"), std::string::npos);
  EXPECT_TRUE(fs::exists(source / "scripts/readme_picture.sh"));

  // What `bash scripts/demo.sh` leaves: the demo's outputs in maps/demo.
  const std::string dir = tempDir("newcomer");
  fs::create_directories(dir);
  const Result demo = runShell("cd '" + dir + "' && " + MOBMAP_EXE + " demo --out maps/demo --quiet");
  ASSERT_EQ(demo.code, 0) << demo.out;

  const std::string exe = "./build/apps/mobmap";
  int ran = 0, setup = 0;
  for (const std::string& command : readmeCommands(readme)) {
    SCOPED_TRACE(command);
    if (command.rfind("bash scripts/", 0) == 0) {  // the set-up commands: what CI runs
      ++setup;
      EXPECT_TRUE(fs::exists(source / command.substr(5))) << command;
      continue;
    }
    ASSERT_EQ(command.rfind(exe + " ", 0), 0u) << "a command the test does not know how to run";
    const std::string line = MOBMAP_EXE + command.substr(exe.size());
    ++ran;
    if (line.find(" serve ") != std::string::npos) {
      std::string out;
      // --port 0: a free port, where 8080 may be taken on a shared machine.
      EXPECT_EQ(serveUntilListening(dir, line + " --port 0", out), 0) << out;
      EXPECT_NE(out.find("http://127.0.0.1:"), std::string::npos) << out;
      continue;
    }
    const Result r = runShell("cd '" + dir + "' && " + line);
    EXPECT_EQ(r.code, 0) << r.out;
    EXPECT_FALSE(r.out.empty());
  }
  EXPECT_EQ(setup, 2);  // the two commands for a fresh machine
  EXPECT_GE(ran, 4);    // the tour
}

}  // namespace
}  // namespace mobmap::cli_test
