#pragma once
// The PCL half of the .pcd reader, in the adapter libmobmap_pcd.so (pcd_pcl.cpp) that
// pcd.cpp opens when the first .pcd is read (util/plugin.hpp): a program that reads no
// .pcd never loads PCL.

#include "mobmap/sources/frame.hpp"

#include <string>

namespace mobmap::sources {

/// Changes whenever PcdAdapter does, so that an adapter of another build is refused.
inline constexpr int kPcdAdapterVersion = 1;

struct PcdAdapter {
  int version;
  /// The cloud as stored: points (x, y, z), width and height, colour of an organized
  /// cloud with rgb or rgba, depth unit metres, description. IoError naming the file.
  Frame (*load)(const std::string& path);
  /// The header and, for binary data, the size the header declares (checkPcdComplete).
  void (*check)(const std::string& path);
};

}  // namespace mobmap::sources

/// The adapter's one entry point.
extern "C" const mobmap::sources::PcdAdapter* mobmap_pcd_adapter();
