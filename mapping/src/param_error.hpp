#pragma once
// The parameter checks' error, shared by validate(MapParams) and validate(ReachParams).

#include "mobmap/util/field_error.hpp"

#include <sstream>
#include <stdexcept>

namespace mobmap::mapping::detail {

/// Throws util::FieldError "<params>: `<field>` is <value> (<rule>)".
[[noreturn]] inline void failParam(const char* params, const char* field, double value, const char* rule) {
  std::ostringstream msg;
  msg << "is " << value << " (" << rule << ")";
  throw util::FieldError(field, msg.str(), params);
}

}  // namespace mobmap::mapping::detail
