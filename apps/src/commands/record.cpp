// `mobmap record`: saves a live OpenNI2 depth sensor to an .oni file, to map later
// with `mobmap build FILE.oni`.
#include "commands/commands.hpp"
#include "io/io_error.hpp"
#include "mobmap/sources/openni.hpp"

#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <memory>

namespace mobmap::app {
namespace {

std::atomic<bool> g_stop{false};
extern "C" void onRecordSigint(int) { g_stop.store(true); }
bool stopRequested() { return g_stop.load(); }

}  // namespace

Command addRecordCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("record", "Record a live OpenNI2 depth sensor to an .oni file (map it later with build)");
  struct Options {
    std::string device;
    std::string out;
    int frames = 300;
    bool force = false;
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("--device", o->device, "Device URI (default: the first attached sensor)");
  cmd->add_option("--out", o->out, "Recording to write (.oni)")->required();
  cmd->add_option("--frames", o->frames, "Number of depth frames to record (Ctrl-C stops earlier and keeps them)")
      ->capture_default_str()
      ->check(CLI::Range(1, 10000000));
  cmd->add_flag("--force", o->force, "Overwrite an existing file");
  return [o] {
    std::error_code ec;
    if (std::filesystem::path(o->out).extension() != ".oni") throw UsageError("--out must end in .oni, got '" + o->out + "'");
    if (!o->force && std::filesystem::exists(o->out, ec)) throw UsageError(o->out + " exists; pass --force to overwrite it");
    std::signal(SIGINT, onRecordSigint);
    // After the handler is in place: from here Ctrl-C stops the recording and keeps it.
    std::fprintf(stderr, "recording %s to %s (Ctrl-C stops and keeps the frames so far)\n",
                 o->device.empty() ? "the first attached sensor" : o->device.c_str(), o->out.c_str());
    const int got = sources::recordOni(o->device, o->out, o->frames, 5.0, stopRequested);
    std::signal(SIGINT, SIG_DFL);
    std::printf("recorded %d depth frames to %s%s\n", got, o->out.c_str(), g_stop.load() ? " (stopped by Ctrl-C)" : "");
    return 0;
  };
}

}  // namespace mobmap::app
