#pragma once
// MAP.json: what `mobmap build` (or any program using LiveMapper) records beside MAP.ot
// about how the map was made: the map's frame, the camera path, and one record per run.
// The one place that reads and writes it; the keys are listed in docs/MAPPING.md.

#include <Eigen/Core>

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace mobmap::mapping {

/// The rule `build --keyframes` chose frames by ("keyframes").
struct KeyframeRecord {
  double min_translation_m = 0;  ///< 0: not a test in use
  double min_rotation_deg = 0;   ///< 0: not a test in use
  long long frames_considered = 0;
};

/// The depth camera a run read its frames with ("depth_intrinsics"), so they can be
/// read again the same way (`overlay`).
struct DepthCameraRecord {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  int width = 0, height = 0;
};

/// The perception settings a run used ("perception"); only the values a run recorded.
struct PerceptionRecord {
  std::optional<double> max_range_m, voxel_size_m;
  std::optional<int> normal_k, outlier_k;
  std::optional<double> colour_threshold;
  std::optional<int> min_segment_points, ground_min_points;
  std::optional<double> neighbour_distance_m, max_triangle_edge_m;
  std::optional<int> rough_fragment_max_points, rough_min_points, rough_smoothing_k;
};

/// The fusion settings a run used ("mapping").
struct MappingRecord {
  std::optional<double> resolution_m, max_range_m;
  std::optional<int> free_space_ray_stride_px;
  std::optional<double> max_weight;
  std::optional<bool> clear_seen_through;
};

/// The mobility model a run scored with ("model").
struct ModelRecord {
  std::optional<std::string> kind;   ///< "gp" or "rule"
  std::optional<std::string> table;  ///< "paper" or the table file
  std::optional<double> signal_std, length_scale, noise_std;
};

/// One run that fused frames into the map. Every entry is optional in the file (maps
/// written by older versions lack some); what a run did not record stays unset.
struct MapRun {
  std::optional<std::string> format;     ///< "mobmap-map-metadata"
  std::optional<std::string> tool;       ///< "mobmap 0.9.0"
  std::optional<std::string> tree_type;  ///< MobilityOcTree::kTreeType
  std::optional<std::string> input;      ///< absolute path, or "OpenNI2 device ..."
  std::optional<int> frames_in_run;      ///< frames this run fused
  std::optional<long long> frames_selected;
  std::optional<KeyframeRecord> keyframes;
  std::optional<std::string> skipped;    ///< what reading the input skipped, in words
  /// How a recording left by a crashed recorder was read (no metadata.yaml, a
  /// write-ahead log merged, a ROS 1 bag without its index), in words.
  std::optional<std::string> recovered;
  std::optional<DepthCameraRecord> depth_intrinsics;
  std::optional<std::string> poses;      ///< the trajectory file, absolute
  std::optional<double> max_pose_gap_s;
  /// A recording's choices: the depth and camera_info topics read, the TF frame the
  /// poses are in.
  std::optional<std::string> depth_topic, camera_info_topic, world_frame;
  /// `--extrinsics`: the camera's pose in the posed frame, "x,y,z,qx,qy,qz,qw".
  std::optional<std::string> extrinsics;
  std::optional<long long> frames_without_pose;
  std::vector<std::string> unreadable;   ///< frames left out as unreadable ("frames_unreadable" counts them)
  std::optional<std::array<long long, 2>> frame_numbers;  ///< first and last frame fused
  bool interrupted = false;              ///< stopped by Ctrl-C: the map holds the frames fused until then
  std::optional<bool> checkpoint;        ///< true: written in the middle of a run that did not finish
  std::optional<double> resolution_m;
  std::optional<Eigen::Vector3d> gravity_down_world;  ///< down in the input's world frame
  std::optional<std::string> gravity_source;
  /// The gravity the input or --gravity gave, when the one used was checked against the
  /// floor (and by default refined to it), and the angle between the given and the floor.
  std::optional<Eigen::Vector3d> gravity_given_world;
  std::optional<double> gravity_floor_angle_deg;
  std::optional<Eigen::Matrix3d> R_map_world;  ///< world to map (z up); a rotation
  std::optional<Eigen::Vector3d> origin_world;  ///< the map origin in the world frame
  std::optional<std::string> origin_source;
  std::optional<long long> points_outside_map, frames_outside_map;
  std::optional<double> depth_units_per_m;  ///< the input's depth values per metre as read (`--depth-scale`)
  std::optional<std::string> depth_format;  ///< `--depth-format`: how its 16-bit depth values were decoded
  /// Valid points in the frames fused, and those of them beyond the perception's max range.
  std::optional<long long> points_in_view, points_beyond_range;
  std::optional<double> seconds, frames_per_second;
  std::optional<PerceptionRecord> perception;
  std::optional<MappingRecord> mapping;
  std::optional<ModelRecord> model;
  std::optional<std::string> config;     ///< the configuration file, absolute
  /// Entries this version does not know (a newer version's, or added by hand), as a JSON
  /// object's text: kept as they are when the file is written again.
  std::string other_entries;
};

/// MAP.json as a whole. The file is the latest run's record with the map-wide entries
/// beside it: "frames" (all runs'), "trajectory_map" (all runs' camera positions) and
/// "earlier_runs" (the runs before the latest, oldest first, without camera paths).
struct MapMetadata {
  bool found = false;  ///< false: there is no MAP.json (the rest are the defaults)
  std::string path;    ///< MAP.json's path
  int frames = 0;      ///< frames fused into the map by all its runs
  std::vector<Eigen::Vector3d> trajectory_map;  ///< camera positions, map frame, every run's
  MapRun latest;                    ///< the run that wrote the file
  std::vector<MapRun> earlier_runs;  ///< `build --extend`: the runs before, oldest first

  /// The map's frame as recorded: R_map_world was recorded.
  [[nodiscard]] bool hasFrame() const { return latest.R_map_world.has_value(); }
  /// World to map rotation; identity if not recorded.
  [[nodiscard]] Eigen::Matrix3d R_map_world() const;
  /// The map origin in the world frame; zero if not recorded.
  [[nodiscard]] Eigen::Vector3d originWorld() const;
  /// Gravity (down) in the world frame, if recorded.
  [[nodiscard]] std::optional<Eigen::Vector3d> gravityDownWorld() const { return latest.gravity_down_world; }

  /// Every run, oldest first (the earlier runs, then the latest).
  [[nodiscard]] std::vector<const MapRun*> runs() const;
  /// Where each run's camera positions begin in trajectory_map (0 first), for runs that
  /// recorded frames_in_run.
  [[nodiscard]] std::vector<std::size_t> runStarts() const;

  /// Records `run`, which fused `run_trajectory` (map frame), as the latest run: the
  /// current latest run moves to earlier_runs (with frames_in_run = frames if it did not
  /// record it), frames and the camera path grow by the new run's. For `build --extend`.
  void addRun(MapRun run, const std::vector<Eigen::Vector3d>& run_trajectory);
};

/// "MAP" for "MAP.ot", else the path itself: MAP.json is mapFileStem(ot) + ".json".
std::string mapFileStem(const std::string& ot_path);

/// Reads MAP.json beside `ot_path` (nothing found is not an error: found = false) and
/// checks every entry this version knows: MapIoError "MAP.json: <problem>" naming the
/// entry if the file is not a JSON object, or an entry has the wrong type, R_map_world is
/// not a rotation, a count is negative, a vector is not finite, gravity is zero, or a
/// camera position is beyond 1e6 m. A file over 256 MB is refused unread.
MapMetadata readMapMetadata(const std::string& ot_path);

/// The same from text already read; `path` names it in errors.
MapMetadata parseMapMetadata(const std::string& text, const std::string& path);

/// MAP.json's text: JSON indented by one space with keys in alphabetical order, except
/// that each camera position takes one line ("[x,y,z]"). Numbers are written to round
/// trip: parseMapMetadata(formatMapMetadata(m)) gives m back.
std::string formatMapMetadata(const MapMetadata& metadata);

/// Writes formatMapMetadata(metadata) to `json_path` atomically (a temporary file renamed
/// into place). MapIoError naming the path on failure.
void saveMapMetadata(const MapMetadata& metadata, const std::string& json_path);

}  // namespace mobmap::mapping
