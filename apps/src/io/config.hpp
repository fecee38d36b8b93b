#pragma once
// The YAML configuration (the library's: mobmap/builder/config.hpp) and the shipped
// apps/default.yaml that `mobmap config --print-default` prints.

#include "mobmap/builder/config.hpp"

#include <string>

namespace mobmap::app {

using builder::Config;
using builder::loadConfig;
using builder::loadRuleTable;
using builder::makeModel;
using builder::parseConfig;

/// The shipped apps/default.yaml, embedded at build time.
const std::string& defaultConfigYaml();

}  // namespace mobmap::app
