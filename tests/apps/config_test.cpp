// The YAML configuration: the shipped default equals the structs' defaults; bad files
// are rejected with the file and key named.
#include "io/config.hpp"
#include "io/io_error.hpp"

#include <gtest/gtest.h>

namespace mobmap::app {
namespace {

std::string errorOf(const std::string& yaml) {
  try {
    (void)parseConfig(yaml, "test.yaml");
  } catch (const IoError& e) {
    return e.what();
  }
  return "no error";
}

TEST(Config, ShippedDefaultYamlEqualsTheStructDefaults) {
  const Config c = parseConfig(defaultConfigYaml(), "default.yaml");
  const perception::PerceptionParams p;
  EXPECT_EQ(c.perception.min_range_m, p.min_range_m);
  EXPECT_EQ(c.perception.max_range_m, p.max_range_m);
  EXPECT_EQ(c.perception.voxel_size_m, p.voxel_size_m);
  EXPECT_EQ(c.perception.outlier_k, p.outlier_k);
  EXPECT_EQ(c.perception.outlier_alpha, p.outlier_alpha);
  EXPECT_EQ(c.perception.normal_k, p.normal_k);
  EXPECT_EQ(c.perception.ground_distance_m, p.ground_distance_m);
  EXPECT_EQ(c.perception.ground_probability, p.ground_probability);
  EXPECT_EQ(c.perception.ground_max_iterations, p.ground_max_iterations);
  EXPECT_EQ(c.perception.ground_max_tilt_deg, p.ground_max_tilt_deg);
  EXPECT_EQ(c.perception.ground_upright_prior_deg, p.ground_upright_prior_deg);
  EXPECT_EQ(c.perception.ground_normal_tolerance_deg, p.ground_normal_tolerance_deg);
  EXPECT_EQ(c.perception.ground_min_points, p.ground_min_points);
  EXPECT_EQ(c.perception.ground_reclaim_min_angle_deg, p.ground_reclaim_min_angle_deg);
  EXPECT_EQ(c.perception.ground_reclaim_max_angle_deg, p.ground_reclaim_max_angle_deg);
  EXPECT_EQ(c.perception.colour_threshold, p.colour_threshold);
  EXPECT_EQ(c.perception.neighbour_distance_m, p.neighbour_distance_m);
  EXPECT_EQ(c.perception.min_segment_points, p.min_segment_points);
  EXPECT_EQ(c.perception.region_max_normal_deviation_deg, p.region_max_normal_deviation_deg);
  EXPECT_EQ(c.perception.adopt_max_angle_deg, p.adopt_max_angle_deg);
  EXPECT_EQ(c.perception.adopt_max_distance_m, p.adopt_max_distance_m);
  EXPECT_EQ(c.perception.rough_fragment_max_points, p.rough_fragment_max_points);
  EXPECT_EQ(c.perception.rough_min_fragments, p.rough_min_fragments);
  EXPECT_EQ(c.perception.rough_fragment_max_width_m, p.rough_fragment_max_width_m);
  EXPECT_EQ(c.perception.rough_min_points, p.rough_min_points);
  EXPECT_EQ(c.perception.rough_min_width_m, p.rough_min_width_m);
  EXPECT_EQ(c.perception.rough_max_slope_deg, p.rough_max_slope_deg);
  EXPECT_EQ(c.perception.rough_min_normal_spread_deg, p.rough_min_normal_spread_deg);
  EXPECT_EQ(c.perception.plane_ransac_distance_m, p.plane_ransac_distance_m);
  EXPECT_EQ(c.perception.max_triangle_edge_m, p.max_triangle_edge_m);
  EXPECT_EQ(c.perception.triangulator, p.triangulator);
  EXPECT_EQ(c.perception.roughness_smoothing, p.roughness_smoothing);
  EXPECT_EQ(c.perception.roughness_smoothing_passes, p.roughness_smoothing_passes);
  EXPECT_EQ(c.perception.rough_smoothing_k, p.rough_smoothing_k);
  EXPECT_EQ(c.perception.random_seed, p.random_seed);
  const mapping::MapParams m;
  EXPECT_EQ(c.mapping.resolution_m, m.resolution_m);
  EXPECT_EQ(c.mapping.max_range_m, m.max_range_m);
  EXPECT_EQ(c.mapping.prob_hit, m.prob_hit);
  EXPECT_EQ(c.mapping.prob_miss, m.prob_miss);
  EXPECT_EQ(c.mapping.clamp_min, m.clamp_min);
  EXPECT_EQ(c.mapping.clamp_max, m.clamp_max);
  EXPECT_EQ(c.mapping.max_weight, m.max_weight);
  EXPECT_EQ(c.mapping.range_variance_per_m2, m.range_variance_per_m2);
  EXPECT_EQ(c.mapping.free_space_margin_m, m.free_space_margin_m);
  EXPECT_EQ(c.mapping.free_space_ray_stride_px, m.free_space_ray_stride_px);
  const gp::MobilityModelParams g;
  EXPECT_EQ(c.model.model, g.model);
  EXPECT_EQ(c.model.signal_std, g.signal_std);
  EXPECT_EQ(c.model.length_scale, g.length_scale);
  EXPECT_EQ(c.model.noise_std, g.noise_std);
  EXPECT_EQ(c.model.slope_scale_deg, g.slope_scale_deg);
  EXPECT_EQ(c.model.roughness_scale, g.roughness_scale);
  EXPECT_EQ(c.model.open_slope_limit_deg, g.open_slope_limit_deg);
  EXPECT_EQ(c.model.open_roughness_limit, g.open_roughness_limit);
  EXPECT_DOUBLE_EQ(c.model.rule_variance, g.rule_variance);
  EXPECT_TRUE(c.table_path.empty());
}

TEST(Config, PartialFilesOverrideOnlyWhatTheySay) {
  const Config c = parseConfig("perception:\n  max_range_m: 2.0\n  triangulator: cgal\nmodel:\n  kind: rule\n", "x.yaml");
  EXPECT_EQ(c.perception.max_range_m, 2.0);
  EXPECT_EQ(c.perception.triangulator, perception::Triangulator::kCgal);
  EXPECT_EQ(c.perception.voxel_size_m, 0.01);
  EXPECT_EQ(c.model.model, gp::ModelKind::kRuleTable);
  EXPECT_TRUE(parseConfig("", "empty.yaml").table_path.empty());
}

TEST(Config, BadFilesNameTheFileAndTheKey) {
  EXPECT_NE(errorOf("perception:\n  voxel_size: 0.01\n").find("test.yaml: perception.voxel_size: unknown key"), std::string::npos);
  EXPECT_NE(errorOf("percepton:\n  voxel_size_m: 0.01\n").find("percepton: unknown section"), std::string::npos);
  EXPECT_NE(errorOf("mapping:\n  resolution_m: two\n").find("mapping.resolution_m: 'two' has the wrong type"), std::string::npos);
  EXPECT_NE(errorOf("mapping:\n  resolution_m: -0.02\n").find("resolution_m is -0.02"), std::string::npos);
  EXPECT_NE(errorOf("perception:\n  voxel_size_m: 0\n").find("voxel_size_m is 0"), std::string::npos);
  EXPECT_NE(errorOf("perception:\n  min_range_m: 2\n  max_range_m: 1\n").find("max_range_m"), std::string::npos);
  EXPECT_NE(errorOf("model:\n  kind: magic\n").find("model.kind: 'magic' must be gp or rule"), std::string::npos);
  EXPECT_NE(errorOf("perception:\n  triangulator: qhull\n").find("perception.triangulator: 'qhull' must be own or cgal"),
            std::string::npos);
  EXPECT_NE(errorOf("perception: [1, 2\n").find("not valid YAML"), std::string::npos);
  EXPECT_NE(errorOf("perception:\n  normal_k: [1, 2]\n").find("expected a single value"), std::string::npos);
  // Found by fuzzing (tests/fuzz): mappings used as keys threw yaml-cpp's own exception.
  EXPECT_NE(errorOf("{{}}").find("test.yaml: section names must be plain names"), std::string::npos) << errorOf("{{}}");
  EXPECT_NE(errorOf("perception:\n  {a: 1}: 2\n").find("test.yaml: perception: keys must be plain names"), std::string::npos);
}

}  // namespace
}  // namespace mobmap::app
