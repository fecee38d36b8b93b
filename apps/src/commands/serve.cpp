// `mobmap serve`: a map over HTTP for planners in other processes, with a 3D viewer in
// the browser; with --live, a map being built, served as it grows (serve/api.hpp).
#include "commands/build_command.hpp"
#include "commands/commands.hpp"
#include "commands/picture_options.hpp"
#include "io/cli_text.hpp"
#include "io/io_error.hpp"
#include "io/map_files.hpp"
#include "serve/api.hpp"
#include "serve/http_server.hpp"

#include "mobmap/mapping/live_mapper.hpp"
#include "mobmap/mapping/map_metadata.hpp"
#include "mobmap/mapping/mobility_map.hpp"

#include <malloc.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace mobmap::app {
namespace {

// Ctrl-C, SIGTERM or SIGHUP while the server runs: a byte down this pipe wakes the main thread.
int g_stop_pipe[2] = {-1, -1};
extern "C" void onStopSignal(int) {
  const char byte = 1;
  const ssize_t written = ::write(g_stop_pipe[1], &byte, 1);
  (void)written;
}

// From here on SIGINT, SIGTERM and SIGHUP stop the server through the pipe. Called
// before the line saying where it serves, so a signal sent on reading that line finds
// the handler (the default action would end the process with the signal instead).
void catchStopSignals() {
  for (const int sig : {SIGINT, SIGTERM, SIGHUP}) std::signal(sig, onStopSignal);
}

// Returns once SIGINT, SIGTERM or SIGHUP arrives.
void waitForStopSignal() {
  catchStopSignals();
  char byte = 0;
  while (::read(g_stop_pipe[0], &byte, 1) < 0 && errno == EINTR) {
  }
}

// The server on a thread of its own; stopped and joined when it goes out of scope, also
// when the build run under it throws.
class RunningServer {
 public:
  RunningServer(const serve::Api& api, const std::string& address, int port) : server_(api) {
    try {
      port_ = server_.bind(address, port);
    } catch (const std::runtime_error& e) {
      throw UsageError(std::string("--bind/--port: ") + e.what());
    }
    thread_ = std::thread([this] { server_.run(); });
    const bool loopback = address.rfind("127.", 0) == 0 || address == "::1" || address == "localhost";
    if (!loopback) {
      std::fprintf(stderr,
                   "warning: listening on %s: the API has no authentication, and anyone who can reach this machine on "
                   "port %d can read the map and set it to work (--bind 127.0.0.1 serves this machine only)\n",
                   address.c_str(), port_);
    }
  }
  ~RunningServer() {
    server_.stop();
    thread_.join();
  }
  RunningServer(const RunningServer&) = delete;
  RunningServer& operator=(const RunningServer&) = delete;
  [[nodiscard]] int port() const { return port_; }

 private:
  serve::HttpServer server_;
  int port_ = 0;
  std::thread thread_;
};

std::string urlOf(const std::string& address, int port) {
  const bool v6 = address.find(':') != std::string::npos;
  return "http://" + (v6 ? "[" + address + "]" : address) + ":" + std::to_string(port) + "/";
}

}  // namespace

Command addServeCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "serve",
      "Serve a map over HTTP (point, sole and plan queries as JSON; a 3D viewer at /), or with --live build one and "
      "serve it while it grows");
  struct Options {
    std::string path;
    bool live = false;
    int port = 8080;
    std::string address = "127.0.0.1";
    std::size_t max_batch = serve::Limits{}.max_batch;
    std::size_t max_connections = serve::Limits{}.max_connections;
    double request_timeout = serve::Limits{}.request_read_s;
    ColourScale colours = ColourScale::kViridis;
    build::BuildOptions build;
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("PATH", o->path,
                  "The map to serve (MAP.ot, written by `mobmap build`); with --live, the input to build from, as "
                  "`mobmap build` takes it (or --device)");
  auto* live = cmd->add_flag(
      "--live", o->live,
      "Build the map from PATH (any input of `mobmap build`: a sequence, an .oni recording, a ROS 2 bag, --device) with the build "
      "options below, and serve it as frames are fused; the map is saved to --out at the end or on Ctrl-C exactly as "
      "`mobmap build` saves it, and served until Ctrl-C");
  cmd->add_option("--port", o->port, "TCP port (0: a free one; the address is printed)")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  cmd->add_option("--bind", o->address,
                  "Address to listen on: 127.0.0.1 serves this machine only; 0.0.0.0 every network (the API has no "
                  "authentication)")
      ->capture_default_str();
  cmd->add_option("--max-batch", o->max_batch, "Most points or soles one request may ask about (more: HTTP 413)")
      ->check(CLI::Range(1, 10000000))
      ->capture_default_str();
  cmd->add_option("--max-connections", o->max_connections,
                  "Connections served at once (more: HTTP 503 at once); one client address may hold a quarter of them")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  cmd->add_option("--request-timeout", o->request_timeout,
                  "Seconds a request may take to arrive whole; a slower one is cut off")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  addColoursOption(*cmd, o->colours)->description(
      "The viewer's mobility colours: viridis (dark purple 0, teal 0.5, yellow 1; readable with the common colour-vision "
      "deficiencies) or red-green (the paper's)");
  const std::size_t before = cmd->get_options().size();
  build::addBuildRunOptions(*cmd, o->build);
  const std::vector<CLI::Option*> all = cmd->get_options();
  for (std::size_t i = before; i < all.size(); ++i) all[i]->needs(live)->group("Build options (with --live; as `mobmap build`)");
  return [o]() {
    if (::pipe(g_stop_pipe) != 0) throw std::runtime_error("cannot create a pipe for the signal handler");
    std::signal(SIGPIPE, SIG_IGN);  // a client that hangs up is its own business
    // Request bodies and answers of megabytes come and go on many threads. glibc raises
    // its mmap threshold to the largest block freed, after which such blocks are carved
    // from per-thread arenas and kept there, and it keeps up to 16 arenas on two cores:
    // the soak of hostile clients (serve_hardening_test) peaked at 1.04 GB. A fixed
    // threshold gives every block over 1 MiB back when it is freed (464 MB), and four
    // arenas keep less idle memory (305 MB), with the same requests answered.
    ::mallopt(M_MMAP_THRESHOLD, 1 << 20);
    ::mallopt(M_ARENA_MAX, 4);
    serve::Limits limits;
    limits.max_batch = o->max_batch;
    limits.max_connections = o->max_connections;
    limits.request_read_s = o->request_timeout;
    if (!o->live) {
      if (o->path.empty()) throw UsageError("give the MAP.ot to serve, or --live INPUT --out MAP.ot to build one");
      OpenedMap opened = openMapFiles(o->path);
      serve::ServedMap served;
      served.map = std::make_shared<const mapping::MobilityMap>(std::move(opened.map));
      if (opened.metadata.found) {
        served.frames = opened.metadata.frames;
        served.camera_path = cameraPath(opened.metadata).positions;
        served.metadata = std::make_shared<const mapping::MapMetadata>(std::move(opened.metadata));
      }
      const serve::MapSource source(std::move(served));
      const serve::Api api(o->path, source, limits, o->colours);
      const RunningServer server(api, o->address, o->port);
      catchStopSignals();
      std::printf("serving %s at %s (Ctrl-C stops)\n", o->path.c_str(), urlOf(o->address, server.port()).c_str());
      std::fflush(stdout);
      waitForStopSignal();
      return 0;
    }
    build::BuildOptions& b = o->build;
    if (b.out.empty()) throw UsageError("--live needs --out MAP.ot: where the map is saved");
    b.input = o->path;
    // Until the run starts: an empty map in the resolution asked for.
    mapping::MapParams empty;
    empty.resolution_m = b.resolution;
    serve::ServedMap initial;
    initial.building = true;
    try {
      initial.map = std::make_shared<const mapping::MobilityMap>(empty);
    } catch (const std::invalid_argument& e) {
      throw UsageError(cliText(e));
    }
    serve::MapSource source(std::move(initial));
    const serve::Api api(b.out, source, limits, o->colours);
    const RunningServer server(api, o->address, o->port);
    const std::string url = urlOf(o->address, server.port());

    std::mutex path_mutex;  // the camera path, added to by the fusion thread
    std::vector<Eigen::Vector3d> path;
    build::LiveHooks hooks;
    hooks.started = [&](const mapping::LiveMapper& mapper, int frames) {
      serve::ServedMap s;
      s.map = mapper.snapshot();
      s.frames = frames;
      s.building = true;
      source.publish(std::move(s));
      // Announced once the run has passed build's checks (--out, the input), so that a
      // run refused at once never says it is serving.
      std::printf("serving the map being built into %s at %s\n", b.out.c_str(), url.c_str());
      std::fflush(stdout);
    };
    hooks.fused = [&](std::shared_ptr<const mapping::MobilityMap> map, int frames, const Eigen::Vector3d& camera) {
      serve::ServedMap s;
      {
        const std::lock_guard<std::mutex> lock(path_mutex);
        path.push_back(camera);
        s.camera_path = path;
      }
      s.map = std::move(map);
      s.frames = frames;
      s.building = true;
      source.publish(std::move(s));
    };
    hooks.saved = [&](std::shared_ptr<const mapping::MobilityMap> map, const mapping::MapMetadata& meta) {
      serve::ServedMap s;
      s.map = std::move(map);
      s.frames = meta.frames;
      s.camera_path = cameraPath(meta).positions;
      // As `mobmap info` reads it back from MAP.json.
      try {
        s.metadata = std::make_shared<const mapping::MapMetadata>(mapping::readMapMetadata(b.out));
      } catch (const std::exception&) {
        mapping::MapMetadata written = meta;
        written.found = true;
        written.path = mapping::mapFileStem(b.out) + ".json";
        s.metadata = std::make_shared<const mapping::MapMetadata>(std::move(written));
      }
      source.publish(std::move(s));
    };
    // MOBMAP_HOLD_FRAMES_ON_STDIN=1: each frame waits for a line on standard input (end of
    // input releases the rest), for tests that query the map between frames
    // (docs/RELIABILITY.md).
    if (const char* hold = std::getenv("MOBMAP_HOLD_FRAMES_ON_STDIN"); hold && std::string(hold) == "1") {
      auto holding = std::make_shared<bool>(true);
      hooks.before_frame = [holding] {
        std::string line;
        if (*holding && !std::getline(std::cin, line)) *holding = false;
      };
    }
    const int code = build::runBuild(b, &hooks);
    if (code != 0) return code;  // interrupted (the map is saved) or nothing to save
    catchStopSignals();
    std::printf("saved %s; serving it at %s (Ctrl-C stops)\n", b.out.c_str(), url.c_str());
    std::fflush(stdout);
    waitForStopSignal();
    return 0;
  };
}

}  // namespace mobmap::app
