#pragma once
/// @file map_builder.hpp
/// A map built from any input as `mobmap build` builds it, for every front: the command
/// line, Python (`mobmap.build`), the server's live map and the ROS nodes call this.
///
///     mobmap::builder::BuildOptions options;
///     options.input = "../shared/data/7scenes-redkitchen";
///     options.out = "/tmp/rk.ot";
///     options.frames = "0:99";
///     const mobmap::builder::BuildReport report = mobmap::builder::buildMap(options);
///
/// The run goes through its steps in order, each taking what the one before gave:
/// the options checked and the map's files claimed (one writer per map); the input
/// opened, with depth scale, depth format and extrinsics applied, and its frames selected
/// and checked; gravity settled (given, checked against and refined to the floor, from an
/// IMU, or found from the floor); the map placed (its origin); every frame read,
/// perceived on the machine's cores and fused in order (mapping::LiveMapper), with
/// checkpoints; the result refused when it would hide a mistake (no frame posed, every
/// point outside the map, depth in another unit), else written (all four files or none).
///
/// The library never prints: what a user should read arrives through BuildHooks::message,
/// its fields named in backquotes (util/field_error.hpp), and the numbers of the run in
/// the BuildReport.

#include "mobmap/mapping/live_mapper.hpp"
#include "mobmap/mapping/map_metadata.hpp"
#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/sources/sequence.hpp"

#include <Eigen/Core>

#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace mobmap::builder {

/// What to build and how; each field is named as errors and messages name it.
struct BuildOptions {
  /// A 7-Scenes / 3DMatch folder, a TUM RGB-D folder, .pcd frames with `poses`, one .pcd
  /// or 16-bit depth .png, an OpenNI2 .oni file, a ROS 2 bag (folder, .db3, .mcap) or a
  /// ROS 1 .bag. Empty when `device` is set.
  std::string input;
  /// A live OpenNI2 sensor instead of `input`: its URI, "" for the first attached.
  std::optional<std::string> device;
  /// The map to write, ending in .ot; its .bt, .octovis.ot and .json go beside it.
  std::string out;
  /// "FIRST:LAST:STEP" of the frame numbers to use; empty: all.
  std::string frames;
  /// Points farther from the camera are left out (metres); unset: 3, or the configuration's.
  std::optional<double> max_range_m;
  /// The map's voxel size (metres); unset: 0.02, or the configuration's.
  std::optional<double> resolution_m;
  /// The perception voxel size (metres): the configuration's point counts and spacings
  /// are rescaled to keep their physical sizes (perception::scaledToVoxel).
  std::optional<double> voxel_size_m;
  /// Depth values per metre of the input; unset: its own.
  std::optional<double> depth_scale;
  /// How 16-bit depth values are encoded beyond their unit (sources::depthFormats()).
  std::string depth_format;
  /// "Down" in the input's world frame; unset: the input's own, else found.
  std::optional<Eigen::Vector3d> gravity;
  /// Gravity from the floor's normal even when the input states one.
  bool gravity_from_floor = false;
  /// A gravity given (here or by the input) is refined to the floor when the two differ
  /// by more than a degree (within 10).
  bool refine_gravity = true;
  /// The map's origin in the world frame; unset: the first camera position rounded to
  /// 100 m (the camera for a lone frame).
  std::optional<Eigen::Vector3d> origin;
  /// Replace an existing map at `out`.
  bool force = false;
  /// Add the frames to the map at `out`, which keeps its frame and resolution.
  bool extend = false;
  /// Also save the map every this many fused frames (0: only at the end).
  int checkpoint_frames = 0;
  /// Keyframes only: (metres, degrees) a camera must move or turn since the last one.
  std::optional<std::pair<double, double>> keyframes;
  /// Clear what frames see through and cast free-space rays.
  bool free_space = true;
  /// Frames that cannot be read are left out (and listed) instead of ending the run.
  bool skip_bad_frames = false;
  /// A YAML file of the library's parameters (builder/config.hpp); empty: the defaults.
  std::string config;
  /// The camera: "fx,fy,cx,cy", "fov:DEGREES" or a camera file; empty: the input's.
  std::string intrinsics;
  /// A frame stamped between two poses further apart in time has none (seconds).
  double max_pose_gap_s = 0.05;
  /// A TUM trajectory: the poses of .pcd frames, an OpenNI2 stream or a bag's images.
  std::string poses;
  /// A bag's topics and world frame.
  sources::RecordingChoice recording;
  /// The camera's pose on the body whose poses are given: x,y,z,qx,qy,qz,qw or a YAML file.
  std::string extrinsics;
  /// Frames perceived at once.
  int perception_threads = 2;
  /// Also write the fused fine surface here as PLY (MobilityMap::saveFineSurfacePly);
  /// turns the configuration's `mapping.fine_surface` on. Empty: none.
  std::string fine_surface_ply;
};

/// What the run has to say, as it happens.
enum class Message {
  kDetail,   ///< how the input is read, the gravity agreed: for a user who asked for detail
  kNote,     ///< something the user should know ("note: ...")
  kWarning,  ///< something that may be wrong ("warning: ...")
};

/// What a caller adds to the run. Every callback is optional and must not throw.
struct BuildHooks {
  /// A line for the user, starting "note: " or "warning: " for those kinds; fields in
  /// backquotes. The reading or the fusion thread, one at a time.
  std::function<void(Message kind, const std::string& line)> message;
  /// Frames done (fused, unposed, unreadable or outside the map) of `total`, the map's
  /// nodes, and when the run started. One at a time.
  std::function<void(int done, int total, std::size_t nodes, std::chrono::steady_clock::time_point run_start)> progress;
  /// Asked before each frame, after each is fused and while a live sensor is awaited:
  /// true ends the run as it stands, with the frames fused so far saved.
  std::function<bool()> stop;
  /// The mapper exists (LiveMapper::Config::serve_snapshots is set when `fused` is), before
  /// the first frame is read; `frames_in_map` counts those of a map being extended.
  std::function<void(const mapping::LiveMapper& mapper, int frames_in_map)> started;
  /// After each frame fused: the map with it, the frames in it and the camera's position
  /// (map frame). The fusion thread.
  std::function<void(std::shared_ptr<const mapping::MobilityMap> map, int frames_in_map, const Eigen::Vector3d& camera_map)>
      fused;
  /// After each frame is fused and any checkpoint written, with the frames fused in this
  /// run. The fusion thread.
  std::function<void(int frames_fused)> frame_done;
  /// Before each frame is read. The reading thread.
  std::function<void()> before_frame;
  /// Every frame fused; the map is written next.
  std::function<void()> frames_done;
  /// The map as saved and what its MAP.json says, once its files are written.
  std::function<void(std::shared_ptr<const mapping::MobilityMap> map, const mapping::MapMetadata& meta)> saved;
};

/// What the run did, for its summary.
struct BuildReport {
  bool written = false;      ///< the map's files were written (false: stopped before any frame was fused)
  bool interrupted = false;  ///< stopped by BuildHooks::stop
  int frames_fused = 0;
  int frames_selected = 0;  ///< the frames the run tried (after keyframes)
  int keyframes_considered = 0;  ///< frames selected before keyframes (0: none chosen)
  int frames_without_ground = 0;
  int frames_without_pose = 0;
  int frames_outside_map = 0;        ///< frames with no point inside the map's extent
  std::size_t points_outside_map = 0;
  std::string map_extent;            ///< "+-N m around its origin (...)"
  std::size_t points = 0;
  std::size_t map_nodes = 0, map_leaves = 0;
  double seconds = 0, frames_per_second = 0;
  int frames_in_map = 0;      ///< all runs' frames (an extended map)
  std::size_t runs_in_map = 1;
  bool extended = false;
  std::vector<std::string> depth_check_summary;  ///< lines "warning: ..." or "note: ..."
  std::optional<Eigen::Vector3d> gravity_given;  ///< the gravity given, when the floor checked it
  Eigen::Vector3d gravity_used = Eigen::Vector3d(0, 0, -1);
  std::string gravity_source;
  std::string live_skipped;                 ///< a live sensor's dropped frames, when any
  std::vector<std::string> unreadable;      ///< "FILE: problem", frames left out
  double read_ms = 0, fusion_ms = 0;        ///< per frame
  std::vector<std::pair<std::string, double>> stage_ms;  ///< per frame, pipeline order
  std::string out, stem;                    ///< the map and its files' stem
  std::size_t rough_voxels = 0;             ///< voxels the fine surface scored as rough ground (MapParams::fine_surface)
};

/// Builds (or extends) the map `options` describe; see the file's comment. IoError naming
/// the file for bad input, util::ValueError (a FieldError naming the field) for options
/// it cannot take, mapping::MapLockError when another writer holds the map.
BuildReport buildMap(const BuildOptions& options, const BuildHooks& hooks = {});

/// "camera moved >= 0.05 m or turned >= 5 degrees": the keyframe rule `keyframes` sets,
/// as the run's note and `mobmap info` word it.
std::string describeKeyframeRule(double min_translation_m, double min_rotation_deg);

/// The frames FIRST:LAST:STEP selects (`frames`); util::FieldError unless well formed.
struct FrameRange {
  int first = 0, last = -1, step = 1;
};
FrameRange parseFrameRange(const std::string& spec);

}  // namespace mobmap::builder
