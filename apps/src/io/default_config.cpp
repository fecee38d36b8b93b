// The shipped apps/default.yaml, embedded at build time (apps/CMakeLists.txt).
#include "io/config.hpp"

namespace mobmap::app {

const std::string& defaultConfigYaml() {
  static const std::string text =
#include "default_yaml.inc"
      ;
  return text;
}

}  // namespace mobmap::app
