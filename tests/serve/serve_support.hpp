#pragma once
// What the tests of `mobmap serve` share: the server as a child process (started,
// talked to, stopped), and an HTTP client.
#include <httplib.h>

#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

extern char** environ;

namespace mobmap::serve_test {

// `mobmap ARGS` with pipes to its standard input and from its standard output (its
// standard error goes to `stderr_path`). The tests synchronise on what it prints: the
// address it serves at, "saved ..." after a live build.
class ServeProcess {
 public:
  ServeProcess(const std::vector<std::string>& args, const std::string& stderr_path,
               const std::vector<std::string>& extra_env = {}) {
    int in[2], out[2];
    if (::pipe(in) != 0 || ::pipe(out) != 0) return;
    std::vector<std::string> argv_strings{MOBMAP_EXE};
    argv_strings.insert(argv_strings.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : argv_strings) argv.push_back(a.data());
    argv.push_back(nullptr);
    std::vector<std::string> env_strings = extra_env;
    for (char** e = environ; *e; ++e) env_strings.emplace_back(*e);
    std::vector<char*> envp;
    for (auto& e : env_strings) envp.push_back(e.data());
    envp.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    ::posix_spawn_file_actions_init(&fa);
    ::posix_spawn_file_actions_adddup2(&fa, in[0], 0);
    ::posix_spawn_file_actions_adddup2(&fa, out[1], 1);
    ::posix_spawn_file_actions_addopen(&fa, 2, stderr_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::posix_spawn_file_actions_addclose(&fa, in[1]);
    ::posix_spawn_file_actions_addclose(&fa, out[0]);
    if (::posix_spawn(&pid_, argv[0], &fa, nullptr, argv.data(), envp.data()) != 0) pid_ = -1;
    ::posix_spawn_file_actions_destroy(&fa);
    ::close(in[0]);
    ::close(out[1]);
    stdin_ = in[1];
    stdout_ = out[0];
  }
  ~ServeProcess() {
    if (stdin_ >= 0) ::close(stdin_);
    if (stdout_ >= 0) ::close(stdout_);
    if (pid_ > 0 && !reaped_) {
      ::kill(pid_, SIGKILL);
      int status = 0;
      ::waitpid(pid_, &status, 0);
    }
  }
  ServeProcess(const ServeProcess&) = delete;
  ServeProcess& operator=(const ServeProcess&) = delete;

  [[nodiscard]] bool started() const { return pid_ > 0; }
  [[nodiscard]] pid_t pid() const { return pid_; }

  // Reads standard output up to a line holding `text`, and returns that line; "" if the
  // process ends first. Everything read goes to output().
  std::string lineWith(const std::string& text) {
    for (;;) {
      const auto end = pending_.find('\n');
      if (end != std::string::npos) {
        const std::string line = pending_.substr(0, end);
        pending_.erase(0, end + 1);
        output_ += line + "\n";
        if (line.find(text) != std::string::npos) return line;
        continue;
      }
      char buf[4096];
      const ssize_t n = ::read(stdout_, buf, sizeof buf);
      if (n <= 0) return "";
      pending_.append(buf, static_cast<std::size_t>(n));
    }
  }
  [[nodiscard]] const std::string& output() const { return output_; }

  // The port of the "... at http://ADDRESS:PORT/ ..." line; 0 if there is none.
  int port() {
    const std::string line = lineWith("http://");
    const auto at = line.find("http://");
    if (at == std::string::npos) return 0;
    const auto colon = line.find(':', at + 7);
    return colon == std::string::npos ? 0 : std::atoi(line.c_str() + colon + 1);
  }

  void writeLine(const std::string& line = "") {
    const std::string text = line + "\n";
    ASSERT_EQ(::write(stdin_, text.data(), text.size()), static_cast<ssize_t>(text.size()));
  }
  void closeInput() {
    if (stdin_ >= 0) ::close(stdin_);
    stdin_ = -1;
  }

  // Sends `signal` without waiting.
  void signal(int sig) {
    if (pid_ > 0) ::kill(pid_, sig);
  }
  // Sends `signal` and waits for the exit; its exit code, or -1 if it did not exit.
  int stop(int signal = SIGINT) {
    if (pid_ <= 0) return -1;
    ::kill(pid_, signal);
    int status = 0;
    if (::waitpid(pid_, &status, 0) != pid_) return -1;
    reaped_ = true;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  // Waits for the exit without a signal.
  int wait() {
    int status = 0;
    if (::waitpid(pid_, &status, 0) != pid_) return -1;
    reaped_ = true;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

 private:
  pid_t pid_ = -1;
  int stdin_ = -1, stdout_ = -1;
  bool reaped_ = false;
  std::string pending_, output_;
};

// A client of the server on `port` (keep-alive; generous timeouts: a slow machine is not
// an error).
inline std::unique_ptr<httplib::Client> client(int port) {
  auto c = std::make_unique<httplib::Client>("127.0.0.1", port);
  c->set_read_timeout(300, 0);
  c->set_write_timeout(300, 0);
  c->set_connection_timeout(60, 0);
  c->set_keep_alive(true);
  return c;
}

struct Reply {
  int status = 0;
  nlohmann::json body;
  std::string raw;
};

inline Reply get(httplib::Client& c, const std::string& path) {
  Reply r;
  const auto res = c.Get(path.c_str());
  if (!res) return r;
  r.status = res->status;
  r.raw = res->body;
  r.body = nlohmann::json::parse(res->body, nullptr, false);
  return r;
}

inline Reply post(httplib::Client& c, const std::string& path, const std::string& body) {
  Reply r;
  const auto res = c.Post(path.c_str(), body, "application/json");
  if (!res) return r;
  r.status = res->status;
  r.raw = res->body;
  r.body = nlohmann::json::parse(res->body, nullptr, false);
  return r;
}

// `mobmap ARGS` (or any command) to the end, its output and standard error together.
struct Result {
  int code = -1;
  std::string out;
};

inline Result runShell(const std::string& command) {
  Result r;
  FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return r;
  char buf[4096];
  while (std::fgets(buf, sizeof buf, pipe)) r.out += buf;
  const int status = ::pclose(pipe);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

inline Result mobmap(const std::string& args) { return runShell(std::string(MOBMAP_EXE) + " " + args); }

// The JSON lines of `out` (notes on standard error may come between).
inline std::vector<nlohmann::json> jsonLines(const std::string& out) {
  std::vector<nlohmann::json> lines;
  std::istringstream in(out);
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line.front() == '{') lines.push_back(nlohmann::json::parse(line));
  }
  return lines;
}

inline std::string tempDir(const std::string& name) {
  namespace fs = std::filesystem;
  const fs::path p = fs::temp_directory_path() / ("mobmap-serve-" + std::to_string(::getpid()) + "-" + name);
  fs::remove_all(p);
  fs::create_directories(p);
  return p.string();
}

// A noise-free simulated corridor and its map, built once for a test suite: Spec names
// the suite's folder (kName), the frames (kFrames) and build's extra options (kBuild).
template <typename Spec>
class MappedCorridor : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::string(tempDir(Spec::kName));
    const Result sim = mobmap("simulate --out " + *dir_ + "/seq --frames " + std::to_string(Spec::kFrames) + " --noise none --quiet");
    ASSERT_EQ(sim.code, 0) << sim.out;
    const Result built = mobmap("build " + *dir_ + "/seq --out " + *dir_ + "/m.ot " + Spec::kBuild + " --quiet");
    ASSERT_EQ(built.code, 0) << built.out;
  }
  static void TearDownTestSuite() {
    std::filesystem::remove_all(*dir_);
    delete dir_;
  }
  static std::string map() { return *dir_ + "/m.ot"; }
  static std::string dir() { return *dir_; }

 private:
  static inline std::string* dir_ = nullptr;
};

}  // namespace mobmap::serve_test
