#include "mobmap/builder/config.hpp"

#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/text.hpp"
#include "mobmap/util/field_error.hpp"

#include <yaml-cpp/yaml.h>

#include <functional>
#include <map>

namespace mobmap::builder {

using sources::IoError;
using sources::readTextFile;

namespace {

using Setter = std::function<void(const YAML::Node&)>;

template <typename T>
Setter bind(T& field) {
  return [&field](const YAML::Node& n) { field = n.as<T>(); };
}

void apply(const YAML::Node& section, const std::string& name, const std::map<std::string, Setter>& fields,
           const std::string& origin) {
  if (!section) return;
  if (!section.IsMap()) throw IoError(origin, name + ": expected a mapping of keys to values");
  for (const auto& kv : section) {
    if (!kv.first.IsScalar()) throw IoError(origin, name + ": keys must be plain names");
    const std::string key = kv.first.as<std::string>();
    const auto it = fields.find(key);
    if (it == fields.end()) throw IoError(origin, name + "." + key + ": unknown key");
    if (!kv.second.IsScalar()) throw IoError(origin, name + "." + key + ": expected a single value");
    try {
      it->second(kv.second);
    } catch (const YAML::Exception&) {
      throw IoError(origin, name + "." + key + ": '" + kv.second.as<std::string>() + "' has the wrong type");
    }
  }
}

}  // namespace

static Config parseConfigUnchecked(const std::string& text, const std::string& origin) {
  Config c;
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw IoError(origin, std::string("not valid YAML: ") + e.what());
  }
  if (root.IsNull()) return c;
  if (!root.IsMap()) throw IoError(origin, "expected sections perception:, mapping:, model:");
  for (const auto& kv : root) {
    if (!kv.first.IsScalar()) throw IoError(origin, "section names must be plain names");
    const std::string key = kv.first.as<std::string>();
    if (key != "perception" && key != "mapping" && key != "model") throw IoError(origin, key + ": unknown section");
  }
  auto& p = c.perception;
  Setter triangulator = [&](const YAML::Node& n) {
    const auto v = n.as<std::string>();
    if (v != "own" && v != "cgal") throw IoError(origin, "perception.triangulator: '" + v + "' must be own or cgal");
    p.triangulator = v == "own" ? perception::Triangulator::kOwn : perception::Triangulator::kCgal;
  };
  apply(root["perception"], "perception",
        {{"min_range_m", bind(p.min_range_m)}, {"max_range_m", bind(p.max_range_m)}, {"voxel_size_m", bind(p.voxel_size_m)},
         {"outlier_k", bind(p.outlier_k)}, {"outlier_alpha", bind(p.outlier_alpha)}, {"normal_k", bind(p.normal_k)},
         {"ground_distance_m", bind(p.ground_distance_m)}, {"ground_probability", bind(p.ground_probability)},
         {"ground_max_iterations", bind(p.ground_max_iterations)}, {"ground_max_tilt_deg", bind(p.ground_max_tilt_deg)},
         {"ground_upright_prior_deg", bind(p.ground_upright_prior_deg)},
         {"ground_normal_tolerance_deg", bind(p.ground_normal_tolerance_deg)}, {"ground_min_points", bind(p.ground_min_points)},
         {"ground_reclaim_min_angle_deg", bind(p.ground_reclaim_min_angle_deg)},
         {"ground_reclaim_max_angle_deg", bind(p.ground_reclaim_max_angle_deg)},
         {"colour_threshold", bind(p.colour_threshold)}, {"neighbour_distance_m", bind(p.neighbour_distance_m)},
         {"min_segment_points", bind(p.min_segment_points)}, {"region_max_normal_deviation_deg", bind(p.region_max_normal_deviation_deg)},
         {"adopt_max_angle_deg", bind(p.adopt_max_angle_deg)}, {"adopt_max_distance_m", bind(p.adopt_max_distance_m)},
         {"rough_fragment_max_points", bind(p.rough_fragment_max_points)}, {"rough_min_fragments", bind(p.rough_min_fragments)},
         {"rough_fragment_max_width_m", bind(p.rough_fragment_max_width_m)},
         {"rough_min_points", bind(p.rough_min_points)},
         {"rough_min_width_m", bind(p.rough_min_width_m)}, {"rough_max_slope_deg", bind(p.rough_max_slope_deg)},
         {"rough_min_normal_spread_deg", bind(p.rough_min_normal_spread_deg)}, {"plane_ransac_distance_m", bind(p.plane_ransac_distance_m)},
         {"max_triangle_edge_m", bind(p.max_triangle_edge_m)}, {"triangulator", triangulator},
         {"roughness_smoothing", bind(p.roughness_smoothing)}, {"roughness_smoothing_passes", bind(p.roughness_smoothing_passes)},
         {"rough_smoothing_k", bind(p.rough_smoothing_k)},
         {"foot_window_m", bind(p.foot_window_m)}, {"foot_support_m", bind(p.foot_support_m)},
         {"random_seed", bind(p.random_seed)}},
        origin);
  auto& m = c.mapping;
  Setter max_range = [&](const YAML::Node& n) {
    m.max_range_m = n.as<double>();
    c.mapping_max_range_set = true;
  };
  apply(root["mapping"], "mapping",
        {{"resolution_m", bind(m.resolution_m)}, {"max_range_m", max_range}, {"prob_hit", bind(m.prob_hit)},
         {"prob_miss", bind(m.prob_miss)}, {"clamp_min", bind(m.clamp_min)}, {"clamp_max", bind(m.clamp_max)},
         {"max_weight", bind(m.max_weight)}, {"range_variance_per_m2", bind(m.range_variance_per_m2)},
         {"free_space_margin_m", bind(m.free_space_margin_m)}, {"free_space_ray_stride_px", bind(m.free_space_ray_stride_px)},
         {"fine_surface", bind(m.fine_surface)}, {"fine_min_weight", bind(m.fine_min_weight)},
         {"fine_max_range_m", bind(m.fine_max_range_m)},
         {"fine_window_m", bind(m.fine_window_m)}, {"fine_support_m", bind(m.fine_support_m)},
         {"fine_support_length_m", bind(m.fine_support_length_m)}},
        origin);
  auto& g = c.model;
  Setter kind = [&](const YAML::Node& n) {
    const auto v = n.as<std::string>();
    if (v != "gp" && v != "rule") throw IoError(origin, "model.kind: '" + v + "' must be gp or rule");
    g.model = v == "gp" ? gp::ModelKind::kGaussianProcess : gp::ModelKind::kRuleTable;
  };
  apply(root["model"], "model",
        {{"kind", kind}, {"table", bind(c.table_path)}, {"signal_std", bind(g.signal_std)},
         {"length_scale", bind(g.length_scale)}, {"noise_std", bind(g.noise_std)},
         {"slope_scale_deg", bind(g.slope_scale_deg)}, {"roughness_scale", bind(g.roughness_scale)},
         {"open_slope_limit_deg", bind(g.open_slope_limit_deg)}, {"open_roughness_limit", bind(g.open_roughness_limit)},
         {"rule_variance", bind(g.rule_variance)}},
        origin);
  try {
    perception::validate(c.perception);
    mapping::validate(c.mapping);
    gp::validate(c.model);
  } catch (const std::invalid_argument& e) {
    // The fields are the file's keys, named as written there.
    throw IoError(origin, util::respellFields(e.what(), [](std::string_view key) { return std::string(key); }));
  }
  return c;
}

Config parseConfig(const std::string& text, const std::string& origin) {
  // yaml-cpp throws its own exceptions for shapes we did not anticipate (found by
  // fuzzing: a mapping used as a key); every one of them becomes an error naming the file.
  try {
    return parseConfigUnchecked(text, origin);
  } catch (const YAML::Exception& e) {
    throw IoError(origin, std::string("invalid configuration: ") + e.what());
  }
}

Config loadConfig(const std::string& path) { return parseConfig(readTextFile(path, 1 << 20), path); }

gp::RuleTable loadRuleTable(const std::string& path) {
  if (path.empty()) return gp::RuleTable::paper();
  const std::string text = readTextFile(path, 1 << 20);
  try {
    return gp::RuleTable::parseCsv(text);
  } catch (const std::invalid_argument& e) {
    throw IoError(path, e.what());
  }
}

gp::MobilityModel makeModel(const Config& c) { return gp::MobilityModel(loadRuleTable(c.table_path), c.model); }

}  // namespace mobmap::builder
