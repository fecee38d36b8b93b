// PerceptionParams' checks and its rescaling to another voxel size (params.hpp).

#include "mobmap/perception/params.hpp"
#include "mobmap/util/field_error.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace mobmap::perception {
namespace {

[[noreturn]] void fail(const char* field, double value, const char* rule) {
  std::ostringstream msg;
  msg << "is " << value << " (" << rule << ")";
  throw util::FieldError(field, msg.str(), "PerceptionParams");
}

}  // namespace

void validate(const PerceptionParams& p) {
  if (!(p.min_range_m >= 0) || !std::isfinite(p.min_range_m)) fail("min_range_m", p.min_range_m, "must be finite and >= 0");
  if (!(p.max_range_m > p.min_range_m) || !std::isfinite(p.max_range_m)) fail("max_range_m", p.max_range_m, "must be finite and > min_range_m");
  if (p.max_range_m > 1000) fail("max_range_m", p.max_range_m, "must be at most 1000");
  if (!(p.voxel_size_m >= 0.001 && p.voxel_size_m <= 1.0)) fail("voxel_size_m", p.voxel_size_m, "must be in [0.001, 1]");
  if (p.outlier_k < 1 || p.outlier_k > 200) fail("outlier_k", p.outlier_k, "must be 1..200");
  if (!(p.outlier_alpha > 0) || !std::isfinite(p.outlier_alpha)) fail("outlier_alpha", p.outlier_alpha, "must be finite and > 0");
  if (p.normal_k < 3 || p.normal_k > 200) fail("normal_k", p.normal_k, "must be 3..200");
  if (!(p.ground_distance_m > 0) || !std::isfinite(p.ground_distance_m)) fail("ground_distance_m", p.ground_distance_m, "must be finite and > 0");
  if (!(p.ground_probability > 0 && p.ground_probability < 1)) fail("ground_probability", p.ground_probability, "must be in (0, 1)");
  if (p.ground_max_iterations < 1) fail("ground_max_iterations", p.ground_max_iterations, "must be >= 1");
  if (!(p.ground_max_tilt_deg >= 0 && p.ground_max_tilt_deg <= 90)) fail("ground_max_tilt_deg", p.ground_max_tilt_deg, "must be in [0, 90]");
  if (!(p.ground_upright_prior_deg >= 0 && p.ground_upright_prior_deg <= 90)) {
    fail("ground_upright_prior_deg", p.ground_upright_prior_deg, "must be in [0, 90]");
  }
  if (!(p.ground_normal_tolerance_deg > 0 && p.ground_normal_tolerance_deg <= 180)) fail("ground_normal_tolerance_deg", p.ground_normal_tolerance_deg, "must be in (0, 180]");
  if (!(p.ground_reclaim_min_angle_deg >= 0 && p.ground_reclaim_min_angle_deg <= 90)) fail("ground_reclaim_min_angle_deg", p.ground_reclaim_min_angle_deg, "must be in [0, 90]");
  if (!(p.ground_reclaim_max_angle_deg >= p.ground_reclaim_min_angle_deg && p.ground_reclaim_max_angle_deg <= 90)) fail("ground_reclaim_max_angle_deg", p.ground_reclaim_max_angle_deg, "must be in [ground_reclaim_min_angle_deg, 90]");
  if (p.ground_min_points < 3) fail("ground_min_points", p.ground_min_points, "must be >= 3");
  if (!(p.colour_threshold > 0) || !std::isfinite(p.colour_threshold)) fail("colour_threshold", p.colour_threshold, "must be finite and > 0");
  if (!(p.neighbour_distance_m > 0) || !std::isfinite(p.neighbour_distance_m)) fail("neighbour_distance_m", p.neighbour_distance_m, "must be finite and > 0");
  if (p.min_segment_points < 3) fail("min_segment_points", p.min_segment_points, "must be >= 3");
  if (!(p.region_max_normal_deviation_deg > 0 && p.region_max_normal_deviation_deg <= 180)) fail("region_max_normal_deviation_deg", p.region_max_normal_deviation_deg, "must be in (0, 180]");
  if (!(p.adopt_max_angle_deg >= 0 && p.adopt_max_angle_deg <= 90)) fail("adopt_max_angle_deg", p.adopt_max_angle_deg, "must be in [0, 90]");
  if (!(p.adopt_max_distance_m > 0) || !std::isfinite(p.adopt_max_distance_m)) fail("adopt_max_distance_m", p.adopt_max_distance_m, "must be finite and > 0");
  if (p.rough_fragment_max_points < 0) fail("rough_fragment_max_points", p.rough_fragment_max_points, "must be >= 0");
  if (!(p.rough_fragment_max_width_m >= 0) || !std::isfinite(p.rough_fragment_max_width_m)) fail("rough_fragment_max_width_m", p.rough_fragment_max_width_m, "must be finite and >= 0");
  if (p.rough_min_fragments < 2) fail("rough_min_fragments", p.rough_min_fragments, "must be >= 2");
  if (p.rough_min_points < 3) fail("rough_min_points", p.rough_min_points, "must be >= 3");
  if (!(p.rough_min_width_m >= 0) || !std::isfinite(p.rough_min_width_m)) fail("rough_min_width_m", p.rough_min_width_m, "must be finite and >= 0");
  if (!(p.rough_min_normal_spread_deg >= 0 && p.rough_min_normal_spread_deg <= 90)) fail("rough_min_normal_spread_deg", p.rough_min_normal_spread_deg, "must be in [0, 90]");
  if (!(p.rough_max_slope_deg >= 0 && p.rough_max_slope_deg <= 90)) fail("rough_max_slope_deg", p.rough_max_slope_deg, "must be in [0, 90]");
  if (p.roughness_smoothing_passes < 1 || p.roughness_smoothing_passes > 10) fail("roughness_smoothing_passes", p.roughness_smoothing_passes, "must be 1..10");
  if (p.rough_smoothing_k < 3 || p.rough_smoothing_k > 200) fail("rough_smoothing_k", p.rough_smoothing_k, "must be 3..200");
  // A window is summed over cells a third of its width: 1 cm keeps every grid of a frame
  // within max_range_m's reach far inside the sizes the sums can index.
  if (!(p.foot_window_m == 0 || (p.foot_window_m >= 0.01 && p.foot_window_m <= 2.0))) {
    fail("foot_window_m", p.foot_window_m, "must be 0 (off) or in [0.01, 2]");
  }
  if (!(p.foot_support_m >= 0 && p.foot_support_m <= 2.0)) fail("foot_support_m", p.foot_support_m, "must be in [0, 2]");
  if (!(p.plane_ransac_distance_m > 0) || !std::isfinite(p.plane_ransac_distance_m)) fail("plane_ransac_distance_m", p.plane_ransac_distance_m, "must be finite and > 0");
  if (!(p.max_triangle_edge_m > 0) || !std::isfinite(p.max_triangle_edge_m)) fail("max_triangle_edge_m", p.max_triangle_edge_m, "must be finite and > 0");
}

PerceptionParams scaledToVoxel(const PerceptionParams& params, double voxel_m) {
  if (!(voxel_m >= 0.001 && voxel_m <= 1.0)) fail("voxel_size_m", voxel_m, "must be in [0.001, 1]");
  if (!(params.voxel_size_m > 0)) fail("voxel_size_m", params.voxel_size_m, "must be > 0");
  PerceptionParams p = params;
  const double f = voxel_m / params.voxel_size_m;
  const auto area = [f](int count, int at_least) {
    return std::max(at_least, static_cast<int>(std::lround(count / (f * f))));
  };
  p.voxel_size_m = voxel_m;
  p.min_segment_points = area(params.min_segment_points, 3);
  p.ground_min_points = area(params.ground_min_points, 3);
  // 0 switches rough joining off and must stay 0.
  p.rough_fragment_max_points = params.rough_fragment_max_points > 0 ? area(params.rough_fragment_max_points, 1) : 0;
  p.rough_min_points = area(params.rough_min_points, 3);
  // k neighbours and the point itself cover the same disc: (k + 1) / f^2 - 1. Finer
  // voxels may ask for more than normal_k, which is then what is used (at most 200).
  p.rough_smoothing_k = static_cast<int>(std::clamp(std::lround((params.rough_smoothing_k + 1) / (f * f) - 1), 3L, 200L));
  p.neighbour_distance_m = params.neighbour_distance_m * f;
  p.max_triangle_edge_m = params.max_triangle_edge_m * f;
  return p;
}

}  // namespace mobmap::perception
