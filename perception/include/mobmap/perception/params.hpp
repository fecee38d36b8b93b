#pragma once
/// @file params.hpp
/// PerceptionParams: every tunable of the per-frame pipeline, grouped by the paper's
/// steps, with its checks and its rescaling to another voxel size.

#include "mobmap/perception/triangulator.hpp"

#include <cstdint>

namespace mobmap::perception {

/// Every tunable of the pipeline, with units in the names. Defaults follow the paper
/// where it gives a value (1 cm voxels, RANSAC with p = 0.99) and our measurements
/// elsewhere; docs/PERCEPTION.md says which is which.
struct PerceptionParams {
  // 1. Data reduction
  double min_range_m = 0.3;    ///< points closer than this (Euclidean range) are dropped
  double max_range_m = 3.0;    ///< points farther than this are dropped (paper: 1.5-2 m)
  double voxel_size_m = 0.01;  ///< voxel grid reduction (paper: 1 cm); output = voxel centroids
  // 2. Statistical outlier removal (paper eq. 1)
  int outlier_k = 16;            ///< neighbours for the mean distance
  double outlier_alpha = 2.0;    ///< keep mean distance within mu +- alpha sigma
  // 3. Normals (paper eqs. 2-4)
  int normal_k = 30;  ///< neighbours of the least-squares plane
  // 5. Ground (paper eq. 6)
  double ground_distance_m = 0.02;        ///< RANSAC inlier distance
  double ground_probability = 0.99;       ///< p: chance of drawing one outlier-free sample
  int ground_max_iterations = 1000;
  double ground_max_tilt_deg = 20.0;      ///< with gravity: plane normal within this of "up"
  /// Without gravity the paper takes the largest plane, which is a wall when a wall
  /// fills more of the view than the floor. If the largest plane's normal leans more
  /// than this from the image's up axis (-y in OpenCV camera axes: a camera held
  /// roughly upright), the largest plane below the camera within this cone is the
  /// ground instead, provided it has ground_min_points and is not within 5 degrees of
  /// the cone's edge (that is the leaning surface fitted at the edge, not a floor).
  /// 0 follows the paper.
  double ground_upright_prior_deg = 45.0;
  double ground_normal_tolerance_deg = 25.0;  ///< inliers' own normals within this of the plane's
  int ground_min_points = 500;            ///< fewer inliers: "no floor in view"
  /// Ground inliers that continue a region tilted at least this much from the floor
  /// (the foot of a gentle ramp) go back to that region; 0 turns this off.
  double ground_reclaim_min_angle_deg = 3.0;
  /// ... and at most this much (ramps, not walls: floor at a wall's base stays floor).
  double ground_reclaim_max_angle_deg = 30.0;
  // 6. Region growing (paper Algorithm 1)
  double colour_threshold = 12.0;       ///< max YCrCb distance between neighbours (0-255 scale)
  double neighbour_distance_m = 0.025;  ///< neighbours farther apart are not connected
  int min_segment_points = 50;
  /// A point joins a region only if its normal is within this angle of the region's
  /// mean normal (stops regions creeping round creases); 180 turns it off.
  double region_max_normal_deviation_deg = 40.0;
  /// Points colour growing left out (noise breaks a plane into a region and specks)
  /// join the neighbouring region whose plane is within adopt_max_distance_m of them
  /// if their normal is within this angle of that plane's; 0 turns it off (the
  /// paper's segmentation). See adoptUnsegmentedPoints in departures.hpp.
  double adopt_max_angle_deg = 40.0;
  double adopt_max_distance_m = 0.02;
  /// Rough surfaces (see mergeFragments in departures.hpp): regions smaller than this are
  /// fragments, and connected groups of them are joined into one segment; 0 turns it off.
  int rough_fragment_max_points = 150;
  double rough_fragment_max_width_m = 0.08;  ///< narrower regions are fragments too
  int rough_min_fragments = 3;   ///< a group needs at least this many fragments ...
  int rough_min_points = 100;    ///< ... and this many points
  double rough_min_width_m = 0.15;  ///< ... and this width both ways (not a strip along an edge)
  double rough_min_normal_spread_deg = 20.0;  ///< ... and normals leaning this much off its plane on average
  double rough_max_slope_deg = 20.0;  ///< ... and a mean plane this close to level (gravity or ground)
  // 7. Surface properties
  double plane_ransac_distance_m = 0.01;  ///< floor of the RANSAC refinement threshold
  double max_triangle_edge_m = 0.05;      ///< Delaunay triangles with a longer edge span gaps: skipped
  /// Who triangulates (the library, or CGAL as the reference): same triangles, see
  /// Triangulator.
  Triangulator triangulator = Triangulator::kOwn;
  /// Measure roughness on points projected onto their local least-squares plane (the
  /// plane of their normal, one planar moving-least-squares step) instead of the raw
  /// voxel centroids. Removes sensor noise and depth quantisation below the normal
  /// neighbourhood's scale, which otherwise inflates A/A' with range; false follows the
  /// paper literally.
  bool roughness_smoothing = true;
  /// How many times the projection is applied (each pass re-fits the planes on the
  /// previous pass's points with the same neighbours, widening the smoothing scale).
  int roughness_smoothing_passes = 3;
  /// Rough segments (joined fragments) are measured after one projection only, with
  /// this many nearest neighbours (at most normal_k): their roughness is creases at
  /// the fragments' scale, which wider or repeated smoothing rounds off.
  int rough_smoothing_k = 30;
  /// Roughness at foot scale (docs/ALGORITHM.md, "Roughness"): points of a surface on
  /// which no flat square of foot_support_m fits (a ridge face, a block top, the floor
  /// between stones, any rough segment) are scored by the ground around them: slope and
  /// area ratio A/A' over all points within foot_window_m / 2, A/A' from the points'
  /// normals against the window's mean plane. 0 switches it off (the paper: every
  /// segment on its own).
  double foot_window_m = 0.0;
  double foot_support_m = 0.10;  ///< side of the flat square a surface must hold
  std::uint32_t random_seed = 42;         ///< RANSAC sampling (results are deterministic)
};

/// Throws std::invalid_argument "PerceptionParams: <field> is <value> (<rule>)".
void validate(const PerceptionParams& params);

/// `params` (taken as tuned for its own voxel_size_m) moved to voxels of `voxel_m`,
/// keeping the physical sizes: with f = voxel_m / params.voxel_size_m, the point
/// counts that stand for an area (min_segment_points, ground_min_points,
/// rough_fragment_max_points, rough_min_points; rough_smoothing_k with the point
/// itself: (k + 1) / f^2 - 1) are divided by f^2
/// and the distances tied to the sample spacing (neighbour_distance_m,
/// max_triangle_edge_m) multiplied by f. normal_k and outlier_k stay: at 2 cm, 30
/// neighbours span ~6 cm, the normal radius of the paper's own code. Everything else
/// is physical (metres of noise or width, degrees) and stays. Throws
/// std::invalid_argument unless voxel_m is in [0.001, 1].
[[nodiscard]] PerceptionParams scaledToVoxel(const PerceptionParams& params, double voxel_m);

}  // namespace mobmap::perception
