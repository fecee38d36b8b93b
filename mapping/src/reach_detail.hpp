#pragma once
// What computeStandability / computeReachability and the planner's quick checks share:
// how one lattice sole centre is judged and how the start soles are chosen.
#include "mobmap/mapping/reachability.hpp"

#include <Eigen/Core>

#include <cmath>
#include <cstddef>
#include <optional>
#include <utility>
#include <vector>

namespace mobmap::mapping::detail {

/// a / b rounded towards minus infinity (b > 0): the lattice cell of a voxel key.
inline long floorDiv(long a, long b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

/// A start sole's support may lie this far above the start point (a point given on the
/// floor may be a voxel low).
inline constexpr double kStartSlack = 0.1;

/// The lattice offsets (in lattice steps of `s` voxels of `res`) a step of at most
/// max_stride_m can make: what a walk over foot places tries from each.
inline std::vector<std::pair<long, long>> strideOffsets(const RobotParams& robot, long s, double res) {
  std::vector<std::pair<long, long>> offsets;
  const long rad = static_cast<long>(std::floor(robot.max_stride_m / (s * res) + 1e-9));
  for (long di = -rad; di <= rad; ++di) {
    for (long dj = -rad; dj <= rad; ++dj) {
      if ((di || dj) && std::hypot(di, dj) * s * res <= robot.max_stride_m + 1e-9) offsets.emplace_back(di, dj);
    }
  }
  return offsets;
}

/// How far (in height) from its reference the surface under a sole's sample may lie to
/// carry it: evaluateFoothold()'s band.
inline double supportBand(const RobotParams& robot, double res) {
  constexpr double kPi = 3.14159265358979323846;
  return 0.5 * std::hypot(robot.sole_length_m, robot.sole_width_m) * std::tan(robot.max_tilt_deg * kPi / 180) +
         robot.max_unevenness_m + res;
}

/// How far a standable sole's height (its plane at its centre) may lie from the top of
/// the surface it was judged on: its supports within supportBand() of that top, each
/// within max_unevenness_m of the plane, which tilts at most max_tilt_deg over the half
/// diagonal from a support to the centre.
inline double soleOffTop(const RobotParams& robot, double res) {
  constexpr double kPi = 3.14159265358979323846;
  return supportBand(robot, res) + robot.max_unevenness_m +
         0.5 * std::hypot(robot.sole_length_m, robot.sole_width_m) * std::tan(robot.max_tilt_deg * kPi / 180) + 1e-6;
}

/// The foot place on `run` at lattice column (kx, ky): its headings judged
/// (geometry_ok == 0 when no heading's geometry passes). The supports of each standable
/// heading are appended to `standable_supports` when given.
FootPlace judgeFootPlace(const SurfaceColumns& cols, long kx, long ky, std::size_t run, const RobotParams& robot,
                         std::vector<std::size_t>* standable_supports = nullptr);

/// The start soles of ReachParams::Start::kNearest: the sole centre nearest `start`
/// (then the highest) among `near` (foot places within the start radius, in lattice
/// order) with its support at most kStartSlack above the start, and every standable foot
/// place within `around` of it on its level. `within(x, y, r)` lists foot places near a
/// point; `foot(i)` gives one.
template <class Within, class FootOf>
std::vector<std::size_t> nearestStartFeet(const Eigen::Vector3d& start, const std::vector<std::size_t>& near, double around,
                                          double level_tol, Within&& within, FootOf&& foot) {
  const auto dist2 = [&](const FootPlace& f) {
    return (f.x - start.x()) * (f.x - start.x()) + (f.y - start.y()) * (f.y - start.y());
  };
  std::optional<std::size_t> ref;
  for (const std::size_t f : near) {
    const FootPlace& fp = foot(f);
    if (fp.z > start.z() + kStartSlack) continue;
    if (!ref || dist2(fp) < dist2(foot(*ref)) - 1e-12 || (dist2(fp) <= dist2(foot(*ref)) + 1e-12 && fp.z > foot(*ref).z)) {
      ref = f;
    }
  }
  std::vector<std::size_t> out;
  if (!ref) return out;
  const FootPlace c = foot(*ref);
  for (const std::size_t f : within(c.x, c.y, around)) {
    if (foot(f).isStandable() && std::abs(foot(f).z - c.z) <= level_tol) out.push_back(f);
  }
  return out;
}

}  // namespace mobmap::mapping::detail
