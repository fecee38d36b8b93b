#pragma once
// Atomic file writes for the map files (private to the mapping module).

#include <functional>
#include <ostream>
#include <string>

namespace mobmap::mapping {

/// Writes through a temporary file beside `path` and renames it into place, so the file
/// on disk is always either the old one or the complete new one. `write` returns false
/// on failure. MapIoError naming `path` if it cannot be written.
void writeAtomically(const std::string& path, const std::function<bool(std::ostream&)>& write);

}  // namespace mobmap::mapping
