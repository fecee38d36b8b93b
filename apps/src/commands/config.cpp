#include "commands/commands.hpp"
#include "io/config.hpp"
#include "io/io_error.hpp"

#include <iostream>
#include <memory>

namespace mobmap::app {

Command addConfigCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("config", "Print the default configuration, or check a configuration file");
  struct Options {
    bool print_default = false;
    std::string check;
  };
  auto o = std::make_shared<Options>();
  cmd->add_flag("--print-default", o->print_default, "Print the documented default YAML (every parameter)");
  cmd->add_option("--check", o->check, "Parse and validate a YAML file; report the first problem");
  return [o]() {
    if (o->print_default) {
      std::cout << defaultConfigYaml();
      return 0;
    }
    if (!o->check.empty()) {
      (void)makeModel(loadConfig(o->check));
      std::cout << o->check << ": valid\n";
      return 0;
    }
    throw UsageError("config needs --print-default or --check FILE");
  };
}

}  // namespace mobmap::app
