#pragma once
/// @file departures.hpp
/// Where the pipeline departs from the paper, and why: five refinements of the ground and
/// the segments that real depth noise makes necessary. FramePipeline runs them between
/// the paper's steps 6 and 7; each has a PerceptionParams switch that turns it off
/// (docs/ALGORITHM.md lists them with their switches).

#include "mobmap/perception/neighbours.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <optional>
#include <vector>

namespace mobmap::perception {

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
std::size_t absorbGroundIntoRough(const KnnGraph& graph, double max_neighbour_distance_m,
                                  const std::vector<bool>& region_is_rough, double min_fraction, int passes,
                                  std::vector<int>& labels, std::vector<bool>& ground);

/// Rough regions with graph neighbours (within `max_neighbour_distance_m`) in another
/// rough region become one region. Labels are renumbered (survivors keep their
/// order); `region_is_rough` and `regions` are updated. Returns the number of joins.
int joinTouchingRoughRegions(const KnnGraph& graph, double max_neighbour_distance_m, std::vector<bool>& region_is_rough,
                             std::vector<int>& labels, int* regions);

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

}  // namespace mobmap::perception
