#pragma once
/// @file stages.hpp
/// The pipeline's stages as separate functions, so each can be tested against a
/// brute-force reference. FramePipeline chains them.

#include "mobmap/perception/neighbours.hpp"
#include "mobmap/perception/triangulator.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <optional>
#include <random>
#include <vector>

namespace mobmap::perception {

/// Voxel-grid reduction: the centroid of the points in each occupied cubic voxel of
/// `voxel_m` (grid aligned to the origin), in order of first occurrence.
/// `voxel_of_point` (optional) receives the output index of each input point.
/// A centroid is the mean of its points summed in input order in double precision.
std::vector<Eigen::Vector3f> voxelReduce(const std::vector<Eigen::Vector3f>& points, float voxel_m,
                                         std::vector<int>* voxel_of_point = nullptr);

/// Statistical outlier removal (paper eq. 1): mean distance d_i to the k nearest
/// neighbours; keep points with |d_i - mu| <= alpha sigma over the cloud. Returns the
/// mask of kept points. Points without k neighbours within the graph are removed.
/// k defaults to graph.k; a smaller k uses the first k entries of each row.
std::vector<bool> statisticalOutlierMask(const KnnGraph& graph, double alpha, int k = 0);

/// PCA normals (paper eqs. 2-3): eigenvector of the smallest eigenvalue of the
/// neighbourhood covariance (the point and its graph neighbours), oriented towards
/// `viewpoint` (eq. 4). Curvature = lambda_min / (sum of eigenvalues). Points with
/// fewer than 3 neighbours get a zero normal and curvature 1. If `projected` is given
/// it receives each point moved onto its neighbourhood's least-squares plane.
/// Fast path: with `near` (a unit vector per point not far from the answer, such as the
/// previous smoothing pass's normal or the direction to the camera), the eigenvector is
/// found by inverse iteration from it (multiplying by the covariance's adjugate, which
/// amplifies the smallest eigenvector by lambda_1 / lambda_0 per step, ~100 on a noisy
/// surface) until a step moves it by under 1e-5 rad, instead of the closed-form
/// eigen-decomposition; tests bound the difference. Points whose
/// `near` is zero, whose iteration does not converge in 8 steps, or whose smallest
/// eigenvalue exceeds a quarter of the sum (no plane) use the exact solver.
void estimateNormals(const std::vector<Eigen::Vector3f>& points, const KnnGraph& graph,
                     const Eigen::Vector3f& viewpoint, std::vector<Eigen::Vector3f>& normals,
                     std::vector<float>& curvature, std::vector<Eigen::Vector3f>* projected = nullptr,
                     const std::vector<Eigen::Vector3f>* near = nullptr);

/// For the points listed in `which` only: `projected[i]` = point i moved onto the
/// least-squares plane of itself and its first `max_neighbours` graph neighbours (the
/// nearest, graph rows being sorted), as estimateNormals' `projected` with a
/// narrower neighbourhood. Other entries are left as they are. `projected` must have
/// one entry per point.
void projectOntoLocalPlanes(const std::vector<Eigen::Vector3f>& points, const KnnGraph& graph, int max_neighbours,
                            const std::vector<int>& which, std::vector<Eigen::Vector3f>& projected);

/// RGB-N colours (paper eq. 5): each normal component mapped to 0-255 with the
/// cloud's own min and max of that component.
std::vector<std::array<std::uint8_t, 3>> normalColours(const std::vector<Eigen::Vector3f>& normals);

/// ITU-R BT.601 full-range RGB -> (Y, Cr, Cb), each 0-255.
Eigen::Vector3f rgbToYCrCb(const std::array<std::uint8_t, 3>& rgb);

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

/// Region growing on colours (paper Algorithm 1): a neighbour joins the region of the
/// point it is reached from if it is within `max_distance_m` and the Euclidean
/// distance of their YCrCb colours is at most `colour_threshold`. Only points with
/// `eligible[i]` take part. Regions smaller than `min_points` are dropped (label -1).
/// With `normals`, a point also needs a normal within `max_deviation_deg` of the mean
/// normal of the region so far: normals estimated across a crease turn gradually from
/// one face to the other, and neighbour-to-neighbour colour steps alone would carry a
/// region round the edge of a box onto its sides. Ignored if `max_deviation_deg` >= 180.
/// Returns a label per point (0, 1, ... in order of seeds) and the number of regions.
std::vector<int> growRegions(const std::vector<Eigen::Vector3f>& points,
                             const std::vector<std::array<std::uint8_t, 3>>& colours, const KnnGraph& graph,
                             const std::vector<bool>& eligible, double colour_threshold, double max_distance_m,
                             int min_points, int* regions, const std::vector<Eigen::Vector3f>* normals = nullptr,
                             double max_deviation_deg = 180.0);

/// Rough surfaces. Region growing on normal colours splits a surface whose normal
/// turns faster than the colour threshold allows (gravel, rubble, a pyramid field)
/// into fragments, each too small to stand on and most too small to be kept, and the
/// surface would be scored as a scatter of steep facets, or not at all. This joins
/// them: `labels` holds every grown region (growRegions with min_points 1, -1 for
/// points that took no part). Regions under `fragment_max_points` points or
/// `fragment_max_width_m` wide (a row of faces touching at their corners) are fragments;
/// fragment points connected through graph neighbours within
/// `max_neighbour_distance_m` form groups, and a group of at least `min_fragments`
/// fragments and `min_points` points, at least `min_width_m` wide in both directions
/// (sqrt(12) standard deviations: a strip of fragments along a crease is not a rough
/// surface), whose point normals lean on average at least `min_spread_deg` from its
/// mean plane (rough: fragments of a smooth surface that noise broke up lean only a
/// few degrees) and, if `up` is given, with a mean plane at most `max_slope_deg` from
/// horizontal (walking surfaces: a staircase or wall seen at a range where noise
/// fragments it is not rough ground), becomes one region, whose slope and roughness
/// are then those of the rough surface as a whole. Other regions under
/// `min_segment_points` are dropped. If `ground` (a mask of the ground's points) is
/// given, fragments on either side of one ground point within that distance of both
/// connect: the floor's RANSAC band takes the bottoms of a rough surface's valleys,
/// and without noise the strips it leaves cut the surface into rows too narrow to
/// pass the width test. Returns the final labels (0.. in order of first
/// point, -1 none); `regions` gets their number and `rough` (if given) a flag per
/// region for the merged ones.
std::vector<int> mergeFragments(const std::vector<Eigen::Vector3f>& points, const std::vector<Eigen::Vector3f>& normals,
                                const KnnGraph& graph, double max_neighbour_distance_m, const std::vector<int>& labels,
                                int min_segment_points, int fragment_max_points, double fragment_max_width_m,
                                int min_fragments, int min_points, double min_width_m, double min_spread_deg,
                                const std::optional<Eigen::Vector3f>& up, double max_slope_deg, int* regions,
                                std::vector<bool>* rough = nullptr, const std::vector<bool>* ground = nullptr);

/// The ground plane's RANSAC band also takes the creases of a rough surface that lie
/// in it (the valleys of a pyramid field standing on the floor, whose normals average
/// to "up"), which cuts the surface into pieces and its creases out of its area. A
/// ground point most of whose graph neighbours within `max_neighbour_distance_m`
/// (more than `min_fraction`) belong to rough regions moves into the one most of them
/// belong to; repeated up to `passes` times. Updates `labels` and `ground`; returns how
/// many moved. Follow with joinTouchingRoughRegions: a valley filled in this way
/// connects the pieces it separated.
/// Rough regions with graph neighbours (within `max_neighbour_distance_m`) in another
/// rough region become one region. Labels are renumbered (survivors keep their
/// order); `region_is_rough` and `regions` are updated. Returns the number of joins.
int joinTouchingRoughRegions(const KnnGraph& graph, double max_neighbour_distance_m, std::vector<bool>& region_is_rough,
                             std::vector<int>& labels, int* regions);

std::size_t absorbGroundIntoRough(const KnnGraph& graph, double max_neighbour_distance_m,
                                  const std::vector<bool>& region_is_rough, double min_fraction, int passes,
                                  std::vector<int>& labels, std::vector<bool>& ground);

/// Gives points that region growing left out (colour jumps between neighbours under
/// sensor noise break a plane into a large region and many specks below the size
/// limit) to the region next to them whose plane they lie on. In rounds, every
/// unsegmented point that is not ground, has a normal, and has a graph neighbour
/// within `max_neighbour_distance_m` in region r joins the r (not excluded by
/// `region_excluded`) whose plane `region_planes[r]` it is closest to, if that
/// distance is at most `max_plane_distance_m` and its normal is within
/// `max_angle_deg` of the plane's. Updates `labels`; returns how many points joined.
std::size_t adoptUnsegmentedPoints(const std::vector<Eigen::Vector3f>& points,
                                   const std::vector<Eigen::Vector3f>& normals, const KnnGraph& graph,
                                   double max_neighbour_distance_m, const std::vector<Eigen::Vector4f>& region_planes,
                                   const std::vector<bool>& region_excluded, double max_plane_distance_m,
                                   double max_angle_deg, std::vector<int>& labels, const std::vector<bool>& ground);

/// Gives back to a tilted region the ground inliers that continue it. RANSAC takes
/// every point within its distance of the floor plane, which includes the foot of a
/// gentle ramp (a 5 degree ramp stays within 2 cm of the floor for its first 23 cm).
/// Starting from each region whose plane (`region_planes[r]`) is between
/// `min_angle_deg` and `max_angle_deg` from the ground's (a ramp, not a wall: the foot
/// of a steep face loses under 2 cm to the ground, and floor points at a wall's base
/// must stay floor), a breadth-first walk over graph neighbours
/// within `max_neighbour_distance_m` moves a ground point into the region when it
/// is closer to the region's plane than to the ground plane and within
/// `max_plane_distance_m` of it, and, if `normals` are given, when the point's normal
/// is closer to the region's plane normal than to the ground's (along the line where a
/// ramp's plane meets the floor, extended past the ramp's sides, noisy floor points are
/// as close to one plane as to the other, and without this test the walk spreads
/// along that line). Those two tests are skipped, and the point taken, when its foot
/// on the ground plane lies under the region: on the side of the line where the two
/// planes meet that the region stands over, with the region's plane more than 7 mm
/// above the ground plane there, and within the region's extent along the line (near
/// the line noise makes both tests a coin toss); a point whose foot has the region's
/// plane more than 7 mm below the ground plane (in front of a ramp) stays ground. Not
/// for regions with `(*no_footprint)[r]` (rough ones: their plane is only a mean, and
/// a level rough patch's can lean a few degrees and stand over floor it does not cover).
/// Updates `labels` (region per point, -1 none) and `ground` (ground mask); returns how
/// many points moved.
std::size_t reclaimGroundPoints(const std::vector<Eigen::Vector3f>& points, const KnnGraph& graph,
                                double max_neighbour_distance_m, const Eigen::Vector4f& ground_plane,
                                const std::vector<Eigen::Vector4f>& region_planes, double min_angle_deg,
                                double max_angle_deg, double max_plane_distance_m, std::vector<int>& labels,
                                std::vector<bool>& ground,
                                const std::vector<Eigen::Vector3f>* normals = nullptr,
                                const std::vector<bool>* no_footprint = nullptr);


/// 2D Delaunay triangulation of `points`: index triples, counter-clockwise, in no
/// particular order. Duplicate points are triangulated once; collinear points give none;
/// points with a non-finite coordinate are left out.
std::vector<std::array<int, 3>> delaunayTriangles(const std::vector<Eigen::Vector2d>& points,
                                                  Triangulator which = Triangulator::kOwn);

/// Roughness r = A / A' (paper eqs. 8-10) of a segment: 2D Delaunay triangulation of the
/// points projected on `plane`; A sums the triangles' 3D areas, A' the areas of the same
/// triangles in the plane. Triangles with an edge longer than `max_edge_m` (in 3D)
/// bridge gaps and are skipped. Returns {r, A}; r = 1 and A = 0 when fewer than 3 points
/// or no triangle remain (collinear, degenerate).
std::pair<double, double> delaunayRoughness(const std::vector<Eigen::Vector3f>& points,
                                            const std::vector<int>& indices, const Eigen::Vector4f& plane,
                                            double max_edge_m, Triangulator which = Triangulator::kOwn);

}  // namespace mobmap::perception
