#pragma once
// The `mobmap` subcommands. Each registers its options on the CLI11 app and returns
// the function that runs it (exit code).

#include <CLI/CLI.hpp>

#include <functional>

namespace mobmap::app {

using Command = std::function<int()>;

Command addSimulateCommand(CLI::App& app);
Command addScoreCommand(CLI::App& app);
Command addDemoCommand(CLI::App& app);
Command addAnalyzeCommand(CLI::App& app);
Command addBuildCommand(CLI::App& app);
Command addQueryCommand(CLI::App& app);
Command addInfoCommand(CLI::App& app);
Command addEvaluateCommand(CLI::App& app);
Command addExportCommand(CLI::App& app);
Command addOverlayCommand(CLI::App& app);
Command addConfigCommand(CLI::App& app);

}  // namespace mobmap::app
