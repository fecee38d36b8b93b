#pragma once
// A building-scale voxel scene for planning tests and benchmarks, every voxel set from
// its geometry (exact mobility, no sensor): a ground floor of size x size metres with
// two corridors crossing at its centre, eight rooms off them through 1 m doors, rough
// patches (one too poor to stand on, two walkable but costly), and over one quadrant an
// upper floor 3 m up reached by a straight staircase of 12 cm risers and 30 cm treads.
// Walls are one voxel thick and 1 m tall (higher than any swing), the upper floor one
// voxel thick with an opening over the stairs. A building of 40 m has ~6 million voxels
// (a few seconds to make); tests use a smaller one.
#include "mobmap/mapping/mobility_octree.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

namespace mobmap::mapping::building {

struct Params {
  double size_m = 40.0;  ///< at least 20 (the stairs are 7.5 m long)
  double resolution_m = 0.02;
  std::uint64_t seed = 5;  ///< the rough patches' bumps
};

/// A named start and goal on it, and roughly how far a walk between them is.
struct Trip {
  std::string name;
  Eigen::Vector3d from, to;
};

struct Scene {
  explicit Scene(const Params& p = {}) : params(p), tree(p.resolution_m) { make(); }

  Params params;
  MobilityOcTree tree;
  double floor2_top_m = 0;  ///< the upper floor's top face
  std::vector<Trip> trips;  ///< plans of about 10, 30 and 60 m (a building of 40 m)

 private:
  long n_ = 0;             // voxels along a side
  double res_ = 0;

  long idx(double m) const { return static_cast<long>(std::floor(m / res_ + 1e-9)); }
  double z(long k) const { return (static_cast<double>(k) + 1.0) * res_; }  // top face of voxel layer k

  void put(long i, long j, long k, double mobility) {
    const octomap::OcTreeKey key = tree.coordToKey((i + 0.5) * res_, (j + 0.5) * res_, (k + 0.5) * res_);
    auto* n = tree.updateNode(key, true, /*lazy_eval=*/true);
    n->setMobility(mobility, 100.0, 3);
  }
  // A wall one voxel thick and 1 m tall along a line of constant i (or j), from a to b
  // (voxels), standing on the floor whose top voxel is layer k0.
  void wall(bool along_j, long at, long a, long b, long k0, const std::vector<std::pair<long, long>>& doors) {
    const long height = idx(1.0);
    for (long t = a; t < b; ++t) {
      bool door = false;
      for (const auto& [d0, d1] : doors) door = door || (t >= d0 && t < d1);
      if (door) continue;
      for (long k = k0 + 1; k <= k0 + height; ++k) along_j ? put(at, t, k, 0.0) : put(t, at, k, 0.0);
    }
  }

  void make() {
    res_ = params.resolution_m;
    const double S = params.size_m;
    n_ = idx(S);
    const auto door = [&](double centre_m) { return std::make_pair(idx(centre_m - 0.5), idx(centre_m + 0.5)); };
    const double c0 = 0.45 * S, c1 = 0.55 * S;  // the corridors' sides (4 m wide in a building of 40 m)

    // Rough patches: (x0, y0, side, mobility); the first too poor to stand on.
    struct Patch {
      double x0, y0, side, mobility;
    };
    const std::vector<Patch> patches = {{0.6 * S, 0.65 * S, 0.1 * S, 0.3},
                                        {0.7 * S, 0.15 * S, 0.08 * S, 0.7},
                                        {0.15 * S, 0.7 * S, 0.08 * S, 0.8}};
    // The staircase: along +x from (sx, sy), 25 risers of 12 cm (6 voxels), 30 cm treads.
    const long riser = 6, tread = idx(0.3), steps = 25;
    const long sx = idx(0.05 * S), sy0 = idx(0.05 * S), sy1 = sy0 + idx(1.4);
    const long stairs_end = sx + steps * tread;
    const long k_floor2 = steps * riser;  // the upper floor's voxel layer
    floor2_top_m = z(k_floor2);
    const long up = idx(c0);  // the upper floor covers [0, c0) x [0, c0)

    for (long i = 0; i < n_; ++i) {
      for (long j = 0; j < n_; ++j) {
        // Ground floor: layer 0, bumps of up to 3 voxels in the rough patches.
        double mob = 1.0;
        long top = 0;
        for (const Patch& p : patches) {
          if (i >= idx(p.x0) && i < idx(p.x0 + p.side) && j >= idx(p.y0) && j < idx(p.y0 + p.side)) {
            mob = p.mobility;
            // Bumps constant over 10 x 10 cm cells.
            std::mt19937_64 cell(params.seed ^ (static_cast<std::uint64_t>(i / 5) * 1000003u + static_cast<std::uint64_t>(j / 5)));
            top = static_cast<long>(cell() % 3);
          }
        }
        for (long k = 0; k <= top; ++k) put(i, j, k, k == top ? mob : 0.0);
        // The staircase: solid under each tread.
        if (i >= sx && i < stairs_end && j >= sy0 && j < sy1) {
          const long step = (i - sx) / tread + 1;
          for (long k = 1; k <= step * riser; ++k) put(i, j, k, k == step * riser ? 1.0 : 0.0);
        }
        // The upper floor, open over the stairs.
        if (i < up && j < up && !(i >= sx - 1 && i < stairs_end && j >= sy0 - 1 && j <= sy1)) put(i, j, k_floor2, 1.0);
      }
    }
    // Outer walls.
    wall(true, 0, 0, n_, 0, {});
    wall(true, n_ - 1, 0, n_, 0, {});
    wall(false, 0, 0, n_, 0, {});
    wall(false, n_ - 1, 0, n_, 0, {});
    // Corridor walls with doors into the rooms (two per room side), open where the
    // corridors cross.
    const long a = idx(c0), b = idx(c1);
    const std::vector<std::pair<long, long>> doors = {door(0.1 * S), door(0.3 * S), door(0.7 * S), door(0.9 * S),
                                                      {a, b}};
    for (const long at : {a, b}) {
      wall(false, at, 1, n_ - 1, 0, doors);  // along x, at y = c0 and c1
      wall(true, at, 1, n_ - 1, 0, doors);   // along y, at x = c0 and c1
    }
    // Each quadrant split in two rooms by a wall with one door.
    wall(true, idx(0.225 * S), 1, a, 0, {door(0.3 * S)});
    wall(true, idx(0.775 * S), 1, a, 0, {door(0.2 * S)});
    wall(false, idx(0.775 * S), b + 1, n_ - 1, 0, {door(0.85 * S)});
    wall(true, idx(0.225 * S), b + 1, n_ - 1, 0, {door(0.75 * S)});
    // The upper floor's own walls: its edges over the corridors, a door-less rail along
    // the stair opening's far side, one inner wall with a door.
    wall(true, up - 1, 0, up, k_floor2, {});
    wall(false, up - 1, 0, up, k_floor2, {});
    wall(true, idx(0.3 * S), sy1 + 2, up - 1, k_floor2, {door(0.35 * S)});

    tree.updateInnerOccupancy();
    const double g = 0.05, f2 = floor2_top_m + 0.03;
    trips = {{"along the corridor, ~10 m", {0.05 * S, 0.5 * S, g}, {0.3 * S, 0.5 * S, g}},
             {"room to room across the crossing, ~30 m", {0.1 * S, 0.8 * S, g}, {0.8 * S, 0.4 * S, g}},
             {"far room to the upper floor by the stairs, ~60 m", {0.9 * S, 0.9 * S, g}, {0.2 * S, 0.3 * S, f2}}};
  }
};

}  // namespace mobmap::mapping::building
