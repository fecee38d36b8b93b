// libFuzzer target: arbitrary text as a YAML configuration and as a rule-table CSV must
// parse or be rejected with an exception, never crash.
#include "io/config.hpp"
#include "io/io_error.hpp"

#include "mobmap/gp/rule_table.hpp"

#include <cstdint>
#include <stdexcept>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    (void)mobmap::app::parseConfig(text, "fuzz.yaml");
  } catch (const mobmap::app::IoError&) {
  }
  try {
    const auto t = mobmap::gp::RuleTable::parseCsv(text);
    (void)t.lookup(12.0, 1.3);
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
