#pragma once
// What the mapping tests share: a scratch folder per process, a small scored frame and
// the map built from it.
#include "mobmap/mapping/gravity.hpp"
#include "mobmap/mapping/map_lock.hpp"
#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/mapping/mobility_octree.hpp"
#include "mobmap/sim/corridor_scene.hpp"

#include <octomap/ColorOcTree.h>
#include <octomap/OcTree.h>

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <csignal>

#include <cmath>
#include <cstdio>
#include <functional>
#include <iterator>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <set>
#include <sstream>
#include <thread>
#include <tuple>

namespace mobmap::mapping {

namespace fs = std::filesystem;

// This process's scratch folder, removed when the process ends (ctest runs each test
// in its own process, and folders left behind used to pile up in /tmp).
inline std::string tempPath(const std::string& name) {
  struct Scratch {
    fs::path dir = fs::temp_directory_path() / ("mobmap-mapping-" + std::to_string(::getpid()));
    ~Scratch() {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  };
  static const Scratch scratch;
  fs::create_directories(scratch.dir);
  return (scratch.dir / name).string();
}

// A small scored "frame": a floor patch (mobility 1) and a wall (0) seen from 1.2 m.
// Surfaces sit mid-voxel (z = 0.01, x = 1.61) so float rounding cannot move them
// across a voxel boundary.
inline perception::FrameResult syntheticFrame() {
  perception::FrameResult r;
  perception::Segment floor, wall;
  floor.mobility = 1.0;
  floor.variance = 0.002;
  wall.mobility = 0.0;
  wall.variance = 0.002;
  for (int i = -30; i <= 30; ++i) {
    for (int j = 0; j < 60; ++j) {
      r.points.emplace_back(i * 0.01f, 1.19f, 1.0f + j * 0.01f);  // camera frame: floor 1.19 m below
      r.segment_of_point.push_back(0);
      floor.points.push_back(static_cast<int>(r.points.size() - 1));
      r.points.emplace_back(i * 0.01f, 1.19f - j * 0.01f, 1.61f);  // wall 1.61 m ahead
      r.segment_of_point.push_back(1);
      wall.points.push_back(static_cast<int>(r.points.size() - 1));
    }
  }
  r.segments = {floor, wall};
  return r;
}

inline Eigen::Isometry3d cameraLookingForward() {
  // Camera axes (x right, y down, z forward) in a z-up world, at 1.2 m height.
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  Eigen::Matrix3d r;
  r.col(0) = Eigen::Vector3d(0, -1, 0);
  r.col(1) = Eigen::Vector3d(0, 0, -1);
  r.col(2) = Eigen::Vector3d(1, 0, 0);
  T.linear() = r;
  T.translation() = Eigen::Vector3d(0, 0, 1.2);
  return T;
}

inline MobilityMap builtMap() {
  MobilityMap map;
  const auto frame = syntheticFrame();
  for (int i = 0; i < 3; ++i) map.integrate(frame, cameraLookingForward());
  map.finalize();
  return map;
}

}  // namespace mobmap::mapping
