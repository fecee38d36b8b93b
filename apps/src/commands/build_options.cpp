#include "commands/build_command.hpp"

#include "commands/commands.hpp"

#include <CLI/CLI.hpp>

namespace mobmap::app::build {

std::shared_ptr<BuildOptions> addBuildOptions(CLI::App& app) {
  auto* cmd = app.add_subcommand("build", "Build a mobility map from a sequence of posed depth frames");
  auto o = std::make_shared<BuildOptions>();
  cmd->add_option("INPUT", o->input, kBuildInputHelp);
  addBuildRunOptions(*cmd, *o);
  o->given.out->required();
  return o;
}

void addBuildRunOptions(CLI::App& cmd_ref, BuildOptions& o_ref) {
  CLI::App* cmd = &cmd_ref;
  BuildOptions* o = &o_ref;
  o->given.device = cmd->add_option("--device", o->device,
                                 "Read a live OpenNI2 depth sensor instead of INPUT: the first attached one, or the "
                                 "given device URI. Stops after --frames LAST (default 300 frames) or Ctrl-C")
                     ->expected(0, 1);
  auto* intrinsics = cmd->add_option("--intrinsics", o->intrinsics, kIntrinsicsHelp);
  o->given.fov = cmd->add_option("--fov", o->fov, kFovHelp)->excludes(intrinsics);
  cmd->add_option("--poses", o->poses,
                  "Trajectory, TUM format 't tx ty tz qx qy qz qw' (camera to world). For .pcd frames: one line per "
                  "frame in file-name order, or timestamped and matched to time stamps in the file names. For .oni "
                  "and --device: matched to the frames' time stamps (seconds of the device clock); without it the "
                  "camera is taken as static");
  cmd->add_option("--max-pose-gap", o->max_pose_gap, "TUM / timestamped --poses: skip frames whose neighbouring poses are farther apart in time (s)")
      ->check(finiteNonNegative())
      ->capture_default_str();
  addRecordingOptions(*cmd, o->recording);
  cmd->add_option("--extrinsics", o->extrinsics, kExtrinsicsHelp);
  o->given.out = cmd->add_option("--out", o->out, "Map file to write (MAP.ot; MAP.bt, MAP.octovis.ot and MAP.json go beside it)");
  cmd->add_option("--frames", o->frames, "FIRST:LAST:STEP of the frame numbers to use (default: all; a live sensor: 0:299; OpenNI2 frames are numbered as they arrive)");
  o->given.max_range = cmd->add_option("--max-range", o->max_range, "Maximum range of points, metres")->capture_default_str();
  o->given.resolution = cmd->add_option("--resolution", o->resolution, "Voxel size of the map, metres")->capture_default_str();
  cmd->add_option("--config", o->config, "YAML file with any of the parameters of `mobmap config --print-default`");
  o->given.voxel = cmd->add_option("--voxel", o->voxel, kVoxelHelp);
  o->given.depth_scale = cmd->add_option("--depth-scale", o->depth_scale, kDepthScaleHelp)->check(CLI::PositiveNumber);
  cmd->add_option("--depth-format", o->depth_format, kDepthFormatHelp);
  cmd->add_option("--gravity", o->gravity, "Gravity (down) in the data's world frame X,Y,Z, or 'floor' for the floor's normal "
                  "(default: gravity-direction.txt, else the floor's normal in up to 8 frames spread over the run, else "
                  "the cameras' mean +y axis; a single .pcd or .png frame: its ground plane's normal; OpenNI2: the "
                  "camera's +y without --poses, -z with them)");
  cmd->add_option("--gravity-refine", o->gravity_refine,
                  "on: a gravity taken from gravity-direction.txt or --gravity X,Y,Z is refined to the floor found within "
                  "10 degrees of it in up to 8 sampled frames, when the two differ by more than 1 degree; off: trusted as "
                  "given (the angle to the floor is still reported). Not for --extend (the map keeps its frame) or "
                  "OpenNI2 input")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  auto* origin = o->given.origin = cmd->add_option("--origin", o->origin,
                                 "X Y Z: the map frame's origin in the data's world frame (metres; default: the first "
                                 "camera position rounded to 100 m, so coordinates stay small when the world frame's "
                                 "are large, e.g. UTM; the map reaches 32768 voxels from it each way: 655 m at 2 cm)")
                     ->expected(3);
  auto* force = cmd->add_flag("--force", o->force, "Overwrite an existing map");
  cmd->add_flag("--extend", o->extend,
                "Add the frames to the existing map at --out instead of starting a new one: its resolution and map "
                "frame are kept, INPUT's poses must be in the same world frame, MAP.json records each run")
      ->excludes(force)
      ->excludes(origin);
  cmd->add_option("--checkpoint", o->checkpoint,
                  "Also save the map every N fused frames while the run goes on (MAP.json says \"checkpoint\"); after a "
                  "crash, --extend with the remaining --frames finishes it")
      ->check(CLI::Range(1, 1000000));
  o->given.keyframes = cmd->add_option("--keyframes", o->keyframes,
                                    "METRES,DEGREES: fuse only frames whose camera has moved at least METRES or turned "
                                    "at least DEGREES since the last frame fused (0 turns a test off), e.g. 0.05,5; the "
                                    "first selected frame is always fused. For sequences with their poses in files "
                                    "(7-Scenes, TUM, .pcd frames with --poses)")
                        ->delimiter(',')
                        ->expected(2);
  cmd->add_option("--surface-ply", o->surface_ply,
                  "Also write the fused fine surface as a PLY (points with normals, weight, views, roughness and "
                  "mobility; map frame); turns the configuration's mapping.fine_surface on, which scores rough ground "
                  "on it (docs/ALGORITHM.md); an existing FILE is replaced only with --force");
  cmd->add_flag("--no-free-space", o->no_free_space, "Skip free-space updates: neither clear voxels a frame sees through nor cast free-space rays (faster; obstacles that moved stay in the map)");
  cmd->add_flag("--skip-bad-frames", o->skip_bad_frames,
                "Leave out, with a warning naming the file, a frame that cannot be read (a depth image that is "
                "corrupt or cut short, a pose file that is missing or not a rigid transform, an unreadable .pcd) "
                "instead of stopping the run; the summary and MAP.json count them. For sequences of files");
  cmd->add_flag("--quiet,-q", o->quiet, "No progress output");
}

}  // namespace mobmap::app::build
