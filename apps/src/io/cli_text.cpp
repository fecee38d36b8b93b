#include "io/cli_text.hpp"

#include "mobmap/util/field_error.hpp"

#include <array>
#include <utility>

namespace mobmap::app {

std::optional<std::string> flagOf(std::string_view field) {
  // Library field -> the flag that sets it (every command spells a field the same way).
  static constexpr std::array<std::pair<std::string_view, std::string_view>, 48> kFlags{{
      // inputs (sources::SequenceOptions, RecordingChoice)
      {"intrinsics", "--intrinsics"},
      {"depth_format", "--depth-format"},
      {"poses", "--poses"},
      {"max_pose_gap_s", "--max-pose-gap"},
      {"depth_topic", "--depth-topic"},
      {"camera_info_topic", "--camera-info-topic"},
      {"world_frame", "--world-frame"},
      {"imu_topic", "--imu-topic"},
      {"uri", "--device"},
      {"extrinsics", "--extrinsics"},
      {"depth_scale", "--depth-scale"},
      {"frames", "--frames"},
      {"keyframes", "--keyframes"},
      {"origin", "--origin"},
      {"frame", "--frame"},
      {"device", "--device"},
      // a build's run and its map (builder::BuildOptions)
      {"out", "--out"},
      {"force", "--force"},
      {"extend", "--extend"},
      {"config", "--config"},
      {"checkpoint_frames", "--checkpoint"},
      {"free_space", "--no-free-space"},
      {"fine_surface_ply", "--surface-ply"},
      {"skip_bad_frames", "--skip-bad-frames"},
      {"refine_gravity", "--gravity-refine"},
      {"gravity_from_floor", "--gravity floor"},
      // a build's perception and fusion
      {"gravity", "--gravity"},
      {"voxel_size_m", "--voxel"},
      {"max_range_m", "--max-range"},
      {"resolution_m", "--resolution"},
      // the robot (mapping::RobotParams) and the search (PlanParams, ReachParams)
      {"sole_length_m", "--sole"},
      {"sole_width_m", "--sole"},
      {"max_step_m", "--max-step"},
      {"min_mobility", "--min-mobility"},
      {"max_poor_fraction", "--max-poor"},
      {"min_support_fraction", "--min-support"},
      {"max_tilt_deg", "--max-tilt"},
      {"max_unevenness_m", "--max-unevenness"},
      {"clearance_m", "--clearance"},
      {"max_stride_m", "--max-stride"},
      {"swing_clearance_m", "--swing-clearance"},
      {"max_gap_m", "--max-gap"},
      {"stance_width_m", "--stance-width"},
      {"lattice_m", "--lattice"},
      {"start_radius_m", "--start-radius"},
      {"goal_tolerance_m", "--goal-tolerance"},
      {"heuristic_weight", "--weight"},
      {"time_limit_s", "--time-limit"},
  }};
  for (const auto& [name, flag] : kFlags) {
    if (name == field) return std::string(flag);
  }
  return std::nullopt;
}

std::string cliText(std::string_view message) { return util::respellFields(message, flagOf); }

std::string cliText(const std::exception& e) {
  if (const auto* field = dynamic_cast<const util::FieldError*>(&e)) {
    return cliText(util::FieldError::named(field->field(), field->problem()));
  }
  return cliText(std::string_view(e.what()));
}

}  // namespace mobmap::app
