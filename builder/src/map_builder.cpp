// buildMap(): a map from any input, as `mobmap build` builds it (map_builder.hpp). Each
// step is a function taking what the steps before gave: prepare() -> Prepared,
// openInput() -> Input, settleGravity() -> Gravity, placeMap() -> Placement,
// runFrames() -> Fused, then finish() writes the map and reports.
#include "mobmap/builder/map_builder.hpp"

#include "build_steps.hpp"

#include "mobmap/builder/config.hpp"
#include "mobmap/builder/depth_checks.hpp"
#include "mobmap/builder/files.hpp"
#include "mobmap/builder/frames.hpp"
#include "mobmap/mapping/gravity.hpp"
#include "mobmap/mapping/map_lock.hpp"
#include "mobmap/mapping/trajectory.hpp"
#include "mobmap/sources/adjusted.hpp"
#include "mobmap/sources/openni.hpp"
#include "mobmap/sources/recording.hpp"
#include "mobmap/util/field_error.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <limits>
#include <mutex>
#include <sstream>

#ifndef MOBMAP_VERSION_STRING
#define MOBMAP_VERSION_STRING "unknown"
#endif

namespace mobmap::builder {
namespace fs = std::filesystem;
namespace {

using Clock = std::chrono::steady_clock;

std::string describeExtent(const mapping::MobilityMap& m) {
  char text[160];
  const Eigen::Vector3d& c = m.originWorld();
  std::snprintf(text, sizeof text, "+-%.0f m around its origin (%.1f, %.1f, %.1f) in the world frame", m.extentM(),
                c.x(), c.y(), c.z());
  return std::string(text);
}

std::string absolutePath(const std::string& path) {
  std::error_code ec;
  return fs::absolute(path, ec).lexically_normal().string();
}

// The hooks, callable whether or not the caller set them.
struct Say {
  const BuildHooks& hooks;
  void operator()(Message kind, const std::string& line) const {
    if (hooks.message) hooks.message(kind, line);
  }
  [[nodiscard]] bool stopped() const { return hooks.stop && hooks.stop(); }
};

// prepare(): the options checked, the map's files claimed, the parameters.
struct Prepared {
  std::unique_ptr<mapping::MapLock> lock;  // one writer per map for the whole run
  std::string stem;
  std::array<std::string, 4> paths;  // .ot, .bt, .octovis.ot, .json
  Config config;
  std::optional<ExistingMap> existing;
  gp::MobilityModel model;
  std::unique_ptr<perception::FramePipeline> pipeline;
};

Prepared prepare(const BuildOptions& o) {
  std::error_code ec;
  if (fs::path(o.out).extension() != ".ot") throw util::FieldError("out", "must end in .ot, got '" + o.out + "'");
  if (o.origin && !o.origin->allFinite()) throw util::FieldError("origin", "values must be finite");
  if (o.extend && o.force) throw util::ValueError("`extend` and `force` exclude each other");
  if (o.extend && o.origin) throw util::ValueError("`extend` keeps the map's origin: `origin` cannot be given with it");
  if (o.checkpoint_frames < 0) throw util::FieldError("checkpoint_frames", "must be 0 or more");
  if (!(o.max_pose_gap_s >= 0)) throw util::FieldError("max_pose_gap_s", "must be a finite number of seconds >= 0");
  if (o.perception_threads < 1 || o.perception_threads > 64) throw util::FieldError("perception_threads", "must be 1 to 64");
  Prepared p;
  // One writer per map for the whole run: a second build to the same `out` (fresh or
  // `extend`) fails here at once instead of replacing the first one's frames.
  p.lock = std::make_unique<mapping::MapLock>(o.out);
  if (o.extend && !fs::exists(o.out, ec)) {
    throw util::FieldError("extend", ": " + o.out + " does not exist (build it without `extend` first)");
  }
  if (!o.force && !o.extend && fs::exists(o.out, ec)) {
    throw util::FieldError("out", o.out + " exists; `force` overwrites it, `extend` adds frames to it");
  }
  // Now, not after the whole run; all four files, so that none of them is in the way
  // (a directory of that name) when they are renamed into place.
  p.stem = mapping::mapFileStem(o.out);
  p.paths = {o.out, p.stem + ".bt", p.stem + ".octovis.ot", p.stem + ".json"};
  for (const std::string& path : p.paths) checkWritable(path);  // creates the map's folder
  if (!o.fine_surface_ply.empty()) {
    if (!o.force && fs::exists(o.fine_surface_ply, ec)) {
      throw util::FieldError("fine_surface_ply", o.fine_surface_ply + " exists; `force` overwrites it");
    }
    checkWritable(o.fine_surface_ply);
  }
  {
    std::vector<NamedPath> inputs{{"the input", o.input}, {"`poses`", o.poses}, {"`config`", o.config}};
    if (fs::is_regular_file(o.intrinsics, ec)) inputs.push_back({"`intrinsics`", o.intrinsics});
    std::vector<NamedPath> outputs{{"`out`", p.paths[0]}, {"`out`'s occupancy export", p.paths[1]},
                                   {"`out`'s octovis export", p.paths[2]}, {"`out`'s metadata", p.paths[3]}};
    if (!o.fine_surface_ply.empty()) outputs.push_back({"`fine_surface_ply`", o.fine_surface_ply});
    refuseToOverwriteInputs(outputs, inputs);
  }
  p.config = o.config.empty() ? Config{} : loadConfig(o.config);
  perception::PerceptionParams& perception_params = p.config.perception;
  mapping::MapParams& map_params = p.config.mapping;
  if (o.config.empty() || o.max_range_m) perception_params.max_range_m = o.max_range_m.value_or(3.0);
  if (o.config.empty() || o.resolution_m) map_params.resolution_m = o.resolution_m.value_or(0.02);
  if (!p.config.mapping_max_range_set || o.max_range_m) map_params.max_range_m = perception_params.max_range_m;
  if (!o.free_space) map_params.free_space_ray_stride_px = 0;
  if (!o.fine_surface_ply.empty()) map_params.fine_surface = true;
  if (o.voxel_size_m) perception_params = perception::scaledToVoxel(perception_params, *o.voxel_size_m);
  perception::validate(perception_params);
  mapping::validate(map_params);
  if (o.extend) {
    p.existing = openForExtension(o.out);
    const double res = p.existing->tree->getResolution();
    if (o.resolution_m && std::abs(*o.resolution_m - res) > 1e-9) {
      std::ostringstream msg;
      msg << *o.resolution_m << " differs from the resolution of " << o.out << " (" << res
          << "); an extended map keeps its own";
      throw util::FieldError("resolution_m", msg.str());
    }
    map_params.resolution_m = res;
  }
  p.model = makeModel(p.config);
  p.pipeline = std::make_unique<perception::FramePipeline>(perception_params, p.model);
  return p;
}

// openInput(): the sequence (or the lone frame), its frames selected and checked.
struct Input {
  std::unique_ptr<Sequence> sequence;  // null for a lone frame
  Frame single;                        // a lone frame (no sequence)
  bool live = false, oni = false;
  std::vector<int> frames;
  int keyframes_considered = 0;  // frames selected before keyframes (0: not used)
  std::optional<Eigen::Vector3d> gravity_world;  // the input's own
  std::optional<Eigen::Isometry3d> T_base_camera;
  std::string device_label;
  // Frames left out as unreadable (skip_bad_frames): "FILE: problem", in the order found.
  std::vector<std::string> unreadable;
  std::size_t unreadable_before_run = 0;
  [[nodiscard]] bool isSequence() const { return sequence != nullptr; }
  [[nodiscard]] sources::DepthUnit depthUnit() const { return sequence ? sequence->depthUnit() : single.depth_unit; }
};

void noteUnreadable(std::vector<std::string>& unreadable, const std::string& what, const Say& say) {
  unreadable.push_back(what);
  constexpr std::size_t kListed = 10;
  if (unreadable.size() <= kListed) {
    say(Message::kWarning, "warning: skipped " + what);
  } else if (unreadable.size() == kListed + 1) {
    say(Message::kWarning, "warning: more unreadable frames skipped; the summary counts them");
  }
}

Input openInput(const BuildOptions& o, const Say& say) {
  std::error_code ec;
  Input in;
  in.live = o.device.has_value();
  in.oni = !in.live && fs::path(o.input).extension() == ".oni";
  if (in.live == !o.input.empty()) throw util::ValueError("give either the input or `device`");
  const bool bag = !in.live && !o.input.empty() && sources::isRecording(o.input);
  const bool sequence = in.live || in.oni || bag || fs::is_directory(o.input, ec) || !o.poses.empty();
  if (o.skip_bad_frames && (in.live || in.oni || !sequence)) {
    throw util::FieldError("skip_bad_frames", "is for sequences of files (7-Scenes, TUM, .pcd frames with `poses`), not " +
                                                  std::string(in.live ? "a live sensor" : in.oni ? "an .oni recording" : "a single frame"));
  }
  in.device_label = "OpenNI2 device " + (o.device.value_or("").empty() ? std::string("(first attached)") : *o.device);
  if (in.live || in.oni) {
    const FrameRange range = parseFrameRange(o.frames);
    sources::OpenNiOptions on;
    on.uri = in.live ? *o.device : o.input;
    on.is_file = in.oni;
    on.intrinsics_spec = o.intrinsics;
    on.poses_path = o.poses;
    on.max_pose_gap_s = o.max_pose_gap_s;
    on.first = range.first, on.last = range.last, on.step = range.step;
    on.interrupted = [&say] { return say.stopped(); };
    in.sequence = sources::openOpenNi(on);
  }
  if (!sequence) {
    in.single = loadSingleFrame(o.input, -1, o.intrinsics);
    if (!in.single.note.empty()) say(Message::kNote, "note: " + in.single.note);
    if (!o.depth_format.empty()) decodeDepthFormat(in.single, o.depth_format, o.input);
    if (o.depth_scale) sources::rescaleDepth(in.single, *o.depth_scale);
    in.frames.push_back(0);
    if (!o.frames.empty()) throw util::FieldError("frames", "needs a directory input");
    if (o.keyframes) throw util::FieldError("keyframes", "needs a sequence of frames");
    return in;
  }
  if (!in.sequence) {
    in.sequence = sources::openSequence(o.input, {o.intrinsics, o.max_pose_gap_s, o.poses, o.recording, o.depth_format});
  } else if (!o.depth_format.empty()) {
    throw util::FieldError("depth_format", "is for depth images stored in files; OpenNI2 gives millimetres");
  }
  if (o.depth_scale) in.sequence = sources::withDepthScale(std::move(in.sequence), *o.depth_scale);
  if (!o.extrinsics.empty()) {
    if (in.sequence->recording()) {
      throw util::FieldError("extrinsics", ": " + o.input + " is a bag, whose TF tree has its camera's mounting");
    }
    in.T_base_camera = sources::parseExtrinsics(o.extrinsics);
    in.sequence = sources::withExtrinsics(std::move(in.sequence), *in.T_base_camera);
  }
  const Sequence& input = *in.sequence;
  const FrameRange range = parseFrameRange(o.frames);
  for (int f : input.frames()) {
    if (f >= range.first && (range.last < 0 || f <= range.last) && (f - range.first) % range.step == 0) in.frames.push_back(f);
  }
  if (in.frames.empty()) throw util::FieldError("frames", o.frames + " selects none of the frames in " + o.input);
  in.gravity_world = input.gravityDown();
  // Every frame needs a pose: check them all before the long run starts.
  std::vector<int> readable;
  readable.reserve(in.frames.size());
  for (int f : in.frames) {
    try {
      input.check(f);
      readable.push_back(f);
    } catch (const IoError& e) {
      if (!o.skip_bad_frames) throw withSkipHint(e);
      noteUnreadable(in.unreadable, e.what(), say);
    }
  }
  if (readable.empty()) {
    throw IoError(o.input, "no selected frame can be read (" + std::to_string(in.frames.size()) +
                               " tried; the first: " + in.unreadable.front() + "); no map written");
  }
  in.frames = std::move(readable);
  in.unreadable_before_run = in.unreadable.size();
  if (o.keyframes) {
    if (in.live || in.oni) {
      throw util::FieldError("keyframes", "needs the poses before the run (7-Scenes, TUM, .pcd frames with `poses`); "
                                          "OpenNI2 frames get theirs as they arrive");
    }
    std::vector<Eigen::Isometry3d> poses;
    poses.reserve(in.frames.size());
    for (int f : in.frames) {
      const auto pose = input.pose(f);
      if (!pose) throw util::FieldError("keyframes", ": " + o.input + " gives no poses before the run");
      poses.push_back(*pose);
    }
    std::vector<std::size_t> keep;
    try {
      keep = mapping::selectKeyframes(poses, o.keyframes->first, o.keyframes->second);
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();  // "keyframes: ..."
      throw util::FieldError("keyframes", ":" + what.substr(what.find(':') + 1));
    }
    in.keyframes_considered = static_cast<int>(in.frames.size());
    std::vector<int> kept;
    kept.reserve(keep.size());
    for (std::size_t i : keep) kept.push_back(in.frames[i]);
    in.frames = std::move(kept);
  }
  say(Message::kDetail, input.describe());
  if (input.recording() && !input.recording()->recovered().empty()) {
    say(Message::kWarning, "warning: a recording its recorder did not finish, recovered: " + input.recording()->recovered());
  }
  if (!input.skipped().empty()) {
    const bool ended_early = input.recording() && !input.recording()->fault().empty();
    say(ended_early ? Message::kWarning : Message::kNote, std::string(ended_early ? "warning" : "note") + ": " + input.skipped());
  }
  if (in.keyframes_considered > 0) {
    say(Message::kDetail, "keyframes: " + std::to_string(in.frames.size()) + " of the " +
                              std::to_string(in.keyframes_considered) + " selected frames (" +
                              describeKeyframeRule(o.keyframes->first, o.keyframes->second) + ")");
  }
  return in;
}

// settleGravity(): "down" in the world frame, and the map's rotation from it.
struct Gravity {
  Eigen::Vector3d down_world = Eigen::Vector3d(0, 0, -1);
  Eigen::Matrix3d R_map_world = Eigen::Matrix3d::Identity();
  std::string source;
  std::optional<Eigen::Vector3d> given;     // checked against the floor
  std::optional<double> floor_angle_deg;
  PerceivedForRun perceived_for_run;        // frames the check perceived, for the run
  Eigen::Isometry3d T_world_single = Eigen::Isometry3d::Identity();
  std::optional<perception::FrameResult> single_result;
  Clock::time_point run_start;
};

Gravity settleGravity(const BuildOptions& o, const Prepared& p, const Input& in, const Say& say) {
  std::error_code ec;
  const perception::PerceptionParams& perception_params = p.config.perception;
  Gravity g;
  std::optional<Eigen::Vector3d> gravity_world = in.gravity_world;
  if (gravity_world) g.source = in.live || in.oni ? "the static camera's +y axis" : in.sequence->gravitySource();
  if (o.gravity_from_floor) {
    if (o.gravity) throw util::ValueError("`gravity` and `gravity_from_floor` exclude each other");
    if (p.existing) throw util::FieldError("gravity_from_floor", ": `extend` keeps the map's gravity");
    if (in.live || in.oni) throw util::FieldError("gravity_from_floor", "needs frames to sample before the run; OpenNI2 input has none");
    gravity_world.reset();  // estimated from the floor below
  } else if (o.gravity) {
    // Normalised in double (stableNorm does not overflow), kept as a float direction: as
    // every front has given it since maps recorded it.
    const double length = o.gravity->stableNorm();
    if (!o.gravity->allFinite() || !(length >= 1e-6)) throw util::FieldError("gravity", "must be a finite, non-zero vector");
    gravity_world = (*o.gravity / length).cast<float>().cast<double>();
    g.source = "`gravity`";
  }
  // A gravity given by a file or `gravity`, checked against (and by default refined to)
  // the floor; what was given is recorded beside what was used. A short run fuses the
  // frames the check perceived rather than perceiving them again (kept below only while
  // the gravity stays the one given).
  g.perceived_for_run.ground_cone_deg = perception_params.ground_max_tilt_deg;
  if (gravity_world && !p.existing && !in.live && !in.oni) {
    g.given = gravity_world->normalized();
    const auto floor = floorNear(*g.given, in.sequence.get(), in.frames, in.isSequence() ? nullptr : &in.single,
                                 perception_params, p.model, o.skip_bad_frames,
                                 in.isSequence() && in.frames.size() <= kPerceiveForRunFrames ? &g.perceived_for_run : nullptr);
    if (floor) {
      g.floor_angle_deg = angleDeg(*g.given, floor->vote.down);
      char text[400];
      if (*g.floor_angle_deg <= kGravityAgreesDeg) {
        std::snprintf(text, sizeof text, "%s (the floor in %d of %zu sampled frames agrees within %.2f degrees)",
                      g.source.c_str(), floor->vote.agreeing, floor->sampled, *g.floor_angle_deg);
      } else if (o.refine_gravity) {
        gravity_world = floor->vote.down;
        g.perceived_for_run.results.clear();  // perceived with the gravity given, not this one
        std::snprintf(text, sizeof text, "%s, refined to the floor in %d of %zu sampled frames (%.2f degrees from it)",
                      g.source.c_str(), floor->vote.agreeing, floor->sampled, *g.floor_angle_deg);
      } else {
        std::snprintf(text, sizeof text, "%s, as given (`refine_gravity` off; the floor in %d of %zu sampled frames lies "
                      "%.2f degrees from it)", g.source.c_str(), floor->vote.agreeing, floor->sampled, *g.floor_angle_deg);
      }
      g.source = text;
    } else {
      char text[160];
      std::snprintf(text, sizeof text, " (no floor agreed on within %g degrees of it in the sampled frames: kept as given)",
                    kGravityRefineConeDeg);
      g.source += text;
    }
    char text[600];
    std::snprintf(text, sizeof text, "note: gravity (down) in the world frame (%.4f, %.4f, %.4f), from %s", gravity_world->x(),
                  gravity_world->y(), gravity_world->z(), g.source.c_str());
    say(g.floor_angle_deg && *g.floor_angle_deg > 1.0 ? Message::kNote : Message::kDetail, text);
  }
  if (p.existing && !in.live) {
    const auto overlaps = overlappingRuns(p.existing->meta, absolutePath(o.input), in.frames.front(), in.frames.back());
    for (const auto& r : overlaps) {
      say(Message::kNote, "note: run " + std::to_string(r.run) + " of " + o.out + " already fused frames " +
                              std::to_string(r.first) + ".." + std::to_string(r.last) +
                              " of this input, which overlap the frames selected now (" + std::to_string(in.frames.front()) +
                              ".." + std::to_string(in.frames.back()) + "): a frame fused again counts twice");
    }
  }
  if (p.existing) {
    // The map's frame is kept; a gravity the input states must agree with it.
    if (gravity_world && angleDeg(*gravity_world, p.existing->down_world) > 1.0) {
      throw util::ValueError("gravity (down) from " + g.source + " is " + formatVector(*gravity_world) + " but " + o.out +
                             " was built with " + formatVector(p.existing->down_world) +
                             " in the same world frame: are the poses in the world frame of that map?");
    }
    gravity_world = p.existing->down_world;
    // The frame count stays a whole number a reader accepts, whatever this run adds.
    const long long earlier_frames = p.existing->meta.frames;
    const long long most = std::numeric_limits<int>::max();
    if (earlier_frames + static_cast<long long>(in.frames.size()) > most) {
      throw IoError(mapping::mapFileStem(o.out) + ".json",
                    "says the map holds " + std::to_string(earlier_frames) + " frames; " + std::to_string(in.frames.size()) +
                        " more would pass the " + std::to_string(most) + " a map counts (is \"frames\" right?)");
    }
    // Where the first run took it from (a map extended before records that first).
    const mapping::MapRun& first_run = *p.existing->meta.runs().front();
    g.source = "the map's first run (" + first_run.gravity_source.value_or("its R_map_world") + ")";
  }
  if (in.isSequence() && !gravity_world && !in.live && !in.oni) {
    const GravityGuess guess = estimateGravity(*in.sequence, in.frames, perception_params, p.model, o.skip_bad_frames);
    gravity_world = guess.down;
    g.source = guess.how;
    char text[400];
    std::snprintf(text, sizeof text, "note: gravity (down) in the world frame (%.3f, %.3f, %.3f), from %s; `gravity` X,Y,Z sets it",
                  guess.down.x(), guess.down.y(), guess.down.z(), guess.how.c_str());
    say(Message::kNote, text);
  }
  // The run's clock starts here: a lone frame without `gravity` is perceived next.
  g.run_start = Clock::now();
  // A single frame is mapped in its camera frame; without `gravity`, "down" is the
  // normal of the ground plane the pipeline finds, else the camera's +y axis. That run
  // measured slopes against the same ground normal, so its result is the frame's.
  // A cloud whose points were turned from its camera's frame is mapped in their frame.
  g.T_world_single = in.single.T_cloud_camera.value_or(Eigen::Isometry3d::Identity());
  if (!in.isSequence() && !gravity_world) {
    g.single_result = perceiveFrame(*p.pipeline, in.single, std::nullopt);
    const perception::FrameResult& r = *g.single_result;
    gravity_world = g.T_world_single.linear() *
                    (r.ground_plane ? Eigen::Vector3d(-r.ground_plane->head<3>().cast<double>()) : Eigen::Vector3d(0, 1, 0));
    const auto extent = groundExtent(r);
    const std::string how = extent ? "; " + describeGround(*extent) : "";
    g.source = !r.ground_plane ? "the camera's +y axis (no ground plane)"
               : r.ground_rule == perception::GroundRule::kUprightPrior
                   ? "the frame's ground plane (a floor within ground_upright_prior_deg of the image's up axis" + how + ")"
                   : "the frame's ground plane (its largest plane" + how + ")";
    if (extent && extent->near_m >= kFarGroundM) {
      char text[600];
      std::snprintf(text, sizeof text,
                    "note: gravity (down) comes from the frame's ground plane, seen only %.1f m from the camera or farther "
                    "(median %.1f m; %s): depth noise grows with the square of the range, so a far floor tilts gravity and "
                    "heights measured above it may be off by centimetres; `gravity` X,Y,Z sets it",
                    extent->near_m, extent->median_m, describeGround(*extent).c_str());
      say(Message::kNote, text);
    }
    const std::string note = groundChoiceNote(r, perception_params.ground_upright_prior_deg);
    if (!note.empty()) say(Message::kNote, note);
  }
  if (!gravity_world) g.source = "-z (default)";
  g.down_world = gravity_world.value_or(Eigen::Vector3d(0, 0, -1));
  g.R_map_world = p.existing ? p.existing->R_map_world : mapping::gravityAlignment(g.down_world);
  return g;
}

// placeMap(): the map's origin, and the camera whose rays clear free space.
struct Placement {
  std::optional<Eigen::Vector3d> origin_world;  // unset: a stream's first posed frame sets it
  std::string origin_source;
  const perception::PinholeIntrinsics* depth_camera = nullptr;
};

Placement placeMap(const BuildOptions& o, const Prepared& p, const Input& in) {
  Placement place;
  if (p.existing) {
    place.origin_world = p.existing->origin_world, place.origin_source = "the map being extended";
  } else if (o.origin) {
    place.origin_world = *o.origin, place.origin_source = "`origin`";
  } else if (!in.isSequence()) {
    place.origin_world = Eigen::Vector3d::Zero(), place.origin_source = "the camera (a single frame)";
  } else if (const auto first = in.sequence->pose(in.frames.front())) {
    place.origin_world = mapping::defaultMapOrigin(first->translation());
    place.origin_source = "the first camera position, rounded to 100 m";
  }
  place.depth_camera = in.isSequence() ? (in.sequence->hasDepth() ? &in.sequence->intrinsics() : nullptr)
                                       : (in.single.depth ? &in.single.intrinsics : nullptr);
  return place;
}

// What the run fused, counted as the frames come (by the reading thread and the
// fusion thread, under `lock`).
struct Fused {
  std::mutex lock;
  int used = 0, no_ground = 0, no_pose = 0, unreadable_in_run = 0;
  int outside_frames = 0, outside_warnings = 0;
  std::size_t points = 0, points_outside = 0, map_nodes = 0;
  int last_fused = 0;
  std::vector<Eigen::Vector3d> trajectory;  // camera positions, map frame
  double read_ms = 0, fuse_ms = 0;
  std::vector<std::pair<std::string, double>> stage_ms;  // in pipeline order
  struct Pushed {
    int number;
    Eigen::Isometry3d T_world_camera;
    std::optional<LowZeroBits> bits;  // of its stored depth values, for the unit check
  };
  std::vector<Pushed> pushed;  // by LiveMapper's frame index
  DepthCheckTally depth_checks;
  std::exception_ptr checkpoint_error;
  bool interrupted = false;
  std::shared_ptr<const mapping::MobilityMap> final_map;
  [[nodiscard]] int done() const { return used + no_pose + unreadable_in_run + outside_frames; }
};

// Writes the map's four files (all or none) and returns what MAP.json says.
mapping::MapMetadata writeMap(const BuildOptions& o, const Prepared& p, const Input& in, const Gravity& g,
                              const Placement& place, const Fused& f, const mapping::MobilityMap& map, bool checkpoint,
                              double run_s) {
  const perception::PerceptionParams& pp = p.config.perception;
  const mapping::MapParams& mp = p.config.mapping;
  mapping::MapRun run;
  run.format = "mobmap-map-metadata";
  run.tool = std::string("mobmap ") + MOBMAP_VERSION_STRING;
  run.tree_type = mapping::MobilityOcTree::kTreeType;
  run.input = in.live ? in.device_label : absolutePath(o.input);
  run.frames_in_run = f.used;
  run.frames_selected = static_cast<long long>(in.frames.size()) + static_cast<long long>(in.unreadable_before_run);
  if (in.keyframes_considered > 0) {
    run.keyframes = mapping::KeyframeRecord{o.keyframes->first, o.keyframes->second, in.keyframes_considered};
  }
  if (in.isSequence() && !in.sequence->skipped().empty()) run.skipped = in.sequence->skipped();
  // How this run read its frames, so `overlay` can read them again the same way.
  if (const perception::PinholeIntrinsics* k = place.depth_camera) {
    run.depth_intrinsics = mapping::DepthCameraRecord{k->fx, k->fy, k->cx, k->cy, k->width, k->height};
  }
  if (!o.poses.empty()) run.poses = absolutePath(o.poses);
  run.max_pose_gap_s = o.max_pose_gap_s;
  if (in.T_base_camera) run.extrinsics = sources::extrinsicsText(*in.T_base_camera);
  if (const sources::Recording* rec = in.isSequence() ? in.sequence->recording() : nullptr) {
    run.depth_topic = rec->depthTopic();
    if (!rec->cameraInfoTopic().empty()) run.camera_info_topic = rec->cameraInfoTopic();
    if (!rec->worldFrame().empty()) run.world_frame = rec->worldFrame();
    if (!rec->recovered().empty()) run.recovered = rec->recovered();
  }
  if (f.no_pose > 0) run.frames_without_pose = f.no_pose;
  run.unreadable = in.unreadable;
  run.frame_numbers = std::array<long long, 2>{in.frames.front(), f.last_fused};
  run.interrupted = f.interrupted;
  run.resolution_m = map.tree().getResolution();
  run.gravity_down_world = g.down_world;
  run.gravity_source = g.source;
  if (g.given) run.gravity_given_world = *g.given;
  if (g.floor_angle_deg) run.gravity_floor_angle_deg = *g.floor_angle_deg;
  run.R_map_world = g.R_map_world;
  run.origin_world = map.originWorld();
  run.origin_source = place.origin_source.empty() ? std::string("none") : place.origin_source;
  if (f.points_outside > 0) {
    run.points_outside_map = static_cast<long long>(f.points_outside);
    run.frames_outside_map = f.outside_frames;
  }
  run.seconds = run_s;
  run.frames_per_second = run_s > 0 ? (f.used + f.no_pose) / run_s : 0.0;
  if (checkpoint) run.checkpoint = true;
  // The configuration's values that `voxel_size_m` rescales are recorded with the rest.
  run.perception = mapping::PerceptionRecord{pp.max_range_m, pp.voxel_size_m, pp.normal_k, pp.outlier_k, pp.colour_threshold,
                                             pp.min_segment_points, pp.ground_min_points, pp.neighbour_distance_m,
                                             pp.max_triangle_edge_m, pp.rough_fragment_max_points, pp.rough_min_points,
                                             pp.rough_smoothing_k};
  run.mapping = mapping::MappingRecord{mp.resolution_m, mp.max_range_m, mp.free_space_ray_stride_px, mp.max_weight, o.free_space};
  run.model = mapping::ModelRecord{p.config.model.model == gp::ModelKind::kGaussianProcess ? "gp" : "rule",
                                   p.config.table_path.empty() ? "paper" : p.config.table_path, p.config.model.signal_std,
                                   p.config.model.length_scale, p.config.model.noise_std};
  if (!o.config.empty()) run.config = absolutePath(o.config);
  run.points_in_view = static_cast<long long>(f.depth_checks.validPoints());
  run.points_beyond_range = static_cast<long long>(f.depth_checks.beyondMaxRange());
  run.depth_units_per_m = in.depthUnit().units_per_m;
  if (!o.depth_format.empty()) run.depth_format = o.depth_format;
  mapping::MapMetadata meta;
  if (p.existing) {
    meta = p.existing->meta;
    meta.addRun(std::move(run), f.trajectory);
  } else {
    meta.frames = f.used;
    meta.latest = std::move(run);
    meta.trajectory_map = f.trajectory;
  }
  // All four or none: a disk that fills up while they are written leaves the map on disk
  // as it was (an extended map included), not a new .ot beside an old .json.
  const mapping::MobilityOcTree& tree = map.tree();
  const std::string meta_text = mapping::formatMapMetadata(meta);
  writeFilesTogether({{p.paths[0], [&](const std::string& tmp) { mapping::saveMobilityMap(tree, tmp); }},
                      {p.paths[1], [&](const std::string& tmp) { mapping::saveOccupancyBt(tree, tmp); }},
                      {p.paths[2], [&](const std::string& tmp) { mapping::saveOctovisColorTree(tree, tmp); }},
                      {p.paths[3], [&](const std::string& tmp) { writeTextFileAtomically(tmp, meta_text); }}});
  return meta;
}

// runFrames(): every frame read, perceived and fused; checkpoints. The depth unit the
// frames were read in is the input's.
void runFrames(const BuildOptions& o, Prepared& p, Input& in, Gravity& g, Placement& place, Fused& f,
               const BuildHooks& hooks, const Say& say) {
  const sources::DepthUnit depth_unit = in.depthUnit();
  const int total = static_cast<int>(in.frames.size());
  const int frames_before = p.existing ? p.existing->meta.frames : 0;
  f.last_fused = in.frames.front();
  const auto progress = [&] {
    if (hooks.progress) hooks.progress(f.done(), total, f.map_nodes, g.run_start);
  };
  const auto checkpointDue = [&] {
    return o.checkpoint_frames > 0 && f.used % o.checkpoint_frames == 0 && f.done() < total;
  };
  mapping::LiveMapper* mapper_ptr = nullptr;
  const auto frameDone = [&] {
    if (hooks.frame_done) hooks.frame_done(f.used);
    if (say.stopped()) mapper_ptr->cancel();
  };
  // Perception on the perception threads (each keeps its pipeline buffers from frame to
  // frame), fusion in order on another: mapping::LiveMapper.
  mapping::LiveMapper::Config live_config;
  live_config.map = p.config.mapping;
  live_config.perception = p.config.perception;
  live_config.model = p.model;
  live_config.gravity_down_world = g.down_world;
  live_config.origin_world = place.origin_world;
  live_config.perception_threads = o.perception_threads;
  live_config.queue_capacity = 2;
  // Fusion gets the depth images only to clear what a frame sees through (and cast
  // free-space rays): free_space off withholds them.
  live_config.clear_free_space = o.free_space;
  // Unless someone queries the map during the run, each frame is fused once.
  live_config.serve_snapshots = static_cast<bool>(hooks.fused);
  live_config.on_frame = [&](const mapping::FrameReport& r) {
    const std::lock_guard<std::mutex> lock(f.lock);
    if (!r.fused) return;  // perception threw; the frames were checked when read
    const Fused::Pushed& pushed = f.pushed[r.index];
    const std::shared_ptr<const mapping::MobilityMap> latest = mapper_ptr->snapshot();
    f.map_nodes = latest->tree().size();
    if (!place.origin_world) {  // a stream: its first posed frame set the origin
      place.origin_world = latest->originWorld();
      place.origin_source = "the first camera position, rounded to 100 m";
    }
    f.fuse_ms += r.fusion_ms;
    // Depth in another unit, or a range that cuts away most of the frame or its floor.
    for (const std::string& w : f.depth_checks.add("frame " + std::to_string(pushed.number), r.range,
                                                   r.ground_found ? std::optional<double>(r.ground_distance_m) : std::nullopt,
                                                   depth_unit, pushed.bits)) {
      say(w.rfind("warning", 0) == 0 ? Message::kWarning : Message::kNote, w);
    }
    const mapping::IntegrationReport& fused = r.integration;
    if (fused.points_outside_map > 0) {
      f.points_outside += fused.points_outside_map;
      constexpr int kListed = 10;
      if (++f.outside_warnings <= kListed) {
        say(Message::kWarning, "warning: frame " + std::to_string(pushed.number) + ": " +
                                   std::to_string(fused.points_outside_map) + " of " +
                                   std::to_string(fused.points_outside_map + fused.points_fused) +
                                   " points in range lie outside the map's extent (" + describeExtent(*latest) +
                                   ") and were left out" + (fused.points_fused == 0 ? ": the frame adds nothing" : ""));
      } else if (f.outside_warnings == kListed + 1) {
        say(Message::kWarning, "warning: more frames reach outside the map's extent; the summary counts them");
      }
      if (fused.points_fused == 0) {
        ++f.outside_frames;
        progress();
        return;
      }
    }
    for (const auto& st : r.stages) {
      auto it = std::find_if(f.stage_ms.begin(), f.stage_ms.end(), [&](const auto& e) { return e.first == st.name; });
      if (it == f.stage_ms.end()) it = f.stage_ms.insert(f.stage_ms.end(), {st.name, 0.0});
      it->second += st.milliseconds;
    }
    const Eigen::Vector3d c = latest->worldToMap(pushed.T_world_camera.translation());
    f.trajectory.push_back({c.x(), c.y(), c.z()});
    f.points += r.points;
    f.no_ground += !r.ground_found;
    ++f.used;
    f.last_fused = pushed.number;
    if (hooks.fused) hooks.fused(latest, frames_before + f.used, c);
    progress();
    if (!checkpointDue()) frameDone();
  };
  live_config.finalize_after = [&](const mapping::FrameReport& r) {
    const std::lock_guard<std::mutex> lock(f.lock);
    return r.integration.points_fused > 0 && checkpointDue();
  };
  live_config.on_finalized = [&](const mapping::MobilityMap& checkpoint_map, const mapping::FrameReport&) {
    const std::lock_guard<std::mutex> lock(f.lock);
    try {
      writeMap(o, p, in, g, place, f, checkpoint_map, true,
               std::chrono::duration<double>(Clock::now() - g.run_start).count());
    } catch (...) {  // reported by the reading thread, which stops the run
      if (!f.checkpoint_error) f.checkpoint_error = std::current_exception();
      mapper_ptr->cancel();
    }
    frameDone();
  };
  std::unique_ptr<mapping::LiveMapper> mapper =
      p.existing ? std::make_unique<mapping::LiveMapper>(live_config, std::move(p.existing->tree), g.R_map_world, *place.origin_world)
                 : std::make_unique<mapping::LiveMapper>(live_config);
  mapper_ptr = mapper.get();
  if (hooks.started) hooks.started(*mapper, frames_before);
  // Read each frame and hand it over; push() waits while the queue is full.
  for (const int number : in.frames) {
    if (hooks.before_frame) hooks.before_frame();
    if (say.stopped()) break;
    const auto t0 = Clock::now();
    if (!in.isSequence()) {
      mapping::PerceivedFrame frame;
      if (g.single_result) {
        frame.result = std::move(*g.single_result);
      } else {
        frame.result = perceiveFrame(*p.pipeline, in.single, (g.T_world_single.linear().transpose() * g.down_world).cast<float>());
      }
      frame.T_world_camera = g.T_world_single;
      if (in.single.depth) frame.depth = *in.single.depth;  // free space by projection, as for a sequence
      frame.intrinsics = in.single.intrinsics;
      {
        const std::lock_guard<std::mutex> lock(f.lock);
        f.pushed.push_back({number, g.T_world_single, in.single.depth ? lowZeroBits(*in.single.depth, depth_unit) : std::nullopt});
      }
      mapper->push(std::move(frame));
      continue;
    }
    const Sequence& input = *in.sequence;
    Frame frame;
    try {
      frame = input.load(number);
    } catch (const sources::StreamInterrupted&) {  // stopped while a live sensor was silent
      break;
    } catch (const IoError& e) {  // a frame that passed check() but cannot be decoded
      if (in.live || in.oni) throw;
      if (!o.skip_bad_frames) throw withSkipHint(e);
      const std::lock_guard<std::mutex> lock(f.lock);
      noteUnreadable(in.unreadable, e.what(), say);
      ++f.unreadable_in_run;
      progress();
      continue;
    }
    if (!frame.T_world_camera) {
      const std::lock_guard<std::mutex> lock(f.lock);
      ++f.no_pose;
      progress();
      continue;
    }
    std::optional<LowZeroBits> bits = frame.depth ? lowZeroBits(*frame.depth, depth_unit) : std::nullopt;
    {
      const std::lock_guard<std::mutex> lock(f.lock);
      f.read_ms += std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
      f.pushed.push_back({number, *frame.T_world_camera, bits});
    }
    try {
      // A frame the gravity check perceived, with the hint LiveMapper would give it (else
      // it is perceived again).
      std::optional<perception::FrameResult> early;
      if (const auto it = g.perceived_for_run.results.find(number); it != g.perceived_for_run.results.end()) {
        if (it->second.gravity_down_camera == (frame.T_world_camera->linear().transpose() * g.down_world.normalized()).cast<float>()) {
          early = std::move(it->second.result);
        }
        g.perceived_for_run.results.erase(it);
      }
      if (early) {
        mapper->push(mapping::PerceivedFrame{std::move(*early), std::move(*frame.depth), input.intrinsics(), *frame.T_world_camera, 0.0});
      } else if (input.hasDepth()) {
        mapper->push(mapping::DepthFrame{std::move(*frame.depth), input.intrinsics(), *frame.T_world_camera, 0.0});
      } else {
        mapper->push(mapping::CloudFrame{std::move(frame.points), frame.width, frame.height, *frame.T_world_camera, 0.0});
      }
    } catch (const std::invalid_argument& e) {  // a frame LiveMapper cannot take (image and camera disagree)
      throw IoError(o.input, "frame " + std::to_string(number) + ": " + e.what());
    } catch (const std::logic_error&) {  // the run was cancelled: a failed checkpoint or a stop
      break;
    }
  }
  f.interrupted = say.stopped();
  if (f.interrupted) mapper->cancel();  // the frames not yet fused are left out
  mapper->finish();
  if (f.checkpoint_error) std::rethrow_exception(f.checkpoint_error);
  if (hooks.frames_done) hooks.frames_done();
  f.final_map = mapper->snapshot();
  mapper.reset();  // joins its threads: the counts are final
}

// finish(): refuse a map that would hide a mistake, else write it; the report.
BuildReport finish(const BuildOptions& o, const Prepared& p, const Input& in, const Gravity& g, const Placement& place,
                   Fused& f, const BuildHooks& hooks) {
  // Reading, perception and fusion of every frame, as the user waited for them.
  const double run_s = std::chrono::duration<double>(Clock::now() - g.run_start).count();
  const std::string source = in.live ? in.device_label : o.input;
  const mapping::MobilityMap& map = *f.final_map;
  if (f.used == 0 && f.no_pose > 0 && !f.interrupted) {
    std::ostringstream msg;
    msg << "none of the " << f.no_pose << " frames read has a pose within " << o.max_pose_gap_s
        << " s of its time stamp (are the poses on the sensor's clock, in seconds?); no map written";
    throw IoError(o.poses, msg.str());
  }
  if (f.used == 0 && f.unreadable_in_run > 0 && !f.interrupted) {
    throw IoError(o.input, "no selected frame could be read (" + std::to_string(in.unreadable.size()) +
                               " tried; the first: " + in.unreadable.front() + "); no map written");
  }
  // Most frames outside the map: a map of the few inside would hide the mistake (a stray
  // first pose that placed the map, poses in another unit, a wrong origin).
  if (f.outside_frames > f.used && !f.interrupted) {
    const std::string which = f.used == 0 ? "all " + std::to_string(f.outside_frames)
                                          : std::to_string(f.outside_frames) + " of " + std::to_string(f.outside_frames + f.used);
    throw IoError(source, which + " frames with points in range lie outside the map's extent (" + describeExtent(map) +
                              "); no map written. Are the poses in metres? The map's origin comes from " +
                              place.origin_source + ": `origin` X Y Z centres the map elsewhere, and `frames` leaves out a stray pose");
  }
  BuildReport report;
  report.interrupted = f.interrupted;
  report.out = o.out;
  report.stem = p.stem;
  report.extended = p.existing.has_value();
  if (f.interrupted && f.used == 0) return report;  // nothing to save; a map being extended stays as it was
  if (map.tree().size() == 0 && f.used > 0 && !f.interrupted) {
    // Nothing in range anywhere (a range shorter than the scene, depth in the wrong
    // unit, a sensor facing the sky): an empty map would only hide the mistake.
    const perception::PerceptionParams& pp = p.config.perception;
    std::ostringstream msg;
    msg << "none of the " << f.used << " frames fused ";
    if (f.points == 0) {
      msg << "has a measured point between " << pp.min_range_m << " and " << pp.max_range_m
          << " m of the camera (`max_range_m`)";
    } else {
      msg << "has a surface segment (" << f.points << " points in range, none in a segment of at least "
          << pp.min_segment_points << ")";
    }
    msg << ", so the map would be empty";
    if (o.checkpoint_frames > 0 && f.used >= o.checkpoint_frames) {
      msg << " (the checkpoint at " << o.out << " is)";
    } else {
      msg << "; no map written";
    }
    msg << ". Check the range, the depth unit and the intrinsics";
    if (const auto unit = f.depth_checks.unitProblem()) msg << " (" << *unit << ")";
    throw IoError(source, msg.str());
  }
  if (f.depth_checks.everyFrameInAnotherUnit() && !f.interrupted) {
    // A map of depth read in the wrong unit is not the scene's: say what fits instead.
    std::ostringstream msg;
    msg << "every frame fused reads as depth in another unit (" << *f.depth_checks.unitProblem() << ")";
    msg << (o.checkpoint_frames > 0 && f.used >= o.checkpoint_frames ? "; the checkpoint at " + o.out + " holds them"
                                                                     : "; no map written");
    throw IoError(source, msg.str());
  }
  const mapping::MapMetadata meta = writeMap(o, p, in, g, place, f, map, false, run_s);
  if (!o.fine_surface_ply.empty()) f.final_map->saveFineSurfacePly(o.fine_surface_ply);
  report.rough_voxels = f.final_map->roughVoxels().size();
  if (hooks.saved) hooks.saved(f.final_map, meta);
  report.written = true;
  report.frames_fused = f.used;
  report.frames_selected = static_cast<int>(in.frames.size() + in.unreadable_before_run);
  report.keyframes_considered = in.keyframes_considered;
  report.frames_without_ground = f.no_ground;
  report.frames_without_pose = f.no_pose;
  report.frames_outside_map = f.outside_frames;
  report.points_outside_map = f.points_outside;
  report.map_extent = describeExtent(map);
  report.points = f.points;
  report.map_nodes = map.tree().size();
  report.map_leaves = map.tree().getNumLeafNodes();
  report.seconds = run_s;
  report.frames_per_second = *meta.latest.frames_per_second;
  report.frames_in_map = meta.frames;
  report.runs_in_map = meta.earlier_runs.size() + 1;
  report.depth_check_summary = f.depth_checks.summary();
  report.gravity_given = g.given;
  report.gravity_used = g.down_world;
  report.gravity_source = g.source;
  if (in.live) report.live_skipped = in.sequence->skipped();
  report.unreadable = in.unreadable;
  const int per = std::max(1, f.used);
  report.read_ms = f.used ? f.read_ms / f.used : 0.0;
  report.fusion_ms = f.used ? f.fuse_ms / f.used : 0.0;
  for (const auto& [name, ms] : f.stage_ms) report.stage_ms.emplace_back(name, ms / per);
  return report;
}

}  // namespace

std::string describeKeyframeRule(double min_translation_m, double min_rotation_deg) {
  std::ostringstream out;
  if (min_translation_m > 0) out << "camera moved >= " << min_translation_m << " m";
  if (min_translation_m > 0 && min_rotation_deg > 0) out << " or ";
  if (min_rotation_deg > 0) out << (min_translation_m > 0 ? "" : "camera ") << "turned >= " << min_rotation_deg << " degrees";
  return out.str();
}

BuildReport buildMap(const BuildOptions& options, const BuildHooks& hooks) {
  const Say say{hooks};
  Prepared prepared = prepare(options);
  Input input = openInput(options, say);
  Gravity gravity = settleGravity(options, prepared, input, say);
  Placement placement = placeMap(options, prepared, input);
  Fused fused;
  runFrames(options, prepared, input, gravity, placement, fused, hooks, say);
  return finish(options, prepared, input, gravity, placement, fused, hooks);
}

}  // namespace mobmap::builder
