#pragma once
/// @file plugin.hpp
/// Adapters that bring heavy libraries (PCL for .pcd files, GDAL for GeoTIFF) are shared
/// objects opened when first used, so that a program or command that never reads a .pcd
/// or writes a GeoTIFF never loads those libraries (`mobmap --version` and `mobmap query`
/// start in a few milliseconds instead of loading ~170 libraries).
///
/// An adapter libmobmap_NAME.so is looked for, in order, in: $MOBMAP_PLUGIN_DIR; the folder
/// lib/mobmap beside the folder of the program or library holding this code (bin/mobmap
/// finds lib/mobmap/, as `cmake --install` lays them out, and build/apps/mobmap finds
/// build/lib/mobmap/); the install and build folders compiled in.

#include <stdexcept>
#include <string>

namespace mobmap::util {

/// The symbol `symbol` of adapter `name` (libmobmap_NAME.so), opened once and kept open.
/// std::runtime_error saying where it was looked for when it cannot be found or opened,
/// or has no such symbol.
[[nodiscard]] void* pluginSymbol(const std::string& name, const char* symbol);

/// An adapter's table of functions: what its entry point `symbol` (a function taking
/// nothing and returning `const Table*`) returns, its `version` checked against the
/// caller's. std::runtime_error as pluginSymbol, or for another version.
template <typename Table>
[[nodiscard]] const Table& pluginTable(const std::string& name, const char* symbol, int version) {
  const auto entry = reinterpret_cast<const Table* (*)()>(pluginSymbol(name, symbol));
  const Table* table = entry();
  if (table->version != version) {
    throw std::runtime_error("mobmap's " + name + " adapter (libmobmap_" + name + ".so) belongs to another version of mobmap");
  }
  return *table;
}

}  // namespace mobmap::util
