#pragma once
/// @file json_limits.hpp
/// Bounds on JSON text read from outside the program (MAP.json, HTTP request bodies),
/// checked in one linear pass before the text is parsed. A JSON library recurses when it
/// copies, prints or compares a value, so text nested tens of thousands deep overflows the
/// stack of whatever touches it after parsing; and a body of many tiny values ("[{},{},...]")
/// parses into a document tens of times its size. Both are refused here, before either can
/// happen.

#include <cstddef>
#include <string>
#include <string_view>

namespace mobmap::util {

struct JsonLimits {
  /// Arrays and objects inside one another: `[[1]]` is 2 deep. MAP.json needs 3; a request 3.
  std::size_t max_depth = 64;
  /// Values in the whole text (every number, string, literal, array and object counts one).
  std::size_t max_values = static_cast<std::size_t>(-1);
};

/// What checkJsonLimits() found.
struct JsonLimitProblem {
  enum class Kind { kNone, kTooDeep, kTooManyValues, kNulByte };
  Kind kind = Kind::kNone;
  /// In words, with the byte offset: "arrays and objects are nested more than 64 deep (at byte 1234)".
  std::string message;
  explicit operator bool() const { return kind != Kind::kNone; }
};

/// What keeps `text` from being parsed within `limits` (false when nothing does). Also
/// refused: a NUL byte outside a string (what follows it would be read by nobody). Does
/// not check that the text is valid JSON; the parser does that afterwards. Linear time.
[[nodiscard]] JsonLimitProblem checkJsonLimits(std::string_view text, const JsonLimits& limits = {});

}  // namespace mobmap::util
