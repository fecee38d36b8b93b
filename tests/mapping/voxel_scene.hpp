#pragma once
// An analytic voxel scene shared by the mapping tests: floors, stairs, a ledge, a table,
// a walled room, a hole, a dais and a strip of poor floor, every voxel set by hand.
#include "mobmap/mapping/mobility_octree.hpp"

#include <octomap/octomap_types.h>

namespace mobmap::mapping {
namespace {

inline constexpr double kRes = 0.02;

// Sets voxel (i, j, k) of a 2 cm tree (voxel centres at (i + 0.5) * kRes ...) occupied with a mobility.
inline void put(MobilityOcTree& t, int i, int j, int k, double mobility) {
  auto* n = t.updateNode(octomap::point3d(static_cast<float>((i + 0.5) * kRes), static_cast<float>((j + 0.5) * kRes),
                                          static_cast<float>((k + 0.5) * kRes)),
                         true);
  n->setMobility(mobility, 100.0, 3);
}

// A floor (tops at 0.02 m) with stairs up to a platform, a ledge, a table, a walled room,
// a hole across the floor, a dais beside a noisy floor voxel and a strip of poor floor
// in front of an annex. Every region
// is a rectangle of columns [i0, i1) x [j0, j1).
struct Scene {
  MobilityOcTree tree{kRes};
  Scene() {
    // Floor x in [0, 3.0), y in [0, 2.0), except a 2-column hole at x in [0.40, 0.44)
    // and the wall ring's footprint.
    for (int i = 0; i < 150; ++i) {
      for (int j = 0; j < 100; ++j) {
        if (i == 20 || i == 21) continue;
        if (inRing(i, j)) continue;
        put(tree, i, j, 0, 1.0);
      }
    }
    // Stairs on the floor, y in [0, 0.6): treads 0.10 m apart from x = 1.0, then a
    // platform at 0.32 m; solid columns, the top voxel walkable, the rest a riser.
    for (int i = 50; i < 100; ++i) {
      const int top = i < 65 ? 5 : i < 80 ? 10 : 15;  // tops 0.12, 0.22, 0.32
      for (int j = 0; j < 30; ++j) {
        for (int k = 1; k <= top; ++k) put(tree, i, j, k, k == top ? 1.0 : 0.0);
      }
    }
    // A ledge 0.30 m above the floor (top 0.32), x in [2.3, 2.8), y in [0, 0.6).
    for (int i = 115; i < 140; ++i) {
      for (int j = 0; j < 30; ++j) {
        for (int k = 1; k <= 15; ++k) put(tree, i, j, k, k == 15 ? 1.0 : 0.0);
      }
    }
    // A table top (one voxel thick, top 0.72 m) over the floor, no legs.
    for (int i = 10; i < 40; ++i) {
      for (int j = 60; j < 90; ++j) put(tree, i, j, 35, 1.0);
    }
    // A room with a 1 m wall one voxel thick around its floor.
    for (int i = 110; i < 150; ++i) {
      for (int j = 60; j < 100; ++j) {
        if (inRing(i, j)) {
          for (int k = 0; k < 50; ++k) put(tree, i, j, k, 0.0);
        }
      }
    }
    // A dais with its top 16 cm above the floor's (0.18 m), x and y in [0.2, 0.3), and
    // beside it one floor voxel a voxel too high (noise): 14 cm from the dais's top.
    for (int i = 10; i < 15; ++i) {
      for (int j = 10; j < 15; ++j) {
        for (int k = 1; k <= 8; ++k) put(tree, i, j, k, k == 8 ? 1.0 : 0.0);
      }
    }
    put(tree, 9, 12, 1, 1.0);
    // An annex, x in [3.1, 3.5), y in [0, 0.8), reached only over floor of mobility 0.2
    // 10 cm wide along its west side (x in [3.0, 3.1)) and its north side (y in [0.8, 0.9)).
    for (int i = 150; i < 175; ++i) {
      for (int j = 0; j < 45; ++j) put(tree, i, j, 0, i < 155 || j >= 40 ? 0.2 : 1.0);
    }
  }
  static bool inRing(int i, int j) {
    return i >= 110 && i < 150 && j >= 60 && j < 100 && (i == 110 || i == 149 || j == 60 || j == 99);
  }
};

}  // namespace
}  // namespace mobmap::mapping
