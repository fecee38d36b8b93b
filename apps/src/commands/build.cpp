// `mobmap build`: the command, and the steps of its run before the frames (BuildRun,
// build_run.hpp; the run itself and what follows it are in build_run.cpp).
#include "io/cli_text.hpp"
#include "commands/build_run.hpp"
#include "commands/build_steps.hpp"
#include "commands/commands.hpp"
#include "io/config.hpp"
#include "io/dataset.hpp"
#include "io/extrinsics.hpp"
#include "io/files.hpp"
#include "io/frame_source.hpp"
#include "io/io_error.hpp"
#include "io/map_files.hpp"
#include "mobmap/sources/openni.hpp"

#include "mobmap/mapping/gravity.hpp"
#include "mobmap/mapping/trajectory.hpp"

#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sstream>

namespace mobmap::app {
using namespace build;  // the steps of this command (build_steps.hpp, build_run.hpp)
namespace fs = std::filesystem;
namespace {

extern "C" void onBuildStopSignal(int sig) {
  int none = 0;
  g_signal.compare_exchange_strong(none, sig);  // the first signal names the exit code
  g_interrupted.store(true);
}

}  // namespace

Command addBuildCommand(CLI::App& app) {
  const std::shared_ptr<BuildOptions> o = addBuildOptions(app);
  return [o]() { return runBuild(*o, nullptr); };
}
int build::runBuild(BuildOptions& options, const LiveHooks* hooks) { return BuildRun(options, hooks).execute(); }

int BuildRun::execute() {
  prepare();
  openInput();
  settleGravity();
  placeMap();
  runFrames();
  return finish();
}

void BuildRun::prepare() {
  if (given.fov->count() > 0) o->intrinsics = fovSpec(o->fov);
  if (fs::path(o->out).extension() != ".ot") throw UsageError("--out must end in .ot, got '" + o->out + "'");
  // From here a stop signal ends the run as it stands (with what was fused saved), never
  // the process in the middle of it: the frames read before the first is fused are the
  // only ones it can cost.
  for (const int sig : kStopSignals) std::signal(sig, onBuildStopSignal);
  // One writer per map for the whole run: a second build to the same --out (fresh or
  // --extend) fails here at once instead of replacing the first one's frames.
  map_lock.emplace(o->out);
  if (given.origin->count() > 0 && !Eigen::Vector3d(o->origin[0], o->origin[1], o->origin[2]).allFinite()) {
    throw UsageError("--origin: values must be finite");
  }
  if (o->extend && !fs::exists(o->out, ec)) throw UsageError("--extend: " + o->out + " does not exist (build it without --extend first)");
  if (!o->force && !o->extend && fs::exists(o->out, ec)) {
    throw UsageError(o->out + " exists; pass --force to overwrite it or --extend to add frames to it");
  }
  // Now, not after the whole run; all four files, so that none of them is in the way
  // (a directory of that name) when they are renamed into place.
  stem = mapping::mapFileStem(o->out);
  map_paths = {o->out, stem + ".bt", stem + ".octovis.ot", stem + ".json"};
  for (const std::string& path : map_paths) checkWritable(path);  // creates the map's folder
  {
    std::vector<NamedPath> inputs{{"the input", o->input}, {"--poses", o->poses}, {"--config", o->config}};
    if (fs::is_regular_file(o->intrinsics, ec)) inputs.push_back({"--intrinsics", o->intrinsics});
    refuseToOverwriteInputs({{"--out", map_paths[0]}, {"--out's occupancy export", map_paths[1]},
                             {"--out's octovis export", map_paths[2]}, {"--out's metadata", map_paths[3]}},
                            inputs);
  }
  config = o->config.empty() ? Config{} : loadConfig(o->config);
  if (o->config.empty() || given.max_range->count() > 0) pp.max_range_m = o->max_range;
  if (o->config.empty() || given.resolution->count() > 0) mp.resolution_m = o->resolution;
  if (!config.mapping_max_range_set || given.max_range->count() > 0) mp.max_range_m = pp.max_range_m;
  if (o->no_free_space) mp.free_space_ray_stride_px = 0;
  try {
    if (given.voxel->count() > 0) pp = perception::scaledToVoxel(pp, o->voxel);
    perception::validate(pp);
    mapping::validate(mp);
  } catch (const std::invalid_argument& e) {
    throw UsageError(cliText(e));
  }
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
  model = makeModel(config);
  pipeline.emplace(pp, model);
}

void BuildRun::noteUnreadable(const std::string& what) {
  unreadable.push_back(what);
  constexpr std::size_t kListed = 10;
  if (unreadable.size() <= kListed) {
    Progress::message("warning: skipped " + what);
  } else if (unreadable.size() == kListed + 1) {
    Progress::message("warning: more unreadable frames skipped; the summary counts them");
  }
}

void BuildRun::openInput() {
  // Inputs: a posed sequence (7-Scenes or TUM directory, .pcd frames with --poses), or
  // a single .pcd or depth .png frame in its camera frame.
  live = given.device->count() > 0;
  oni = !live && fs::path(o->input).extension() == ".oni";
  if (live == !o->input.empty()) throw UsageError("give either INPUT or --device");
  bag = !live && !o->input.empty() && sources::isRecording(o->input);
  is_dir = live || oni || bag || fs::is_directory(o->input, ec) || !o->poses.empty();
  if (o->skip_bad_frames && (live || oni || !is_dir)) {
    throw UsageError("--skip-bad-frames is for sequences of files (7-Scenes, TUM, .pcd frames with --poses), not " +
                     std::string(live ? "a live sensor" : oni ? "an .oni recording" : "a single frame"));
  }
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
    if (!o->quiet) std::fprintf(stderr, "%s\n", cliText(dir->describe()).c_str());
    if (dir->recording() && !dir->recording()->recovered().empty()) {
      std::fprintf(stderr, "warning: a recording its recorder did not finish, recovered: %s\n",
                   cliText(dir->recording()->recovered()).c_str());
    }
    if (!dir->skipped().empty()) {
      const bool ended_early = dir->recording() && !dir->recording()->fault().empty();
      std::fprintf(stderr, "%s: %s\n", ended_early ? "warning" : "note", cliText(dir->skipped()).c_str());
    }
    if (keyframes_considered > 0 && !o->quiet) {
      std::fprintf(stderr, "keyframes: %zu of the %d selected frames (%s)\n", frames.size(), keyframes_considered,
                   describeKeyframeRule(o->keyframes[0], o->keyframes[1]).c_str());
    }
  } else {
    single = loadSingleFrame(o->input, -1, o->intrinsics);
    if (!single.note.empty()) std::fprintf(stderr, "note: %s\n", cliText(single.note).c_str());
    if (!o->depth_format.empty()) decodeDepthFormat(single, o->depth_format, o->input);
    if (given.depth_scale->count() > 0) rescaleDepth(single, o->depth_scale);
    frames.push_back(0);
    if (!o->frames.empty()) throw UsageError("--frames needs a directory input");
    if (given.keyframes->count() > 0) throw UsageError("--keyframes needs a sequence of frames");
  }
}

void BuildRun::settleGravity() {
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
  // A short run fuses the frames the check perceived rather than perceiving them again
  // (kept below only while the gravity stays the one given).
  perceived_for_run.ground_cone_deg = pp.ground_max_tilt_deg;
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
  run_start = std::chrono::steady_clock::now();
  // A single frame is mapped in its camera frame; without --gravity, "down" is the
  // normal of the ground plane the pipeline finds, else the camera's +y axis. That run
  // measured slopes against the same ground normal, so its result is the frame's.
  // A cloud whose points were turned from its camera's frame is mapped in their frame.
  T_world_single = single.T_cloud_camera.value_or(Eigen::Isometry3d::Identity());
  if (!is_dir && !gravity_world) {
    single_result = perceiveFrame(*pipeline, single, std::nullopt);
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
  g_world = gravity_world.value_or(Eigen::Vector3d(0, 0, -1));
  R_map_world = existing ? existing->R_map_world : mapping::gravityAlignment(g_world);
}

void BuildRun::placeMap() {
  // The map origin: the extended map's, --origin, or the first camera position rounded
  // to 100 m (a stream's first pose arrives with its first frame: set there).
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
  depth_k = is_dir ? (dir->hasDepth() ? &dir->intrinsics() : nullptr) : (single.depth ? &single.intrinsics : nullptr);
  // MOBMAP_STOP_AFTER_FRAMES=N: the process stops itself (SIGSTOP) once N frames are
  // fused, reported and checkpointed, for tests that act on a running build.
  const char* stop_env = std::getenv("MOBMAP_STOP_AFTER_FRAMES");
  stop_after_frames = stop_env ? std::atoi(stop_env) : -1;
  progress.emplace("build", static_cast<int>(frames.size()), o->quiet, run_start);
  frames_before = existing ? existing->meta.frames : 0;
  last_fused = frames.front();
  device_label = "OpenNI2 device " + (o->device.empty() ? std::string("(first attached)") : o->device);
  // The stop signals' handler is in place since the start of the run: Ctrl-C saves the frames fused so far.
  if (live && !o->quiet) std::fprintf(stderr, "reading %s (Ctrl-C stops and saves the map)\n", device_label.c_str());
  depth_unit = dir ? dir->depthUnit() : single.depth_unit;
}

}  // namespace mobmap::app
