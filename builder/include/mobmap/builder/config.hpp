#pragma once
// A YAML configuration of every library parameter (perception, mapping, the model), as
// `mobmap build --config` and mobmap::builder read it.

#include "mobmap/gp/mobility_model.hpp"
#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/perception/pipeline.hpp"

#include <string>

namespace mobmap::builder {

struct Config {
  perception::PerceptionParams perception;
  mapping::MapParams mapping;
  gp::MobilityModelParams model;
  std::string table_path;  ///< model.table: rule table CSV, "" for the paper's
  bool mapping_max_range_set = false;
};

/// Reads a YAML file; IoError "<path>: <key>: <problem>" for unknown keys, wrong types,
/// bad YAML, or values the parameter validators reject.
Config loadConfig(const std::string& path);
/// Parses YAML text (`origin` names it in errors).
Config parseConfig(const std::string& text, const std::string& origin);
/// Reads a rule table CSV; "" gives the paper's table. IoError names the file and line.
gp::RuleTable loadRuleTable(const std::string& path);
/// Builds the scorer the configuration describes (reads model.table if set).
gp::MobilityModel makeModel(const Config& c);

}  // namespace mobmap::builder
