#pragma once
// ROS 2's command line, as rcl reads it: `--ros-args` then `-r from:=to` (and `__node:=`,
// `__ns:=`), `-p name:=value`, `--params-file FILE`, `--log-level LEVEL`; `--` or
// `--ros-args`'s end closes it. Parameter files are ROS 2's YAML (`node: ros__parameters:`).
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace mobmap::ros2 {

struct Args {
  std::string node = "mobmap";
  std::string ns = "/";
  std::map<std::string, std::string> remaps;  ///< from -> to, as given
  /// name -> value text, in the order given (a later one wins), files read in place.
  std::vector<std::pair<std::string, std::string>> params;
  std::string log_level = "info";
  bool help = false;
};

/// std::invalid_argument naming the argument or the file and the problem.
Args parseArgs(int argc, char** argv);

/// The parameters a ROS 2 YAML file gives the node `fq_node` (e.g. /mobmap): under its
/// name, its name without the leading slash, or a wildcard (/**); nested keys joined by
/// dots; lists as [a, b]. std::invalid_argument naming the file and the problem.
std::vector<std::pair<std::string, std::string>> readParamsFile(const std::string& path, const std::string& fq_node);

/// A name as ROS 2 resolves it: `~/x` under the node, `x` under the namespace, `/x` as it is.
std::string resolveName(const std::string& name, const std::string& ns, const std::string& node);

/// The DDS topic of a ROS 2 topic: rt/ and the name without its leading slash.
std::string ddsTopic(const std::string& resolved);

}  // namespace mobmap::ros2
