#pragma once
// The simulator's ground_truth.json as geometry, and map evaluation against it.

#include "mobmap/mapping/mobility_map.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace mobmap::app {

struct TruthSurface {
  int id = 0;
  std::string name, kind;
  double slope_deg = 0, roughness = 1, expected_mobility = 0;
  bool seen = true;  ///< false when ground_truth.json says no frame shows it (pixels_seen 0)
  std::vector<std::vector<Eigen::Vector3d>> polygons;  ///< convex, world frame, final positions
  bool pyramid_field = false;
  /// A rough field of the rough yard: the prism over its footprint (polygons) up to top_m.
  bool rough_field = false;
  double top_m = 0;
  double x0 = 0, y0 = 0, pitch = 0, height = 0;
  int nx = 0, ny = 0;
  /// Distance from `p` (world frame) to the surface.
  [[nodiscard]] double distance(const Eigen::Vector3d& p) const;
};

struct GroundTruth {
  Eigen::Vector3d gravity_down = Eigen::Vector3d(0, 0, -1);
  std::vector<TruthSurface> surfaces;
};

/// Reads ground_truth.json; moving surfaces are placed where they are at the end of
/// the sequence. IoError naming the file on any format problem.
GroundTruth loadGroundTruth(const std::string& path);

struct SurfaceScore {
  const TruthSurface* surface = nullptr;
  int voxels = 0;                ///< observed surface voxels with a mobility, assigned to it
  double mean_abs_error = 0;     ///< mean |mobility - expected|
  double worst_abs_error = 0;
  double right_side = 0;         ///< fraction on the same side of 0.5 as expected
  double area_observed_m2 = 0;   ///< voxels * resolution^2 / cos(slope)
};

struct Evaluation {
  std::vector<SurfaceScore> surfaces;
  int unassigned = 0;  ///< surface voxels farther than the tolerance from any truth surface
  int edge_voxels = 0;  ///< voxels whose cell also touches a surface with a different answer
  double edge_mean_abs_error = 0;      ///< edge voxels: mean |mobility - nearest surface's|
  double edge_mean_abs_error_any = 0;  ///< edge voxels: mean of the smallest error over the surfaces they touch
  // Traversable (>= 0.5) confusion over all assigned voxels.
  int true_traversable = 0, false_traversable = 0, true_untraversable = 0, false_untraversable = 0;
};

/// Assigns each surface voxel with a mobility and at least `min_count` observations to
/// the nearest ground-truth surface within `tolerance_m` and scores it.
Evaluation evaluateMap(const mapping::MobilityMap& map, const GroundTruth& truth, int min_count, double tolerance_m,
                       double edge_band_m = -1);
/// The result points into `truth`, so a temporary cannot be evaluated.
Evaluation evaluateMap(const mapping::MobilityMap& map, GroundTruth&& truth, int min_count, double tolerance_m,
                       double edge_band_m = -1) = delete;

}  // namespace mobmap::app
