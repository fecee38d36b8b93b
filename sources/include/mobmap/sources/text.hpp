#pragma once
// Small text inputs: a whole file read with a size limit, and numbers in text.

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace mobmap::sources {

/// Reads a whole file; IoError if it cannot be opened or is larger than max_bytes.
std::string readTextFile(const std::string& path, std::size_t max_bytes = 64u << 20);

/// The whole of `token` as a finite number, else nullopt ("1e3" yes; "1x", "", "nan" no).
std::optional<double> parseFiniteNumber(const std::string& token);

/// Comma-separated finite numbers ("585,585,320,240"); empty if any cell is not one.
std::vector<double> splitNumbers(const std::string& spec);

}  // namespace mobmap::sources
