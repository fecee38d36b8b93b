#pragma once
/// @file frame_result.hpp
/// What the per-frame pipeline gives: the scored points and segments of one frame
/// (camera frame, metres). Kept apart from pipeline.hpp so that code which only fuses
/// or stores results needs none of the pipeline's parameters and model.

#include <Eigen/Core>

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace mobmap::perception {

/// How the ground plane was chosen.
enum class GroundRule {
  kNone,          ///< no plane with ground_min_points inliers
  kGravity,       ///< the largest plane within ground_max_tilt_deg of gravity's "up"
  kLargestPlane,  ///< no gravity: the largest plane (the paper)
  kUprightPrior,  ///< no gravity: the largest plane leaned away, a floor in the upright cone was found
};
const char* toString(GroundRule r);

/// What the slope of a segment is measured against.
enum class SlopeReference {
  kGravity,  ///< "up" from a known gravity direction
  kGround,   ///< the ground plane's normal (paper eq. 7)
  kCamera,   ///< neither known: the camera's -y axis
};
const char* toString(SlopeReference r);

/// Time and point counts of one stage (the paper's Table II).
struct StageTiming {
  std::string name;
  double milliseconds = 0.0;
  std::size_t points_in = 0;
  std::size_t points_out = 0;
};

/// One surface segment.
struct Segment {
  int id = 0;                   ///< 0 is the ground when one was found
  bool is_ground = false;
  bool is_rough = false;        ///< joined from fragments (a rough surface, see mergeFragments)
  std::vector<int> points;      ///< indices into FrameResult::points
  Eigen::Vector3f centroid = Eigen::Vector3f::Zero();  ///< camera frame, metres
  Eigen::Vector3f normal = Eigen::Vector3f::Zero();    ///< unit, towards the camera
  double slope_deg = 0.0;
  double roughness = 1.0;       ///< A / A' (paper eqs. 8-10)
  double mobility = 0.0;        ///< [0,1]
  double variance = 0.0;        ///< of the mobility
  double area_m2 = 0.0;         ///< true (3D) area of the triangulation
};

/// Where a frame's points lay and what the range limits (min_range_m, max_range_m) took
/// from it: enough to tell a range that cuts away most of a frame or its floor, and
/// depth in the wrong unit. Ranges are Euclidean distances from the camera.
struct RangeReport {
  std::size_t valid_points = 0;     ///< finite points in front of the camera
  std::size_t beyond_max_range = 0;  ///< dropped: farther than max_range_m
  std::size_t nearer_than_min_range = 0;  ///< dropped: nearer than min_range_m
  double min_range_m = 0, max_range_m = 0;  ///< the limits applied
  /// Percentiles of the valid points' ranges (from a sample of about one point in 16);
  /// 0 when no point was valid.
  double median_range_m = 0, range_p95_m = 0;
  /// The lowest surface in view: the points within 8 cm of the 98th percentile of height
  /// below the camera along `down`: gravity when the frame had it, else the normal of the
  /// ground plane found, else the camera's +y.
  struct Lowest {
    double below_camera_m = 0;  ///< its depth below the camera along down
    double share_beyond = 0;    ///< of its points, the share farther than max_range_m
    double range_p95_m = 0;     ///< the range within which 95 % of its points lie
    std::size_t sampled = 0;    ///< its points in the sample
  };
  std::optional<Lowest> lowest;  ///< unset when the sample is too small (under 200 points)
  bool down_from_gravity = false;
  bool down_from_ground = false;  ///< down was the ground plane's normal (no gravity)
  /// beyond_max_range / valid_points (0 for no valid point).
  [[nodiscard]] double shareBeyond() const {
    return valid_points ? static_cast<double>(beyond_max_range) / static_cast<double>(valid_points) : 0.0;
  }
};

/// Output of FramePipeline::process().
struct FrameResult {
  std::vector<StageTiming> stages;
  /// Reduced, denoised points (camera frame) and their per-point attributes.
  std::vector<Eigen::Vector3f> points;
  std::vector<Eigen::Vector3f> normals;
  std::vector<float> curvature;
  std::vector<std::array<std::uint8_t, 3>> colours;  ///< RGB-N (eq. 5)
  std::vector<int> segment_of_point;                  ///< index into segments, -1 = none
  std::vector<Segment> segments;
  std::optional<Eigen::Vector4f> ground_plane;  ///< n.x + d = 0, n towards the camera
  GroundRule ground_rule = GroundRule::kNone;
  SlopeReference reference = SlopeReference::kCamera;
  /// For organized input: the index into `points` of each pixel's voxel, -1 if the
  /// pixel was invalid, cropped or removed as an outlier. Empty for unorganized input.
  std::vector<int> point_of_pixel;
  RangeReport range;  ///< what the range limits took, and where the points lay
  [[nodiscard]] double totalMilliseconds() const;
};

}  // namespace mobmap::perception
