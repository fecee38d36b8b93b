#include "commands/commands.hpp"
#include "commands/build_steps.hpp"
#include "io/config.hpp"
#include "io/dataset.hpp"
#include "io/extrinsics.hpp"
#include "io/files.hpp"
#include "io/frame_source.hpp"
#include "io/io_error.hpp"
#include "io/map_files.hpp"
#include "mobmap/sources/openni.hpp"
#include "commands/progress.hpp"
#include "io/sequence.hpp"

#include "mobmap/mapping/gravity.hpp"
#include "mobmap/mapping/live_mapper.hpp"
#include "mobmap/mapping/map_lock.hpp"
#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/mapping/trajectory.hpp"
#include "mobmap/perception/pipeline.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <functional>
#include <future>
#include <iostream>
#include <sstream>
#include <map>
#include <memory>
#include <mutex>
#include <limits>
#include <optional>
#include <thread>

namespace mobmap::app {
using namespace build;  // the steps of this command (build_steps.hpp)
namespace {

// Ctrl-C, SIGTERM (a service manager, `kill`) and SIGHUP (a closed terminal or SSH
// session) all end the run the same way: the frames fused so far are saved, and the exit
// code is 128 + the signal's number (130, 143, 129).
std::atomic<bool> g_interrupted{false};
std::atomic<int> g_signal{0};
extern "C" void onBuildStopSignal(int sig) {
  int none = 0;
  g_signal.compare_exchange_strong(none, sig);  // the first signal names the exit code
  g_interrupted.store(true);
}
constexpr int kStopSignals[] = {SIGINT, SIGTERM, SIGHUP};
int interruptedCode() { return 128 + (g_signal.load() ? g_signal.load() : SIGINT); }

}  // namespace

Command addBuildCommand(CLI::App& app) {
  const std::shared_ptr<BuildOptions> o = addBuildOptions(app);
  return [o]() { return runBuild(*o, nullptr); };
}

int build::runBuild(BuildOptions& options, const LiveHooks* hooks) {
  BuildOptions* const o = &options;
  const BuildOptions::Given& given = o->given;  // which options were given
  if (given.fov->count() > 0) o->intrinsics = fovSpec(o->fov);
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::path(o->out).extension() != ".ot") throw UsageError("--out must end in .ot, got '" + o->out + "'");
  // From here a stop signal ends the run as it stands (with what was fused saved), never
  // the process in the middle of it: the frames read before the first is fused are the
  // only ones it can cost.
  for (const int sig : kStopSignals) std::signal(sig, onBuildStopSignal);
  // One writer per map for the whole run: a second build to the same --out (fresh or
  // --extend) fails here at once instead of replacing the first one's frames.
  const mapping::MapLock map_lock(o->out);
  if (given.origin->count() > 0 && !Eigen::Vector3d(o->origin[0], o->origin[1], o->origin[2]).allFinite()) {
    throw UsageError("--origin: values must be finite");
  }
  if (o->extend && !fs::exists(o->out, ec)) throw UsageError("--extend: " + o->out + " does not exist (build it without --extend first)");
  if (!o->force && !o->extend && fs::exists(o->out, ec)) {
    throw UsageError(o->out + " exists; pass --force to overwrite it or --extend to add frames to it");
  }
  // Now, not after the whole run; all four files, so that none of them is in the way
  // (a directory of that name) when they are renamed into place.
  const std::string stem = mapping::mapFileStem(o->out);
  const std::array<std::string, 4> map_paths{o->out, stem + ".bt", stem + ".octovis.ot", stem + ".json"};
  for (const std::string& path : map_paths) checkWritable(path);  // creates the map's folder
  {
    std::vector<NamedPath> inputs{{"the input", o->input}, {"--poses", o->poses}, {"--config", o->config}};
    if (fs::is_regular_file(o->intrinsics, ec)) inputs.push_back({"--intrinsics", o->intrinsics});
    refuseToOverwriteInputs({{"--out", map_paths[0]}, {"--out's occupancy export", map_paths[1]},
                             {"--out's octovis export", map_paths[2]}, {"--out's metadata", map_paths[3]}},
                            inputs);
  }
  Config config = o->config.empty() ? Config{} : loadConfig(o->config);
  perception::PerceptionParams& pp = config.perception;
  mapping::MapParams& mp = config.mapping;
  if (o->config.empty() || given.max_range->count() > 0) pp.max_range_m = o->max_range;
  if (o->config.empty() || given.resolution->count() > 0) mp.resolution_m = o->resolution;
  if (!config.mapping_max_range_set || given.max_range->count() > 0) mp.max_range_m = pp.max_range_m;
  if (o->no_free_space) mp.free_space_ray_stride_px = 0;
  try {
    if (given.voxel->count() > 0) pp = perception::scaledToVoxel(pp, o->voxel);
    perception::validate(pp);
    mapping::validate(mp);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  std::optional<ExistingMap> existing;
  if (o->extend) {
    existing = openForExtension(o->out);
    const double res = existing->tree->getResolution();
    if (given.resolution->count() > 0 && std::abs(o->resolution - res) > 1e-9) {
      std::ostringstream msg;
      msg << "--resolution " << o->resolution << " differs from the resolution of " << o->out << " (" << res
          << "); an extended map keeps its own";
      throw UsageError(msg.str());
    }
    mp.resolution_m = res;
  }
  const gp::MobilityModel model = makeModel(config);
  const perception::FramePipeline pipeline(pp, model);

  // Inputs: a posed sequence (7-Scenes or TUM directory, .pcd frames with --poses), or
  // a single .pcd or depth .png frame in its camera frame.
  std::unique_ptr<Sequence> dir;
  std::vector<int> frames;
  int keyframes_considered = 0;  // frames selected before --keyframes (0: not used)
  std::optional<Eigen::Vector3d> gravity_world;
  Frame single;
  const bool live = given.device->count() > 0;
  const bool oni = !live && fs::path(o->input).extension() == ".oni";
  if (live == !o->input.empty()) throw UsageError("give either INPUT or --device");
  const bool bag = !live && !o->input.empty() && sources::isRecording(o->input);
  const bool is_dir = live || oni || bag || fs::is_directory(o->input, ec) || !o->poses.empty();
  if (o->skip_bad_frames && (live || oni || !is_dir)) {
    throw UsageError("--skip-bad-frames is for sequences of files (7-Scenes, TUM, .pcd frames with --poses), not " +
                     std::string(live ? "a live sensor" : oni ? "an .oni recording" : "a single frame"));
  }
  // Frames left out as unreadable (--skip-bad-frames): "FILE: problem", in the order found.
  std::vector<std::string> unreadable;
  std::size_t unreadable_before_run = 0;  // left out of `frames` by the checks before the run
  auto noteUnreadable = [&](const std::string& what) {
    unreadable.push_back(what);
    constexpr std::size_t kListed = 10;
    if (unreadable.size() <= kListed) {
      Progress::message("warning: skipped " + what);
    } else if (unreadable.size() == kListed + 1) {
      Progress::message("warning: more unreadable frames skipped; the summary counts them");
    }
  };
  if (live || oni) {
    const FrameRange range = parseRange(o->frames);
    sources::OpenNiOptions on;
    on.uri = live ? o->device : o->input;
    on.is_file = oni;
    on.intrinsics_spec = o->intrinsics;
    on.poses_path = o->poses;
    on.max_pose_gap_s = o->max_pose_gap;
    on.first = range.first, on.last = range.last, on.step = range.step;
    on.interrupted = [] { return g_interrupted.load(); };
    dir = sources::openOpenNi(on);
  }
  std::optional<Eigen::Isometry3d> T_base_camera;  // --extrinsics, read once
  if (is_dir) {
    if (!dir) {
      dir = openSequence(o->input, {o->intrinsics, o->max_pose_gap, o->poses, o->recording, o->depth_format});
    } else if (!o->depth_format.empty()) {
      throw UsageError("--depth-format is for depth images stored in files; OpenNI2 gives millimetres");
    }
    if (given.depth_scale->count() > 0) dir = withDepthScale(std::move(dir), o->depth_scale);
    if (!o->extrinsics.empty()) {
      if (dir->recording()) throw UsageError("--extrinsics: " + o->input + " is a bag, whose TF tree has its camera's mounting");
      T_base_camera = parseExtrinsics(o->extrinsics);
      dir = withExtrinsics(std::move(dir), *T_base_camera);
    }
    const FrameRange range = parseRange(o->frames);
    for (int f : dir->frames()) {
      if (f >= range.first && (range.last < 0 || f <= range.last) && (f - range.first) % range.step == 0) frames.push_back(f);
    }
    if (frames.empty()) throw UsageError("--frames " + o->frames + " selects none of the frames in " + o->input);
    gravity_world = dir->gravityDown();
    // Every frame needs a pose: check them all before the long run starts.
    std::vector<int> readable;
    readable.reserve(frames.size());
    for (int f : frames) {
      try {
        dir->check(f);
        readable.push_back(f);
      } catch (const IoError& e) {
        if (!o->skip_bad_frames) throw withSkipHint(e);
        noteUnreadable(e.what());
      }
    }
    if (readable.empty()) {
      throw IoError(o->input, "no selected frame can be read (" + std::to_string(frames.size()) +
                                  " tried; the first: " + unreadable.front() + "); no map written");
    }
    frames = std::move(readable);
    unreadable_before_run = unreadable.size();
    if (given.keyframes->count() > 0) {
      if (live || oni) {
        throw UsageError("--keyframes needs the poses before the run (7-Scenes, TUM, .pcd frames with --poses); "
                         "OpenNI2 frames get theirs as they arrive");
      }
      std::vector<Eigen::Isometry3d> poses;
      poses.reserve(frames.size());
      for (int f : frames) {
        const auto pose = dir->pose(f);
        if (!pose) throw UsageError("--keyframes: " + o->input + " gives no poses before the run");
        poses.push_back(*pose);
      }
      std::vector<std::size_t> keep;
      try {
        keep = mapping::selectKeyframes(poses, o->keyframes[0], o->keyframes[1]);
      } catch (const std::invalid_argument& e) {
        throw UsageError(std::string("--") + e.what());  // "--keyframes: ..."
      }
      keyframes_considered = static_cast<int>(frames.size());
      std::vector<int> kept;
      kept.reserve(keep.size());
      for (std::size_t i : keep) kept.push_back(frames[i]);
      frames = std::move(kept);
    }
    if (!o->quiet) std::fprintf(stderr, "%s\n", dir->describe().c_str());
    if (!dir->skipped().empty()) {
      const bool ended_early = dir->recording() && !dir->recording()->fault().empty();
      std::fprintf(stderr, "%s: %s\n", ended_early ? "warning" : "note", dir->skipped().c_str());
    }
    if (keyframes_considered > 0 && !o->quiet) {
      std::fprintf(stderr, "keyframes: %zu of the %d selected frames (%s)\n", frames.size(), keyframes_considered,
                   describeKeyframeRule(o->keyframes[0], o->keyframes[1]).c_str());
    }
  } else {
    single = loadSingleFrame(o->input, -1, o->intrinsics);
    if (!single.note.empty()) std::fprintf(stderr, "note: %s\n", single.note.c_str());
    if (!o->depth_format.empty()) decodeDepthFormat(single, o->depth_format, o->input);
    if (given.depth_scale->count() > 0) rescaleDepth(single, o->depth_scale);
    frames.push_back(0);
    if (!o->frames.empty()) throw UsageError("--frames needs a directory input");
    if (given.keyframes->count() > 0) throw UsageError("--keyframes needs a sequence of frames");
  }
  std::string gravity_source;
  if (gravity_world) gravity_source = live || oni ? "the static camera's +y axis" : dir->gravitySource();
  const bool gravity_from_floor = o->gravity == "floor";
  if (gravity_from_floor) {
    if (existing) throw UsageError("--gravity floor: --extend keeps the map's gravity");
    if (live || oni) throw UsageError("--gravity floor needs frames to sample before the run; OpenNI2 input has none");
    gravity_world.reset();  // estimated from the floor below
  } else if (!o->gravity.empty()) {
    gravity_world = parseVector3(o->gravity, "--gravity").cast<double>();
    gravity_source = "--gravity";
  }
  // A gravity given by a file or --gravity, checked against (and by default refined to)
  // the floor; what was given is recorded beside what was used.
  std::optional<Eigen::Vector3d> gravity_given;
  std::optional<double> gravity_floor_angle;
  // A short run fuses the frames the check perceived rather than perceiving them again
  // (kept below only while the gravity stays the one given).
  PerceivedForRun perceived_for_run{pp.ground_max_tilt_deg, {}};
  if (gravity_world && !existing && !live && !oni) {
    gravity_given = gravity_world->normalized();
    const auto floor = floorNear(*gravity_given, is_dir ? dir.get() : nullptr, frames, is_dir ? nullptr : &single, pp,
                                 model, o->skip_bad_frames,
                                 is_dir && frames.size() <= kPerceiveForRunFrames ? &perceived_for_run : nullptr);
    if (floor) {
      gravity_floor_angle = angleDeg(*gravity_given, floor->vote.down);
      char text[400];
      if (*gravity_floor_angle <= kGravityAgreesDeg) {
        std::snprintf(text, sizeof text, "%s (the floor in %d of %zu sampled frames agrees within %.2f degrees)",
                      gravity_source.c_str(), floor->vote.agreeing, floor->sampled, *gravity_floor_angle);
      } else if (o->gravity_refine == "on") {
        gravity_world = floor->vote.down;
        perceived_for_run.results.clear();  // perceived with the gravity given, not this one
        std::snprintf(text, sizeof text, "%s, refined to the floor in %d of %zu sampled frames (%.2f degrees from it)",
                      gravity_source.c_str(), floor->vote.agreeing, floor->sampled, *gravity_floor_angle);
      } else {
        std::snprintf(text, sizeof text, "%s, as given (--gravity-refine off; the floor in %d of %zu sampled frames lies "
                      "%.2f degrees from it)", gravity_source.c_str(), floor->vote.agreeing, floor->sampled,
                      *gravity_floor_angle);
      }
      gravity_source = text;
    } else {
      char text[160];
      std::snprintf(text, sizeof text, " (no floor agreed on within %g degrees of it in the sampled frames: kept as given)",
                    kGravityRefineConeDeg);
      gravity_source += text;
    }
    if (!o->quiet || (gravity_floor_angle && *gravity_floor_angle > 1.0)) {
      std::fprintf(stderr, "note: gravity (down) in the world frame (%.4f, %.4f, %.4f), from %s\n", gravity_world->x(),
                   gravity_world->y(), gravity_world->z(), gravity_source.c_str());
    }
  }
  if (existing && !live) {
    const auto overlaps = overlappingRuns(existing->meta, fs::absolute(o->input, ec).lexically_normal().string(),
                                          frames.front(), frames.back());
    for (const auto& r : overlaps) {
      std::fprintf(stderr,
                   "note: run %zu of %s already fused frames %lld..%lld of this input, which overlap the frames "
                   "selected now (%d..%d): a frame fused again counts twice\n",
                   r.run, o->out.c_str(), r.first, r.last, frames.front(), frames.back());
    }
  }
  if (existing) {
    // The map's frame is kept; a gravity the input states must agree with it.
    if (gravity_world && angleDeg(*gravity_world, existing->down_world) > 1.0) {
      throw UsageError("gravity (down) from " + gravity_source + " is " + formatVector(*gravity_world) + " but " +
                       o->out + " was built with " + formatVector(existing->down_world) +
                       " in the same world frame: are the poses in the world frame of that map?");
    }
    gravity_world = existing->down_world;
    // The frame count stays a whole number a reader accepts, whatever this run adds.
    const long long earlier_frames = existing->meta.frames;
    const long long most = std::numeric_limits<int>::max();
    if (earlier_frames + static_cast<long long>(frames.size()) > most) {
      throw IoError(mapping::mapFileStem(o->out) + ".json",
                    "says the map holds " + std::to_string(earlier_frames) + " frames; " + std::to_string(frames.size()) +
                        " more would pass the " + std::to_string(most) + " a map counts (is \"frames\" right?)");
    }
    // Where the first run took it from (a map extended before records that first).
    const mapping::MapRun& first_run = *existing->meta.runs().front();
    gravity_source = "the map's first run (" + first_run.gravity_source.value_or("its R_map_world") + ")";
  }
  if (is_dir && !gravity_world && !live && !oni) {
    const GravityGuess guess = estimateGravity(*dir, frames, pp, model, o->skip_bad_frames);
    gravity_world = guess.down;
    gravity_source = guess.how;
    std::fprintf(stderr, "note: gravity (down) in the world frame (%.3f, %.3f, %.3f), from %s; --gravity X,Y,Z sets it\n",
                 guess.down.x(), guess.down.y(), guess.down.z(), guess.how.c_str());
  }
  // The run's clock starts here: a lone frame without --gravity is perceived next.
  const auto run_start = std::chrono::steady_clock::now();
  // A single frame is mapped in its camera frame; without --gravity, "down" is the
  // normal of the ground plane the pipeline finds, else the camera's +y axis. That run
  // measured slopes against the same ground normal, so its result is the frame's.
  // A cloud whose points were turned from its camera's frame is mapped in their frame.
  const Eigen::Isometry3d T_world_single = single.T_cloud_camera.value_or(Eigen::Isometry3d::Identity());
  std::optional<perception::FrameResult> single_result;
  if (!is_dir && !gravity_world) {
    single_result = perceiveFrame(pipeline, single, std::nullopt);
    gravity_world = T_world_single.linear() * (single_result->ground_plane
                                                   ? Eigen::Vector3d(-single_result->ground_plane->head<3>().cast<double>())
                                                   : Eigen::Vector3d(0, 1, 0));
    const auto extent = groundExtent(*single_result);
    const std::string how = extent ? "; " + describeGround(*extent) : "";
    gravity_source = !single_result->ground_plane ? "the camera's +y axis (no ground plane)"
                     : single_result->ground_rule == perception::GroundRule::kUprightPrior
                         ? "the frame's ground plane (a floor within ground_upright_prior_deg of the image's up axis" + how + ")"
                         : "the frame's ground plane (its largest plane" + how + ")";
    if (extent && extent->near_m >= kFarGroundM) {
      std::fprintf(stderr,
                   "note: gravity (down) comes from the frame's ground plane, seen only %.1f m from the camera or farther "
                   "(median %.1f m; %s): depth noise grows with the square of the range, so a far floor tilts gravity and "
                   "heights measured above it may be off by centimetres; --gravity X,Y,Z sets it\n",
                   extent->near_m, extent->median_m, describeGround(*extent).c_str());
    }
    const std::string note = groundChoiceNote(*single_result, pp.ground_upright_prior_deg);
    if (!note.empty()) std::fprintf(stderr, "%s\n", note.c_str());
  }
  if (!gravity_world) gravity_source = "-z (default)";
  const Eigen::Vector3d g_world = gravity_world.value_or(Eigen::Vector3d(0, 0, -1));
  const Eigen::Matrix3d R_map_world = existing ? existing->R_map_world : mapping::gravityAlignment(g_world);
  // The map origin: the extended map's, --origin, or the first camera position rounded
  // to 100 m (a stream's first pose arrives with its first frame: set there).
  std::optional<Eigen::Vector3d> origin_world;
  std::string origin_source;
  if (existing) {
    origin_world = existing->origin_world, origin_source = "the map being extended";
  } else if (given.origin->count() > 0) {
    origin_world = Eigen::Vector3d(o->origin[0], o->origin[1], o->origin[2]), origin_source = "--origin";
  } else if (!is_dir) {
    origin_world = Eigen::Vector3d::Zero(), origin_source = "the camera (a single frame)";
  } else if (const auto first = dir->pose(frames.front())) {
    origin_world = mapping::defaultMapOrigin(first->translation()), origin_source = "the first camera position, rounded to 100 m";
  }

  // The camera of the depth images (free space is cleared along their rays), if the
  // input has depth images rather than unorganized clouds.
  const perception::PinholeIntrinsics* depth_k =
      is_dir ? (dir->hasDepth() ? &dir->intrinsics() : nullptr) : (single.depth ? &single.intrinsics : nullptr);
  // MOBMAP_STOP_AFTER_FRAMES=N: the process stops itself (SIGSTOP) once N frames are
  // fused, reported and checkpointed, for tests that act on a running build.
  const char* stop_env = std::getenv("MOBMAP_STOP_AFTER_FRAMES");
  const int stop_after_frames = stop_env ? std::atoi(stop_env) : -1;
  // What the run has done so far. Frames are read here, perceived and fused by the
  // LiveMapper's threads; its callbacks (the fusion thread) and this thread both count,
  // so the counts, the progress line and the camera path are shared under `state`.
  std::mutex state;
  Progress progress("build", static_cast<int>(frames.size()), o->quiet, run_start);
  std::vector<std::pair<std::string, double>> stage_ms;  // in pipeline order
  std::size_t points = 0;
  int used = 0, no_ground = 0, no_pose = 0;
  // Points beyond the map's extent (a pose far from the origin, poses in another unit):
  // counted and reported, never dropped silently. A frame with no point inside adds
  // nothing and is not counted as fused.
  int outside_frames = 0, outside_warnings = 0;
  std::size_t points_outside = 0;
  std::size_t map_nodes = 0;  // after the last frame fused
  const auto describeExtent = [&](const mapping::MobilityMap& m) {
    char text[160];
    const Eigen::Vector3d& c = m.originWorld();
    std::snprintf(text, sizeof text, "+-%.0f m around its origin (%.1f, %.1f, %.1f) in the world frame", m.extentM(),
                  c.x(), c.y(), c.z());
    return std::string(text);
  };
  // Frames the map held before this run (--extend).
  const int frames_before = existing ? existing->meta.frames : 0;
  int unreadable_in_run = 0;  // frames skipped as unreadable after the run started
  int last_fused = frames.front();  // frame number of the last frame fused
  std::vector<Eigen::Vector3d> trajectory;  // camera positions, map frame
  double read_ms = 0, fuse_ms = 0;
  struct Pushed {
    int number;
    Eigen::Isometry3d T_world_camera;
    std::optional<LowZeroBits> bits;  // of its stored depth values, for the unit check
  };
  std::vector<Pushed> pushed;  // by LiveMapper's frame index
  const auto done = [&] { return used + no_pose + unreadable_in_run + outside_frames; };
  const auto showProgress = [&](std::size_t nodes) { progress.update(done(), "map " + std::to_string(nodes) + " nodes"); };
  // The map files: all written, then renamed into place, MAP.ot first, MAP.json last. A checkpoint
  // (--checkpoint) writes the same files in the middle of the run; fusion then goes on
  // in the finalized (pruned) tree, which gives the same map as without (docs/MAPPING.md).
  const std::string device_label = "OpenNI2 device " + (o->device.empty() ? std::string("(first attached)") : o->device);
  // The stop signals' handler is in place since the start of the run: Ctrl-C saves the frames fused so far.
  if (live && !o->quiet) std::fprintf(stderr, "reading %s (Ctrl-C stops and saves the map)\n", device_label.c_str());
  DepthCheckTally depth_checks;  // under `state`, as the rest the callbacks update
  const DepthUnit depth_unit = dir ? dir->depthUnit() : single.depth_unit;
  auto writeMap = [&](const mapping::MobilityMap& map, bool checkpoint, double run_s) {
    mapping::MapRun run;
    run.format = "mobmap-map-metadata";
    run.tool = std::string("mobmap ") + MOBMAP_VERSION_STRING;
    run.tree_type = mapping::MobilityOcTree::kTreeType;
    run.input = live ? device_label : fs::absolute(o->input, ec).lexically_normal().string();
    run.frames_in_run = used;
    run.frames_selected = static_cast<long long>(frames.size()) + unreadable_before_run;
    if (keyframes_considered > 0) run.keyframes = mapping::KeyframeRecord{o->keyframes[0], o->keyframes[1], keyframes_considered};
    if (is_dir && !dir->skipped().empty()) run.skipped = dir->skipped();
    // How this run read its frames, so `overlay` can read them again the same way.
    if (depth_k) run.depth_intrinsics = mapping::DepthCameraRecord{depth_k->fx, depth_k->fy, depth_k->cx, depth_k->cy, depth_k->width, depth_k->height};
    if (!o->poses.empty()) run.poses = fs::absolute(o->poses, ec).lexically_normal().string();
    run.max_pose_gap_s = o->max_pose_gap;
    if (T_base_camera) run.extrinsics = extrinsicsText(*T_base_camera);
    if (const sources::Recording* rec = is_dir ? dir->recording() : nullptr) {
      run.depth_topic = rec->depthTopic();
      if (!rec->cameraInfoTopic().empty()) run.camera_info_topic = rec->cameraInfoTopic();
      if (!rec->worldFrame().empty()) run.world_frame = rec->worldFrame();
    }
    if (no_pose > 0) run.frames_without_pose = no_pose;
    run.unreadable = unreadable;
    run.frame_numbers = std::array<long long, 2>{frames.front(), last_fused};
    run.interrupted = g_interrupted.load();
    run.resolution_m = map.tree().getResolution();
    run.gravity_down_world = g_world;
    run.gravity_source = gravity_source;
    if (gravity_given) run.gravity_given_world = *gravity_given;
    if (gravity_floor_angle) run.gravity_floor_angle_deg = *gravity_floor_angle;
    run.R_map_world = R_map_world;
    run.origin_world = map.originWorld();
    run.origin_source = origin_source.empty() ? std::string("none") : origin_source;
    if (points_outside > 0) {
      run.points_outside_map = static_cast<long long>(points_outside);
      run.frames_outside_map = outside_frames;
    }
    run.seconds = run_s;
    run.frames_per_second = run_s > 0 ? (used + no_pose) / run_s : 0.0;
    if (checkpoint) run.checkpoint = true;
    // The configuration's values that --voxel rescales are recorded with the rest.
    run.perception = mapping::PerceptionRecord{pp.max_range_m, pp.voxel_size_m, pp.normal_k, pp.outlier_k, pp.colour_threshold,
                                               pp.min_segment_points, pp.ground_min_points, pp.neighbour_distance_m,
                                               pp.max_triangle_edge_m, pp.rough_fragment_max_points, pp.rough_min_points,
                                               pp.rough_smoothing_k};
    run.mapping = mapping::MappingRecord{mp.resolution_m, mp.max_range_m, mp.free_space_ray_stride_px, mp.max_weight,
                                         !o->no_free_space};
    run.model = mapping::ModelRecord{config.model.model == gp::ModelKind::kGaussianProcess ? "gp" : "rule",
                                     config.table_path.empty() ? "paper" : config.table_path, config.model.signal_std,
                                     config.model.length_scale, config.model.noise_std};
    if (!o->config.empty()) run.config = fs::absolute(o->config, ec).lexically_normal().string();
    run.points_in_view = static_cast<long long>(depth_checks.validPoints());
    run.points_beyond_range = static_cast<long long>(depth_checks.beyondMaxRange());
    run.depth_units_per_m = depth_unit.units_per_m;
    if (!o->depth_format.empty()) run.depth_format = o->depth_format;
    mapping::MapMetadata meta;
    if (existing) {
      meta = existing->meta;
      meta.addRun(std::move(run), trajectory);
    } else {
      meta.frames = used;
      meta.latest = std::move(run);
      meta.trajectory_map = trajectory;
    }
    // All four or none: a disk that fills up while they are written leaves the map
    // on disk as it was (an --extend run's map included), not a new .ot beside an old .json.
    const mapping::MobilityOcTree& tree = map.tree();
    const std::string meta_text = mapping::formatMapMetadata(meta);
    writeFilesTogether({{map_paths[0], [&](const std::string& tmp) { mapping::saveMobilityMap(tree, tmp); }},
                        {map_paths[1], [&](const std::string& tmp) { mapping::saveOccupancyBt(tree, tmp); }},
                        {map_paths[2], [&](const std::string& tmp) { mapping::saveOctovisColorTree(tree, tmp); }},
                        {map_paths[3], [&](const std::string& tmp) { writeTextFileAtomically(tmp, meta_text); }}});
    return meta;
  };

  // Perception on two threads that last the run (each keeps its pipeline buffers from
  // frame to frame), fusion in order on a third: mapping::LiveMapper.
  mapping::LiveMapper::Config live_config;
  live_config.map = mp;
  live_config.perception = pp;
  live_config.model = model;
  live_config.gravity_down_world = g_world;
  live_config.origin_world = origin_world;
  live_config.perception_threads = 2;
  live_config.queue_capacity = 2;
  // Fusion gets the depth images only to clear what a frame sees through (and cast
  // free-space rays): --no-free-space withholds them.
  live_config.clear_free_space = !o->no_free_space;
  // Unless a server queries the map during the run, each frame is fused once.
  live_config.serve_snapshots = hooks != nullptr;
  std::exception_ptr checkpoint_error;
  mapping::LiveMapper* mapper_ptr = nullptr;
  const auto checkpointDue = [&] {
    return o->checkpoint > 0 && used % o->checkpoint == 0 && done() < static_cast<int>(frames.size());
  };
  const auto holdIfAsked = [&] {
    // Test hook (docs/RELIABILITY.md): stop here, so a test can signal or kill the run
    // at a known frame instead of after a guessed time; a Ctrl-C meanwhile ends the run
    // with this frame.
    if (used != stop_after_frames) return;
    ::raise(SIGSTOP);
    // A Ctrl-C sent while stopped may be handled by another thread after this one goes
    // on: while it is still pending, wait for its handler, so that the frame the run
    // ends with does not depend on which thread the scheduler runs first.
    sigset_t pending;
    const auto stopPending = [&] {
      if (::sigpending(&pending) != 0) return false;
      for (const int sig : kStopSignals) {
        if (::sigismember(&pending, sig) == 1) return true;
      }
      return false;
    };
    while (stopPending()) std::this_thread::yield();
    if (g_interrupted.load()) mapper_ptr->cancel();
  };
  live_config.on_frame = [&](const mapping::FrameReport& r) {
    const std::lock_guard<std::mutex> lock(state);
    if (!r.fused) return;  // perception threw; the frames were checked when read
    const Pushed& f = pushed[r.index];
    const std::shared_ptr<const mapping::MobilityMap> latest = mapper_ptr->snapshot();  // callbacks may
    map_nodes = latest->tree().size();
    if (!origin_world) {  // a stream: its first posed frame set the origin
      origin_world = latest->originWorld();
      origin_source = "the first camera position, rounded to 100 m";
    }
    fuse_ms += r.fusion_ms;
    // Depth in another unit, or a range that cuts away most of the frame or its floor.
    for (const std::string& w : depth_checks.add("frame " + std::to_string(f.number), r.range,
                                                 r.ground_found ? std::optional<double>(r.ground_distance_m) : std::nullopt,
                                                 depth_unit, f.bits)) {
      Progress::message(w);
    }
    const mapping::IntegrationReport& fused = r.integration;
    if (fused.points_outside_map > 0) {
      points_outside += fused.points_outside_map;
      constexpr int kListed = 10;
      if (++outside_warnings <= kListed) {
        Progress::message("warning: frame " + std::to_string(f.number) + ": " + std::to_string(fused.points_outside_map) +
                          " of " + std::to_string(fused.points_outside_map + fused.points_fused) +
                          " points in range lie outside the map's extent (" + describeExtent(*latest) +
                          ") and were left out" + (fused.points_fused == 0 ? ": the frame adds nothing" : ""));
      } else if (outside_warnings == kListed + 1) {
        Progress::message("warning: more frames reach outside the map's extent; the summary counts them");
      }
      if (fused.points_fused == 0) {
        ++outside_frames;
        showProgress(map_nodes);
        return;
      }
    }
    for (const auto& st : r.stages) {
      auto it = std::find_if(stage_ms.begin(), stage_ms.end(), [&](const auto& e) { return e.first == st.name; });
      if (it == stage_ms.end()) it = stage_ms.insert(stage_ms.end(), {st.name, 0.0});
      it->second += st.milliseconds;
    }
    const Eigen::Vector3d c = latest->worldToMap(f.T_world_camera.translation());
    trajectory.push_back({c.x(), c.y(), c.z()});
    points += r.points;
    no_ground += !r.ground_found;
    ++used;
    last_fused = f.number;
    if (hooks && hooks->fused) hooks->fused(latest, frames_before + used, c);
    showProgress(map_nodes);
    if (!checkpointDue()) holdIfAsked();
  };
  live_config.finalize_after = [&](const mapping::FrameReport& r) {
    const std::lock_guard<std::mutex> lock(state);
    return r.integration.points_fused > 0 && checkpointDue();
  };
  live_config.on_finalized = [&](const mapping::MobilityMap& checkpoint_map, const mapping::FrameReport&) {
    const std::lock_guard<std::mutex> lock(state);
    try {
      writeMap(checkpoint_map, true, std::chrono::duration<double>(std::chrono::steady_clock::now() - run_start).count());
    } catch (...) {  // reported by the reading thread, which stops the run
      if (!checkpoint_error) checkpoint_error = std::current_exception();
      mapper_ptr->cancel();
    }
    holdIfAsked();
  };
  std::unique_ptr<mapping::LiveMapper> mapper =
      existing ? std::make_unique<mapping::LiveMapper>(live_config, std::move(existing->tree), R_map_world, *origin_world)
               : std::make_unique<mapping::LiveMapper>(live_config);
  mapper_ptr = mapper.get();
  if (hooks && hooks->started) hooks->started(*mapper, frames_before);
  // Read each frame and hand it over; push() waits while two frames wait for perception.
  for (const int number : frames) {
    if (hooks && hooks->before_frame) hooks->before_frame();
    if (g_interrupted.load()) break;
    const auto t0 = std::chrono::steady_clock::now();
    if (!is_dir) {
      mapping::PerceivedFrame f;
      if (single_result) {
        f.result = std::move(*single_result);
      } else {
        f.result = perceiveFrame(pipeline, single, (T_world_single.linear().transpose() * g_world).cast<float>());
      }
      f.T_world_camera = T_world_single;
      if (single.depth) f.depth = *single.depth;  // free space by projection, as for a sequence
      f.intrinsics = single.intrinsics;
      {
        const std::lock_guard<std::mutex> lock(state);
        pushed.push_back({number, T_world_single, single.depth ? lowZeroBits(*single.depth, depth_unit) : std::nullopt});
      }
      mapper->push(std::move(f));
      continue;
    }
    Frame f;
    try {
      f = dir->load(number);
    } catch (const sources::StreamInterrupted&) {  // Ctrl-C while a live sensor was silent
      break;
    } catch (const IoError& e) {  // a frame that passed check() but cannot be decoded
      if (live || oni) throw;
      if (!o->skip_bad_frames) throw withSkipHint(e);
      const std::lock_guard<std::mutex> lock(state);
      noteUnreadable(e.what());
      ++unreadable_in_run;
      showProgress(map_nodes);
      continue;
    }
    if (!f.T_world_camera) {
      const std::lock_guard<std::mutex> lock(state);
      ++no_pose;
      showProgress(map_nodes);
      continue;
    }
    std::optional<LowZeroBits> bits = f.depth ? lowZeroBits(*f.depth, depth_unit) : std::nullopt;
    {
      const std::lock_guard<std::mutex> lock(state);
      read_ms += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      pushed.push_back({number, *f.T_world_camera, bits});
    }
    try {
      // A frame the gravity check perceived, with the hint LiveMapper would give it (else
      // it is perceived again).
      std::optional<perception::FrameResult> early;
      if (const auto it = perceived_for_run.results.find(number); it != perceived_for_run.results.end()) {
        if (it->second.gravity_down_camera == (f.T_world_camera->linear().transpose() * g_world.normalized()).cast<float>()) {
          early = std::move(it->second.result);
        }
        perceived_for_run.results.erase(it);
      }
      if (early) {
        mapper->push(mapping::PerceivedFrame{std::move(*early), std::move(*f.depth), dir->intrinsics(), *f.T_world_camera, 0.0});
      } else if (dir->hasDepth()) {
        mapper->push(mapping::DepthFrame{std::move(*f.depth), dir->intrinsics(), *f.T_world_camera, 0.0});
      } else {
        mapper->push(mapping::CloudFrame{std::move(f.points), f.width, f.height, *f.T_world_camera, 0.0});
      }
    } catch (const std::invalid_argument& e) {  // a frame LiveMapper cannot take (image and camera disagree)
      throw IoError(o->input, "frame " + std::to_string(number) + ": " + e.what());
    } catch (const std::logic_error&) {  // the run was cancelled: a failed checkpoint or a held Ctrl-C
      break;
    }
  }
  if (g_interrupted.load()) mapper->cancel();  // the frames not yet fused are left out
  mapper->finish();
  if (checkpoint_error) std::rethrow_exception(checkpoint_error);
  for (const int sig : kStopSignals) std::signal(sig, SIG_DFL);
  const std::shared_ptr<const mapping::MobilityMap> final_map = mapper->snapshot();
  mapper.reset();  // joins its threads: the counts are final
  // Reading, perception and fusion of every frame, as the user waited for them.
  const double run_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - run_start).count();

  if (used == 0 && no_pose > 0 && !g_interrupted.load()) {
    std::ostringstream msg;
    msg << "none of the " << no_pose << " frames read has a pose within " << o->max_pose_gap
        << " s of its time stamp (are the poses on the sensor's clock, in seconds?); no map written";
    throw IoError(o->poses, msg.str());
  }
  if (used == 0 && unreadable_in_run > 0 && !g_interrupted.load()) {
    throw IoError(o->input, "no selected frame could be read (" + std::to_string(unreadable.size()) +
                                " tried; the first: " + unreadable.front() + "); no map written");
  }
  // Most frames outside the map: a map of the few inside would hide the mistake (a stray
  // first pose that placed the map, poses in another unit, a wrong --origin).
  if (outside_frames > used && !g_interrupted.load()) {
    const std::string which = used == 0 ? "all " + std::to_string(outside_frames)
                                        : std::to_string(outside_frames) + " of " + std::to_string(outside_frames + used);
    throw IoError(live ? device_label : o->input,
                  which + " frames with points in range lie outside the map's extent (" + describeExtent(*final_map) +
                      "); no map written. Are the poses in metres? The map's origin comes from " + origin_source +
                      ": --origin X Y Z centres the map elsewhere, and --frames leaves out a stray pose");
  }
  if (g_interrupted.load() && used == 0) {
    // Stopped before the first frame was fused: there is nothing to save, and a map
    // being extended stays exactly as it was.
    std::fprintf(stderr, "interrupted before any frame was fused: %s\n",
                 existing ? ("the map at " + o->out + " is unchanged").c_str() : "no map written");
    return interruptedCode();
  }
  if (final_map->tree().size() == 0 && used > 0 && !g_interrupted.load()) {
    // Nothing in range anywhere (a range shorter than the scene, depth in the wrong
    // unit, a sensor facing the sky): an empty map would only hide the mistake.
    std::ostringstream msg;
    msg << "none of the " << used << " frames fused ";
    if (points == 0) {
      msg << "has a measured point between " << pp.min_range_m << " and " << pp.max_range_m
          << " m of the camera (--max-range)";
    } else {
      msg << "has a surface segment (" << points << " points in range, none in a segment of at least "
          << pp.min_segment_points << ")";
    }
    msg << ", so the map would be empty";
    if (o->checkpoint > 0 && used >= o->checkpoint) {
      msg << " (the checkpoint at " << o->out << " is)";
    } else {
      msg << "; no map written";
    }
    msg << ". Check the range, the depth unit and the intrinsics";
    if (const auto unit = depth_checks.unitProblem()) msg << " (" << *unit << ")";
    throw IoError(live ? device_label : o->input, msg.str());
  }
  if (depth_checks.everyFrameInAnotherUnit() && !g_interrupted.load()) {
    // A map of depth read in the wrong unit is not the scene's: say what fits instead.
    std::ostringstream msg;
    msg << "every frame fused reads as depth in another unit (" << *depth_checks.unitProblem() << ")";
    msg << (o->checkpoint > 0 && used >= o->checkpoint ? "; the checkpoint at " + o->out + " holds them" : "; no map written");
    throw IoError(live ? device_label : o->input, msg.str());
  }
  const mapping::MapMetadata meta = writeMap(*final_map, false, run_s);
  if (hooks && hooks->saved) hooks->saved(final_map, meta);

  const std::string keyframe_note =
      keyframes_considered > 0 ? ", keyframes of " + std::to_string(keyframes_considered) + " selected" : "";
  std::printf("\n%d of %zu frames fused (%d without a ground plane%s)%s in %.1f s (%.1f frames/s), %zu points, %zu map nodes (%zu leaves)\n",
              used, frames.size() + unreadable_before_run, no_ground, keyframe_note.c_str(), g_interrupted.load() ? ", INTERRUPTED" : "", run_s,
              *meta.latest.frames_per_second, points, final_map->tree().size(), final_map->tree().getNumLeafNodes());
  if (points_outside > 0) {
    std::printf("%zu points lay outside the map's extent (%s) and were left out", points_outside, describeExtent(*final_map).c_str());
    if (outside_frames > 0) std::printf("; %d frames had no point inside and are not counted as fused", outside_frames);
    std::printf("\n");
  }
  if (existing) {
    std::printf("the map now holds %d frames from %zu runs\n", meta.frames, meta.earlier_runs.size() + 1);
  }
  for (const std::string& line : depth_checks.summary()) std::printf("%s\n", line.c_str());
  if (gravity_given) {  // checked against the floor: what was given and what was used
    std::printf("gravity (down): (%.4f, %.4f, %.4f) given, (%.4f, %.4f, %.4f) used: %s\n", gravity_given->x(),
                gravity_given->y(), gravity_given->z(), g_world.x(), g_world.y(), g_world.z(), gravity_source.c_str());
  }
  if (no_pose > 0) {
    std::printf("%d frames skipped: no pose within %g s of their time stamp in %s\n", no_pose, o->max_pose_gap,
                o->poses.c_str());
  }
  if (live && !dir->skipped().empty()) std::printf("%s\n", dir->skipped().c_str());
  if (!unreadable.empty()) {
    if (unreadable.size() == 1) {
      std::printf("1 frame skipped as unreadable (--skip-bad-frames): %s\n", unreadable.front().c_str());
    } else {
      std::printf("%zu frames skipped as unreadable (--skip-bad-frames), the first: %s (MAP.json lists them all)\n",
                  unreadable.size(), unreadable.front().c_str());
    }
  }
  std::printf("time per frame (ms): read %.1f", used ? read_ms / used : 0.0);
  for (const auto& [name, ms] : stage_ms) std::printf(", %s %.1f", name.c_str(), ms / std::max(1, used));
  std::printf(", fusion %.1f\n", used ? fuse_ms / used : 0.0);
  std::printf("wrote %s, %s.bt, %s.octovis.ot (view: octovis %s.octovis.ot), %s.json\n", o->out.c_str(), stem.c_str(),
              stem.c_str(), stem.c_str(), stem.c_str());
  if (g_interrupted.load()) {
    if (existing) {
      std::fprintf(stderr, "interrupted: saved the map with the first %d frames of this run added\n", used);
    } else {
      std::fprintf(stderr, "interrupted: saved the map of the first %d frames\n", used);
    }
    return interruptedCode();
  }
  return 0;
}

}  // namespace mobmap::app
