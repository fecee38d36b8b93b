#pragma once
// The parameter checks' error, shared by validate(MapParams) and validate(ReachParams).

#include <sstream>
#include <stdexcept>

namespace mobmap::mapping::detail {

/// Throws std::invalid_argument "<params>: <field> is <value> (<rule>)".
[[noreturn]] inline void failParam(const char* params, const char* field, double value, const char* rule) {
  std::ostringstream msg;
  msg << params << ": " << field << " is " << value << " (" << rule << ")";
  throw std::invalid_argument(msg.str());
}

}  // namespace mobmap::mapping::detail
