#pragma once
// Writers of the 7-Scenes / 3DMatch layout (`mobmap simulate`); its readers are the
// library's (mobmap/sources/dataset.hpp), under the names the commands use.

#include "mobmap/perception/camera.hpp"
#include "mobmap/sources/dataset.hpp"

#include <Eigen/Core>

#include <string>

namespace mobmap::app {

using sources::frameStem;
using sources::intrinsicsFromFov;
using sources::kFovSpecPrefix;
using sources::parseIntrinsics;
using sources::readDepthPng;
using sources::readGravityFile;
using sources::readIntrinsicsFile;
using sources::readPoseFile;
using sources::SevenScenesDirectory;

/// Each written atomically (temporary file + rename), numbers in full precision.
void writeIntrinsicsFile(const std::string& path, const perception::PinholeIntrinsics& k);
void writePoseFile(const std::string& path, const Eigen::Matrix4d& T_world_camera);
void writeGravityFile(const std::string& path, const Eigen::Vector3d& gravity_down);

/// Depth in metres -> 16-bit millimetres (rounded; 0 for no measurement or > 65.534 m).
void writeDepthPng(const std::string& path, const perception::DepthImage& depth);

}  // namespace mobmap::app
