// mobmap: RGB-D depth frames -> 3D mobility maps for legged robots.
#include "commands/commands.hpp"
#include "io/cli_text.hpp"
#include "io/io_error.hpp"

#include <cstdio>
#include <exception>
#include <iostream>
#include <map>

#include <malloc.h>

#ifndef MOBMAP_VERSION
#define MOBMAP_VERSION "unknown"
#endif

namespace {
std::map<std::string, mobmap::app::Command>* g_commands = nullptr;
}

namespace mobmap::app {
// Runs another subcommand of the same app (used by `demo` to run `build`).
int runSubcommand(CLI::App& app, const std::vector<std::string>& args) {
  std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 parses a reversed vector
  app.parse(reversed);
  for (auto* sub : app.get_subcommands()) return g_commands->at(sub->get_name())();
  return 2;
}
}  // namespace mobmap::app

int main(int argc, char** argv) {
  // Every frame allocates and frees the same few tens of megabytes (clouds, neighbour
  // graphs, images) on two threads. By default glibc serves blocks that large with
  // mmap and returns them on free, so each frame page-faults its buffers in again
  // (~20 % of `build`'s time on this machine). Keep them in the heap for reuse.
  mallopt(M_MMAP_THRESHOLD, 256 << 20);
  mallopt(M_TRIM_THRESHOLD, 512 << 20);
  CLI::App app{"mobmap " MOBMAP_VERSION
               ": mobility maps for legged robots from RGB-D depth frames (Genesio et al.)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", MOBMAP_VERSION);
  std::map<std::string, mobmap::app::Command> commands;
  g_commands = &commands;
  commands["simulate"] = mobmap::app::addSimulateCommand(app);
  commands["score"] = mobmap::app::addScoreCommand(app);
  commands["demo"] = mobmap::app::addDemoCommand(app);
  commands["analyze"] = mobmap::app::addAnalyzeCommand(app);
  commands["build"] = mobmap::app::addBuildCommand(app);
  commands["query"] = mobmap::app::addQueryCommand(app);
  commands["reach"] = mobmap::app::addReachCommand(app);
  commands["plan"] = mobmap::app::addPlanCommand(app);
  commands["info"] = mobmap::app::addInfoCommand(app);
  commands["serve"] = mobmap::app::addServeCommand(app);
  commands["evaluate"] = mobmap::app::addEvaluateCommand(app);
  commands["export"] = mobmap::app::addExportCommand(app);
  commands["overlay"] = mobmap::app::addOverlayCommand(app);
  commands["config"] = mobmap::app::addConfigCommand(app);
  commands["record"] = mobmap::app::addRecordCommand(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);  // prints help, the version or the usage error
    return code == 0 ? 0 : 2;
  }
  try {
    for (auto* sub : app.get_subcommands()) return commands.at(sub->get_name())();
  } catch (const mobmap::app::UsageError& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 2;
  } catch (const mobmap::util::ValueError& e) {  // a value the library cannot take: a usage mistake
    std::cerr << "error: " << mobmap::app::cliText(e) << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "error: " << mobmap::app::cliText(e) << "\n";
    return 1;
  }
  return 2;
}
