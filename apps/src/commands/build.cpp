#include "commands/commands.hpp"
#include "io/config.hpp"
#include "io/dataset.hpp"
#include "io/files.hpp"
#include "io/frame_source.hpp"
#include "io/io_error.hpp"
#include "io/map_files.hpp"
#include "io/openni_source.hpp"
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

namespace mobmap::app {
namespace {

std::atomic<bool> g_interrupted{false};
extern "C" void onSigint(int) { g_interrupted.store(true); }

// The error of a frame that cannot be read, when the run stops for it: it says how not to.
IoError withSkipHint(const IoError& e) {
  return IoError(e.path(), e.reason() + " (build --skip-bad-frames leaves such frames out)");
}

struct FrameRange {
  int first = 0, last = -1, step = 1;
};

FrameRange parseRange(const std::string& spec) {
  FrameRange r;
  if (spec.empty()) return r;
  std::vector<std::string> parts;
  std::stringstream in(spec);
  std::string part;
  while (std::getline(in, part, ':')) parts.push_back(part);
  try {
    if (parts.size() >= 1 && !parts[0].empty()) r.first = std::stoi(parts[0]);
    if (parts.size() >= 2 && !parts[1].empty()) r.last = std::stoi(parts[1]);
    if (parts.size() >= 3 && !parts[2].empty()) r.step = std::stoi(parts[2]);
  } catch (const std::exception&) {
    throw UsageError("--frames must be FIRST:LAST:STEP, got '" + spec + "'");
  }
  if (parts.empty() || parts.size() > 3 || r.first < 0 || r.step < 1 || (r.last >= 0 && r.last < r.first)) {
    throw UsageError("--frames must be FIRST:LAST:STEP with 0 <= FIRST <= LAST and STEP >= 1, got '" + spec + "'");
  }
  return r;
}


perception::FrameResult perceive(const perception::FramePipeline& pipeline, const Sequence& dir, const Frame& f,
                                 const std::optional<Eigen::Vector3f>& gravity_down_camera) {
  if (dir.hasDepth()) return pipeline.process(*f.depth, dir.intrinsics(), gravity_down_camera);
  if (f.height > 1 && f.points.size() == static_cast<std::size_t>(f.width) * static_cast<std::size_t>(f.height)) {
    return pipeline.processOrganized(f.points, f.width, f.height, gravity_down_camera);
  }
  return pipeline.process(f.points, gravity_down_camera);
}

// A frame's floor as a vote for "down" in the world frame: its ground plane's normal
// turned by the camera's rotation r_wc, weighted by the plane's points. None without one.
std::optional<mapping::DownObservation> floorVote(const perception::FrameResult& r, const Eigen::Matrix3d& r_wc) {
  if (!r.ground_plane) return std::nullopt;
  double weight = 0.0;
  for (const auto& s : r.segments) weight += s.is_ground ? static_cast<double>(s.points.size()) : 0.0;
  return mapping::DownObservation{r_wc * -r.ground_plane->head<3>().cast<double>(), std::max(1.0, weight)};
}

// Up to 8 posed frames spread over the selection, each perceived by `finder` with the
// camera-frame gravity `down_in_camera(r_wc)` gives: their floors' votes, and the
// rotations of the posed frames sampled. An unreadable frame is skipped with
// --skip-bad-frames (the run skips it too, and says so), else its error stops the run.
struct FloorSample {
  std::vector<mapping::DownObservation> floors;
  std::vector<Eigen::Matrix3d> rotations;
};
FloorSample sampleFloors(const Sequence& dir, const std::vector<int>& frames, const perception::FramePipeline& finder,
                         const std::function<Eigen::Vector3f(const Eigen::Matrix3d&)>& down_in_camera, bool skip_unreadable) {
  FloorSample sample;
  const std::size_t samples = std::min<std::size_t>(8, frames.size());
  for (std::size_t i = 0; i < samples; ++i) {
    const std::size_t at = samples == 1 ? 0 : i * (frames.size() - 1) / (samples - 1);
    Frame f;
    try {
      f = dir.load(frames[at]);
    } catch (const IoError& e) {
      if (!skip_unreadable) throw withSkipHint(e);
      continue;
    }
    if (!f.T_world_camera) continue;
    const Eigen::Matrix3d r_wc = f.T_world_camera->linear();
    sample.rotations.push_back(r_wc);
    if (auto vote = floorVote(perceive(finder, dir, f, down_in_camera(r_wc)), r_wc)) sample.floors.push_back(*vote);
  }
  return sample;
}

struct GravityGuess {
  Eigen::Vector3d down;
  std::string how;  // for the note and MAP.json
};

// "Down" for a posed sequence that does not give it (no gravity-direction.txt, no
// --gravity). World frames differ: 7-Scenes and 3DMatch keep the first camera's axes
// (y down), a motion-capture frame has z up. The floor says which: up to 8 frames
// spread over the selection look for a ground plane within 45 degrees of the image's
// up axis (a camera held upright, tilted at most that much), and the floor normals,
// taken to the world frame, vote. Without a floor in view, the cameras' mean +y axis.
GravityGuess estimateGravity(const Sequence& dir, const std::vector<int>& frames, const perception::PerceptionParams& pp,
                             const gp::MobilityModel& model, bool skip_unreadable) {
  perception::PerceptionParams p = pp;
  p.ground_max_tilt_deg = 45.0;
  const FloorSample sample = sampleFloors(
      dir, frames, perception::FramePipeline(p, model), [](const Eigen::Matrix3d&) { return Eigen::Vector3f(0, 1, 0); },
      skip_unreadable);
  const std::size_t posed = sample.rotations.size();
  Eigen::Vector3d camera_y_sum = Eigen::Vector3d::Zero();
  for (const Eigen::Matrix3d& r_wc : sample.rotations) camera_y_sum += r_wc.col(1);
  const auto vote = mapping::consensusDown(sample.floors, 5.0);
  std::ostringstream how;
  how.precision(2);
  if (vote && vote->weight_share >= 0.5) {
    how << "the floor in " << vote->agreeing << " of " << posed << " sampled frames (within " << std::fixed
        << vote->spread_deg << " degrees of each other)";
    return {vote->down, how.str()};
  }
  if (camera_y_sum.norm() > 1e-6) {
    how << "the cameras' mean +y axis (no floor agreed on in " << posed << " sampled frames)";
    return {camera_y_sum.normalized(), how.str()};
  }
  return {Eigen::Vector3d(0, 0, -1), "-z (no posed frame sampled)"};
}

// Gravity is refined to the floor within this cone of the given direction, when the
// two differ by more than kGravityAgreesDeg: closer, the given one is kept (on exact
// synthetic floors the vote of 8 frames lies ~0.15 degrees from the truth; on the real
// kitchen floor normals spread over ~0.5 degrees).
constexpr double kGravityRefineConeDeg = 10.0;
constexpr double kGravityAgreesDeg = 1.0;

// The floor near a given "down": up to 8 frames spread over the selection (or the lone
// frame) look for a ground plane within kGravityRefineConeDeg of it; the floor normals,
// in the world frame, vote as in estimateGravity. Nullopt when no floor agreed on.
struct FloorCheck {
  mapping::DownConsensus vote;
  std::size_t sampled = 0;
};
std::optional<FloorCheck> floorNear(const Eigen::Vector3d& given_down, const Sequence* dir, const std::vector<int>& frames,
                                    const Frame* single, const perception::PerceptionParams& pp,
                                    const gp::MobilityModel& model, bool skip_unreadable) {
  perception::PerceptionParams p = pp;
  p.ground_max_tilt_deg = kGravityRefineConeDeg;
  const perception::FramePipeline finder(p, model);
  const auto down_in_camera = [&](const Eigen::Matrix3d& r_wc) { return Eigen::Vector3f((r_wc.transpose() * given_down).cast<float>()); };
  FloorSample sample;
  if (single) {  // its world frame is its points' frame (the camera's, or the cloud's it was turned from)
    const Eigen::Matrix3d r_wc = single->T_cloud_camera.value_or(Eigen::Isometry3d::Identity()).linear();
    sample.rotations.push_back(r_wc);
    if (auto vote = floorVote(perceiveFrame(finder, *single, down_in_camera(r_wc)), r_wc)) sample.floors.push_back(*vote);
  } else {
    sample = sampleFloors(*dir, frames, finder, down_in_camera, skip_unreadable);
  }
  const auto vote = mapping::consensusDown(sample.floors, 5.0);
  if (!vote || vote->weight_share < 0.5) return std::nullopt;
  return FloorCheck{*vote, sample.rotations.size()};
}

// The map that --extend adds frames to: its tree, its metadata, and the frame it was
// built in (gravity in the input's world frame and the rotation to the map frame).
struct ExistingMap {
  std::unique_ptr<mapping::MobilityOcTree> tree;
  mapping::MapMetadata meta;
  Eigen::Vector3d down_world;
  Eigen::Matrix3d R_map_world;
  Eigen::Vector3d origin_world;
};

ExistingMap openForExtension(const std::string& ot_path) {
  ExistingMap m;
  m.tree = mapping::loadMobilityMap(ot_path);
  m.meta = mapping::readMapMetadata(ot_path);  // the earlier runs' records, for the new MAP.json
  m.origin_world = m.meta.originWorld();  // zero for a map from before origins were recorded
  if (!m.meta.hasFrame()) {
    throw IoError(m.meta.path, "missing, or without \"R_map_world\": --extend needs the metadata written beside the map "
                               "(the rotation from the input's world frame to the map frame)");
  }
  m.R_map_world = m.meta.R_map_world();
  m.down_world = m.R_map_world.transpose() * Eigen::Vector3d(0, 0, -1);
  // The recorded gravity gives the first run's rotation bit for bit (the matrix printed
  // in MAP.json goes through nearestRotation when read): then both are taken from it.
  if (const auto g = m.meta.gravityDownWorld()) {
    const Eigen::Matrix3d r = mapping::gravityAlignment(*g);
    if ((r - m.R_map_world).cwiseAbs().maxCoeff() < 1e-9) {
      m.R_map_world = r;
      m.down_world = *g;
    }
  }
  return m;
}

double angleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

std::string formatVector(const Eigen::Vector3d& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.3f, %.3f, %.3f)", v.x(), v.y(), v.z());
  return buf;
}

// The runs of an extended map that fused frames from the same input in the range
// selected now: (run number from 1, first and last frame it fused). Fusing a frame
// again counts it twice.
struct RunRange {
  std::size_t run = 0;
  long long first = 0, last = 0;
};
std::vector<RunRange> overlappingRuns(const mapping::MapMetadata& earlier, const std::string& input, int first, int last) {
  const std::vector<const mapping::MapRun*> runs = earlier.runs();
  std::vector<RunRange> out;
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const mapping::MapRun& r = *runs[i];
    if (r.input != input || !r.frame_numbers) continue;
    const RunRange range{i + 1, (*r.frame_numbers)[0], (*r.frame_numbers)[1]};
    if (range.first <= last && first <= range.last) out.push_back(range);
  }
  return out;
}

}  // namespace

Command addBuildCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("build", "Build a mobility map from a sequence of posed depth frames");
  struct Options {
    std::string input;
    std::string out;
    std::string frames;
    double max_range = 3.0;
    double depth_scale = 0;
    double resolution = 0.02;
    double voxel = 0;
    std::string gravity;
    std::string gravity_refine = "on";
    std::vector<double> origin;
    bool force = false;
    bool extend = false;
    int checkpoint = 0;
    std::vector<double> keyframes;  // metres, degrees
    bool quiet = false;
    bool no_free_space = false;
    bool skip_bad_frames = false;
    std::string config;
    std::string intrinsics;
    double fov = 0;
    double max_pose_gap = 0.05;
    std::string poses;
    std::string device;
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("INPUT", o->input,
                  "A 7-Scenes / 3DMatch layout directory (frame-NNNNNN.depth.png + .pose.txt), a TUM RGB-D directory "
                  "(depth.txt + groundtruth.txt), a directory of .pcd frames with --poses, one .pcd frame, one 16-bit "
                  "depth .png in millimetres (with --intrinsics or a camera-intrinsics.txt beside it), or an OpenNI2 .oni recording");
  auto* device = cmd->add_option("--device", o->device,
                                 "Read a live OpenNI2 depth sensor instead of INPUT: the first attached one, or the "
                                 "given device URI. Stops after --frames LAST (default 300 frames) or Ctrl-C")
                     ->expected(0, 1);
  auto* intrinsics = cmd->add_option("--intrinsics", o->intrinsics, kIntrinsicsHelp);
  auto* fov = cmd->add_option("--fov", o->fov, kFovHelp)->excludes(intrinsics);
  cmd->add_option("--poses", o->poses,
                  "Trajectory, TUM format 't tx ty tz qx qy qz qw' (camera to world). For .pcd frames: one line per "
                  "frame in file-name order, or timestamped and matched to time stamps in the file names. For .oni "
                  "and --device: matched to the frames' time stamps (seconds of the device clock); without it the "
                  "camera is taken as static");
  cmd->add_option("--max-pose-gap", o->max_pose_gap, "TUM / timestamped --poses: skip frames whose neighbouring poses are farther apart in time (s)")
      ->check(finiteNonNegative())
      ->capture_default_str();
  cmd->add_option("--out", o->out, "Map file to write (MAP.ot; MAP.bt, MAP.octovis.ot and MAP.json go beside it)")->required();
  cmd->add_option("--frames", o->frames, "FIRST:LAST:STEP of the frame numbers to use (default: all; a live sensor: 0:299; OpenNI2 frames are numbered as they arrive)");
  auto* max_range = cmd->add_option("--max-range", o->max_range, "Maximum range of points, metres")->capture_default_str();
  auto* resolution = cmd->add_option("--resolution", o->resolution, "Voxel size of the map, metres")->capture_default_str();
  cmd->add_option("--config", o->config, "YAML file with any of the parameters of `mobmap config --print-default`");
  auto* voxel = cmd->add_option("--voxel", o->voxel, kVoxelHelp);
  auto* depth_scale = cmd->add_option("--depth-scale", o->depth_scale, kDepthScaleHelp)->check(CLI::PositiveNumber);
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
  auto* origin = cmd->add_option("--origin", o->origin,
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
  auto* keyframes = cmd->add_option("--keyframes", o->keyframes,
                                    "METRES,DEGREES: fuse only frames whose camera has moved at least METRES or turned "
                                    "at least DEGREES since the last frame fused (0 turns a test off), e.g. 0.05,5; the "
                                    "first selected frame is always fused. For sequences with their poses in files "
                                    "(7-Scenes, TUM, .pcd frames with --poses)")
                        ->delimiter(',')
                        ->expected(2);
  cmd->add_flag("--no-free-space", o->no_free_space, "Skip free-space updates: neither clear voxels a frame sees through nor cast free-space rays (faster; obstacles that moved stay in the map)");
  cmd->add_flag("--skip-bad-frames", o->skip_bad_frames,
                "Leave out, with a warning naming the file, a frame that cannot be read (a depth image that is "
                "corrupt or cut short, a pose file that is missing or not a rigid transform, an unreadable .pcd) "
                "instead of stopping the run; the summary and MAP.json count them. For sequences of files");
  cmd->add_flag("--quiet,-q", o->quiet, "No progress output");
  return [o, max_range, resolution, device, voxel, keyframes, origin, depth_scale, fov]() {
    if (fov->count() > 0) o->intrinsics = fovSpec(o->fov);
    namespace fs = std::filesystem;
    std::error_code ec;
    if (fs::path(o->out).extension() != ".ot") throw UsageError("--out must end in .ot, got '" + o->out + "'");
    // One writer per map for the whole run: a second build to the same --out (fresh or
    // --extend) fails here at once instead of replacing the first one's frames.
    const mapping::MapLock map_lock(o->out);
    if (origin->count() > 0 && !Eigen::Vector3d(o->origin[0], o->origin[1], o->origin[2]).allFinite()) {
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
    {
      std::vector<NamedPath> inputs{{"the input", o->input}, {"--poses", o->poses}, {"--config", o->config}};
      if (fs::is_regular_file(o->intrinsics, ec)) inputs.push_back({"--intrinsics", o->intrinsics});
      refuseToOverwriteInputs({{"--out", map_paths[0]}, {"--out's occupancy export", map_paths[1]},
                               {"--out's octovis export", map_paths[2]}, {"--out's metadata", map_paths[3]}},
                              inputs);
    }
    for (const std::string& path : map_paths) checkWritable(path);
    Config config = o->config.empty() ? Config{} : loadConfig(o->config);
    perception::PerceptionParams& pp = config.perception;
    mapping::MapParams& mp = config.mapping;
    if (o->config.empty() || max_range->count() > 0) pp.max_range_m = o->max_range;
    if (o->config.empty() || resolution->count() > 0) mp.resolution_m = o->resolution;
    if (!config.mapping_max_range_set || max_range->count() > 0) mp.max_range_m = pp.max_range_m;
    if (o->no_free_space) mp.free_space_ray_stride_px = 0;
    try {
      if (voxel->count() > 0) pp = perception::scaledToVoxel(pp, o->voxel);
      perception::validate(pp);
      mapping::validate(mp);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
    std::optional<ExistingMap> existing;
    if (o->extend) {
      existing = openForExtension(o->out);
      const double res = existing->tree->getResolution();
      if (resolution->count() > 0 && std::abs(o->resolution - res) > 1e-9) {
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
    const bool live = device->count() > 0;
    const bool oni = !live && fs::path(o->input).extension() == ".oni";
    if (live == !o->input.empty()) throw UsageError("give either INPUT or --device");
    const bool is_dir = live || oni || fs::is_directory(o->input, ec) || !o->poses.empty();
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
      OpenNiOptions on;
      on.uri = live ? o->device : o->input;
      on.is_file = oni;
      on.intrinsics_spec = o->intrinsics;
      on.poses_path = o->poses;
      on.max_pose_gap_s = o->max_pose_gap;
      on.first = range.first, on.last = range.last, on.step = range.step;
      on.interrupted = [] { return g_interrupted.load(); };
      dir = openOpenNi(on);
    }
    if (is_dir) {
      if (!dir) dir = openSequence(o->input, o->intrinsics, o->max_pose_gap, o->poses);
      if (depth_scale->count() > 0) dir = withDepthScale(std::move(dir), o->depth_scale);
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
      if (keyframes->count() > 0) {
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
      if (!dir->skipped().empty()) std::fprintf(stderr, "note: %s\n", dir->skipped().c_str());
      if (keyframes_considered > 0 && !o->quiet) {
        std::fprintf(stderr, "keyframes: %zu of the %d selected frames (%s)\n", frames.size(), keyframes_considered,
                     describeKeyframeRule(o->keyframes[0], o->keyframes[1]).c_str());
      }
    } else {
      single = loadSingleFrame(o->input, -1, o->intrinsics);
      if (!single.note.empty()) std::fprintf(stderr, "note: %s\n", single.note.c_str());
      if (depth_scale->count() > 0) rescaleDepth(single, o->depth_scale);
      frames.push_back(0);
      if (!o->frames.empty()) throw UsageError("--frames needs a directory input");
      if (keyframes->count() > 0) throw UsageError("--keyframes needs a sequence of frames");
    }
    std::string gravity_source;
    if (gravity_world) gravity_source = live || oni ? "the static camera's +y axis" : "gravity-direction.txt";
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
    if (gravity_world && !existing && !live && !oni) {
      gravity_given = gravity_world->normalized();
      const auto floor = floorNear(*gravity_given, is_dir ? dir.get() : nullptr, frames, is_dir ? nullptr : &single, pp,
                                   model, o->skip_bad_frames);
      if (floor) {
        gravity_floor_angle = angleDeg(*gravity_given, floor->vote.down);
        char text[400];
        if (*gravity_floor_angle <= kGravityAgreesDeg) {
          std::snprintf(text, sizeof text, "%s (the floor in %d of %zu sampled frames agrees within %.2f degrees)",
                        gravity_source.c_str(), floor->vote.agreeing, floor->sampled, *gravity_floor_angle);
        } else if (o->gravity_refine == "on") {
          gravity_world = floor->vote.down;
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
      gravity_source = !single_result->ground_plane ? "the camera's +y axis (no ground plane)"
                       : single_result->ground_rule == perception::GroundRule::kUprightPrior
                           ? "the frame's ground plane (a floor within ground_upright_prior_deg of the image's up axis)"
                           : "the frame's ground plane (its largest plane)";
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
    } else if (origin->count() > 0) {
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
    std::signal(SIGINT, onSigint);
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
    int unreadable_in_run = 0;  // frames skipped as unreadable after the run started
    int last_fused = frames.front();  // frame number of the last frame fused
    std::vector<Eigen::Vector3d> trajectory;  // camera positions, map frame
    double read_ms = 0, fuse_ms = 0;
    struct Pushed {
      int number;
      Eigen::Isometry3d T_world_camera;
    };
    std::vector<Pushed> pushed;  // by LiveMapper's frame index
    const auto done = [&] { return used + no_pose + unreadable_in_run + outside_frames; };
    const auto showProgress = [&](std::size_t nodes) { progress.update(done(), "map " + std::to_string(nodes) + " nodes"); };
    // The map files: all written, then renamed into place, MAP.ot first, MAP.json last. A checkpoint
    // (--checkpoint) writes the same files in the middle of the run; fusion then goes on
    // in the finalized (pruned) tree, which gives the same map as without (docs/MAPPING.md).
    const std::string device_label = "OpenNI2 device " + (o->device.empty() ? std::string("(first attached)") : o->device);
    // After the handler is in place: from here Ctrl-C saves the frames fused so far.
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
    live_config.serve_snapshots = false;  // nothing queries the map during the run: fuse each frame once
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
                                                   depth_unit)) {
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
    // Read each frame and hand it over; push() waits while two frames wait for perception.
    for (const int number : frames) {
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
          pushed.push_back({number, T_world_single});
        }
        mapper->push(std::move(f));
        continue;
      }
      Frame f;
      try {
        f = dir->load(number);
      } catch (const StreamInterrupted&) {  // Ctrl-C while a live sensor was silent
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
      {
        const std::lock_guard<std::mutex> lock(state);
        read_ms += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        pushed.push_back({number, *f.T_world_camera});
      }
      try {
        if (dir->hasDepth()) {
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
    std::signal(SIGINT, SIG_DFL);
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
    if (used == 0 && outside_frames > 0 && !g_interrupted.load()) {
      throw IoError(live ? device_label : o->input,
                    "all " + std::to_string(outside_frames) + " frames with points in range lie outside the map's extent (" +
                        describeExtent(*final_map) + "); no map written. Are the poses in metres? --origin X Y Z centres the map");
    }
    if (g_interrupted.load() && used == 0) {
      // Stopped before the first frame was fused: there is nothing to save, and a map
      // being extended stays exactly as it was.
      std::fprintf(stderr, "interrupted before any frame was fused: %s\n",
                   existing ? ("the map at " + o->out + " is unchanged").c_str() : "no map written");
      return 130;
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
    const mapping::MapMetadata meta = writeMap(*final_map, false, run_s);

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
      return 130;
    }
    return 0;
  };
}

}  // namespace mobmap::app
