#include "mobmap/util/json_limits.hpp"

namespace mobmap::util {

JsonLimitProblem checkJsonLimits(std::string_view text, const JsonLimits& limits) {
  using Kind = JsonLimitProblem::Kind;
  std::size_t depth = 0, values = 0;
  bool in_string = false, escaped = false, in_scalar = false;
  const auto at = [](std::size_t i) { return " (at byte " + std::to_string(i) + ")"; };
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        in_string = false;
      }
      continue;
    }
    // A scalar (number, literal) counts once, at its first character.
    const bool scalar = c == '-' || c == '+' || c == '.' || (c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') ||
                        (c >= 'A' && c <= 'Z');
    if (scalar) {
      if (!in_scalar) ++values;
      in_scalar = true;
    } else {
      in_scalar = false;
      switch (c) {
        case '"':
          in_string = true;
          ++values;
          break;
        case '[':
        case '{':
          ++values;
          if (++depth > limits.max_depth) {
            return {Kind::kTooDeep, "arrays and objects are nested more than " + std::to_string(limits.max_depth) + " deep" + at(i)};
          }
          break;
        case ']':
        case '}':
          if (depth > 0) --depth;
          break;
        case '\0':
          return {Kind::kNulByte, "a NUL byte outside a string" + at(i)};
        default:
          break;
      }
    }
    if (values > limits.max_values) {
      return {Kind::kTooManyValues, "more than " + std::to_string(limits.max_values) + " values" + at(i)};
    }
  }
  return {};
}

}  // namespace mobmap::util
