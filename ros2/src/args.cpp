#include "args.hpp"

#include <yaml-cpp/yaml.h>

#include <functional>
#include <stdexcept>

namespace mobmap::ros2 {
namespace {

std::pair<std::string, std::string> assignment(const std::string& a, const std::string& what) {
  const auto at = a.find(":=");
  if (at == std::string::npos || at == 0) throw std::invalid_argument(what + " expects name:=value, got \"" + a + "\"");
  return {a.substr(0, at), a.substr(at + 2)};
}

std::string text(const YAML::Node& v) {
  if (v.IsScalar()) return v.Scalar();
  if (v.IsSequence()) {
    std::string out = "[";
    for (std::size_t i = 0; i < v.size(); ++i) out += (i ? ", " : "") + text(v[i]);
    return out + "]";
  }
  if (v.IsNull()) return "";
  throw std::invalid_argument("a value that is neither a scalar nor a list");
}

}  // namespace

Args parseArgs(int argc, char** argv) {
  Args a;
  std::vector<std::string> files;
  bool ros = false;
  for (int i = 1; i < argc; ++i) {
    const std::string s = argv[i];
    if (s == "--help" || s == "-h") {
      a.help = true;
      continue;
    }
    if (s == "--ros-args") {
      ros = true;
      continue;
    }
    if (s == "--") {
      ros = false;
      continue;
    }
    if (!ros) throw std::invalid_argument("unknown argument \"" + s + "\" (ROS 2 arguments follow --ros-args; --help)");
    const auto value = [&](const std::string& flag) {
      if (i + 1 >= argc) throw std::invalid_argument(flag + " needs a value");
      return std::string(argv[++i]);
    };
    if (s == "-r" || s == "--remap") {
      auto [from, to] = assignment(value(s), s);
      if (from == "__node" || from == "__name") {
        a.node = to;
      } else if (from == "__ns") {
        a.ns = to.empty() || to[0] != '/' ? "/" + to : to;
      } else {
        a.remaps[from] = to;
      }
    } else if (s == "-p" || s == "--param") {
      a.params.push_back(assignment(value(s), s));
    } else if (s == "--params-file") {
      files.push_back(value(s));
      a.params.emplace_back("\x01" + files.back(), "");  // read in place once the node's name is known
    } else if (s == "--log-level") {
      a.log_level = value(s);
    } else if (s == "-e" || s == "--enclave") {
      (void)value(s);
    } else {
      throw std::invalid_argument("unknown ROS argument \"" + s + "\"");
    }
  }
  // Files in place, now that __node and __ns are known.
  std::vector<std::pair<std::string, std::string>> params;
  const std::string fq = (a.ns == "/" ? "" : a.ns) + "/" + a.node;
  for (auto& [name, v] : a.params) {
    if (!name.empty() && name[0] == '\x01') {
      for (auto& kv : readParamsFile(name.substr(1), fq)) params.push_back(std::move(kv));
    } else {
      params.emplace_back(name, v);
    }
  }
  a.params = std::move(params);
  return a;
}

std::vector<std::pair<std::string, std::string>> readParamsFile(const std::string& path, const std::string& fq_node) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw std::invalid_argument(path + ": cannot read the parameters file");
  } catch (const YAML::Exception& e) {
    throw std::invalid_argument(path + ": not YAML: " + e.what());
  }
  if (!root.IsMap()) throw std::invalid_argument(path + ": a ROS 2 parameters file is a map of node names");
  std::vector<std::pair<std::string, std::string>> out;
  const std::string bare = fq_node.substr(1);
  const std::string last = fq_node.substr(fq_node.rfind('/') + 1);
  for (const auto& entry : root) {
    const std::string key = entry.first.as<std::string>();
    if (key != fq_node && key != bare && key != last && key != "/**" && key != "**") continue;
    const YAML::Node params = entry.second["ros__parameters"];
    if (!params) throw std::invalid_argument(path + ": " + key + " has no ros__parameters");
    std::function<void(const YAML::Node&, const std::string&)> walk = [&](const YAML::Node& n, const std::string& prefix) {
      for (const auto& kv : n) {
        const std::string name = prefix + kv.first.as<std::string>();
        if (kv.second.IsMap()) {
          walk(kv.second, name + ".");
        } else {
          try {
            out.emplace_back(name, text(kv.second));
          } catch (const std::invalid_argument& e) {
            throw std::invalid_argument(path + ": " + name + ": " + e.what());
          }
        }
      }
    };
    walk(params, "");
  }
  return out;
}

std::string resolveName(const std::string& name, const std::string& ns, const std::string& node) {
  const std::string base = ns == "/" ? "" : ns;
  if (name.rfind("~/", 0) == 0) return base + "/" + node + name.substr(1);
  if (!name.empty() && name[0] == '/') return name;
  return base + "/" + name;
}

std::string ddsTopic(const std::string& resolved) { return "rt" + resolved; }

}  // namespace mobmap::ros2
