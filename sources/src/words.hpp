#pragma once
// How the readers' messages write times and lists.

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace mobmap::sources {

/// "12.345 s" for a time in nanoseconds.
inline std::string seconds(std::int64_t ns) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.3f s", static_cast<double>(ns) * 1e-9);
  return buf;
}

/// "a, b, c", or "none".
inline std::string listed(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out.empty() ? "none" : out;
}

}  // namespace mobmap::sources
