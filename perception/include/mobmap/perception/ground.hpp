#pragma once
/// @file ground.hpp
/// Paper step 5, the ground: RANSAC plane with the adaptive iteration count of eq. 6,
/// and the least-squares plane it is refitted with.

#include <Eigen/Core>

#include <optional>
#include <random>
#include <vector>

namespace mobmap::perception {

/// A plane n.x + d = 0 with unit n, and its inliers.
struct PlaneFit {
  Eigen::Vector4f plane = Eigen::Vector4f::Zero();
  std::vector<int> inliers;
  int iterations = 0;
};

/// Options of ransacPlane().
struct RansacOptions {
  double distance_m = 0.02;
  double probability = 0.99;   ///< p in eq. 6
  int max_iterations = 1000;
  /// If set, only planes whose normal is within max_tilt_deg of this unit vector qualify.
  std::optional<Eigen::Vector3f> required_normal;
  double max_tilt_deg = 20.0;
  /// With required_normal: the origin (the camera) must lie on the side the required
  /// normal points to, so a floor below the camera qualifies and a ceiling above it not.
  bool origin_on_normal_side = false;
  /// If normals are given, inliers must also have a normal within this angle of the plane's.
  const std::vector<Eigen::Vector3f>* point_normals = nullptr;
  double normal_tolerance_deg = 180.0;
  /// Hypotheses are scored on a fixed random subset of this many candidates (0: all),
  /// and w in eq. 6 is the inlier ratio on that subset; the winning plane's inliers
  /// are then counted on all candidates. 4096 points estimate a ratio to about 1%.
  std::size_t score_sample = 4096;
};

/// RANSAC plane among `candidates` (indices into points) with the adaptive number of
/// iterations of paper eq. 6: N = log(1-p) / log(1-w^3), w the best inlier ratio so
/// far (estimated on `score_sample` points). The returned plane is refitted by least
/// squares to its inliers. nullopt if no qualifying plane has 3 or more inliers.
std::optional<PlaneFit> ransacPlane(const std::vector<Eigen::Vector3f>& points, const std::vector<int>& candidates,
                                    const RansacOptions& options, std::mt19937& rng);

/// Least-squares plane (PCA) through the given points; normal is unit, sign arbitrary.
/// Also returns the RMS distance of the points to it.
Eigen::Vector4f leastSquaresPlane(const std::vector<Eigen::Vector3f>& points, const std::vector<int>& indices,
                                  double* rms = nullptr);

/// Angle in degrees between the image's up axis (-y, OpenCV camera axes) and a camera-
/// frame plane's normal turned towards the camera (the origin): near 0 for a floor below
/// the camera, near 90 for a wall, near 180 for a ceiling above it.
[[nodiscard]] double imageUpTiltDeg(const Eigen::Vector4f& plane);

}  // namespace mobmap::perception
