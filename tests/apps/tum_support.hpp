#pragma once
// What the TUM and .pcd-sequence tests share: simulated sequences written in those layouts.
#include "pictures/picture.hpp"
#include "io/dataset.hpp"
#include "io/frame_source.hpp"
#include "io/io_error.hpp"
#include "io/png_io.hpp"
#include "io/map_files.hpp"
#include "mobmap/sources/pcd.hpp"
#include "io/sequence.hpp"
#include "mobmap/sources/trajectory_files.hpp"

#include "mobmap/mapping/trajectory.hpp"
#include "mobmap/sim/corridor_scene.hpp"
#include "mobmap/sim/tum_pose.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>

namespace mobmap {

namespace fs = std::filesystem;

constexpr double kT0 = 1305031102.0;  // TUM timestamps are Unix seconds

// Writes frames 0..n-1 of the noise-free corridor as a TUM directory: depth at 30 Hz,
// ground truth at 100 Hz shifted by 3 ms, with a 40 ms hole around `gap_frame` (with a
// 20 ms tolerance that frame has no pose; its neighbours, 33 ms away, keep theirs).
inline std::string writeTum(const sim::CorridorScene& scene, int n, int gap_frame) {
  const fs::path dir = fs::temp_directory_path() / ("mobmap-tum-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "depth");
  std::ofstream depth_txt(dir / "depth.txt");
  depth_txt << "# depth maps\n# timestamp filename\n";
  for (int f = 0; f < n; ++f) {
    const auto r = scene.render(f);
    app::Image16 img{r.exact_depth.width, r.exact_depth.height, {}};
    for (float z : r.exact_depth.depth_m) img.pixels.push_back(static_cast<std::uint16_t>(z > 0 && z < 13 ? std::lround(z * 5000) : 0));
    char name[64];
    std::snprintf(name, sizeof(name), "depth/%.6f.png", kT0 + f / 30.0);
    app::writePng16((dir / name).string(), img);
    depth_txt << std::fixed << kT0 + f / 30.0 << " " << name << "\n";
  }
  std::ofstream gt(dir / "groundtruth.txt");
  gt << "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n";
  const double gap_t = gap_frame / 30.0;
  for (double t = -0.05; t < n / 30.0 + 0.05; t += 0.01) {
    if (std::abs(t + 0.003 - gap_t) < 0.02) continue;
    sim::writeTumPoseLine(gt, kT0 + t + 0.003, scene.cameraPoseAt(t + 0.003));
  }
  return dir.string();
}

}  // namespace mobmap
