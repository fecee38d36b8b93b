#pragma once
// The steps of FramePipeline::run that take more than a call (internal). Each fills its
// part of the FrameResult; pipeline.cpp times them and chains them in the paper's order.

#include "mobmap/perception/frame_result.hpp"
#include "mobmap/perception/neighbours.hpp"
#include "mobmap/perception/params.hpp"

#include <Eigen/Core>

#include <optional>
#include <random>
#include <vector>

namespace mobmap::perception::steps {

/// Paper step 3: out.normals and out.curvature of out.points. With
/// roughness_smoothing, returns the points after roughness_smoothing_passes
/// projections onto their local planes (what roughness is measured on), else nothing.
std::vector<Eigen::Vector3f> estimateNormalsAndSmooth(FrameResult& out, const KnnGraph& graph,
                                                      const PerceptionParams& p);

/// Paper step 5: the ground plane by RANSAC (with gravity: within its tilt of "up";
/// without: the largest plane, or the upright prior's floor). Sets out.ground_plane and
/// out.ground_rule; returns the ground's points (empty when no ground was found).
std::vector<int> findGround(FrameResult& out, const std::optional<Eigen::Vector3f>& up, const PerceptionParams& p,
                            std::mt19937& rng);

/// Paper step 6 and the departures that follow it (departures.hpp): colour region
/// growing on what is not ground, then rough surfaces joined, ground points given back
/// to the ramps and rough surfaces they belong to, left-out points adopted. Fills
/// out.segments (the ground first, if any) and out.segment_of_point; returns how many
/// points lie in a segment.
std::size_t segment(FrameResult& out, const KnnGraph& graph, std::vector<int> ground_points,
                    const std::optional<Eigen::Vector3f>& up, const PerceptionParams& p);

/// Paper step 7: each segment's plane, slope (against gravity, else the ground, else the
/// camera's up axis) and Delaunay roughness, measured on `smoothed` (rough segments on
/// their own single projection). Sets out.reference; returns the (slope, roughness)
/// rows the mobility model scores.
Eigen::MatrixX2d measureSurfaces(FrameResult& out, const KnnGraph& graph, const std::vector<Eigen::Vector3f>& smoothed,
                                 const std::optional<Eigen::Vector3f>& up, const PerceptionParams& p);

/// Roughness at foot scale (foot_scale.cpp): points of surfaces on which no flat square
/// of foot_support_m fits, and of rough segments, leave their segments for new ones
/// grouped by the slope and area ratio of the ground within foot_window_m of them.
/// Empty segments go; out.segments and out.segment_of_point are renumbered. Takes the
/// segments' (slope, roughness) rows and returns those of the segments that remain.
Eigen::MatrixX2d scoreAtFootScale(FrameResult& out, const Eigen::MatrixX2d& features, const Eigen::Vector3f& reference,
                                  const PerceptionParams& p);

}  // namespace mobmap::perception::steps
