// `mobmap build`: the command line's front of mobmap::builder::buildMap. It turns the
// flags into the library's options, prints what the run says (its fields as flags) and
// a progress line, stops the run on a signal with the frames fused so far saved, and
// prints the summary.
#include "commands/build_command.hpp"
#include "commands/commands.hpp"
#include "commands/progress.hpp"
#include "io/cli_text.hpp"
#include "io/io_error.hpp"

#include <signal.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <optional>
#include <thread>

namespace mobmap::app {
using namespace build;
namespace {

// Ctrl-C, SIGTERM (a service manager, `kill`) and SIGHUP (a closed terminal or SSH
// session) all end the run the same way: the frames fused so far are saved, and the exit
// code is 128 + the signal's number (130, 143, 129).
std::atomic<bool> g_interrupted{false};
std::atomic<int> g_signal{0};
constexpr int kStopSignals[] = {SIGINT, SIGTERM, SIGHUP};
int interruptedCode() { return 128 + (g_signal.load() ? g_signal.load() : SIGINT); }

extern "C" void onBuildStopSignal(int sig) {
  int none = 0;
  g_signal.compare_exchange_strong(none, sig);  // the first signal names the exit code
  g_interrupted.store(true);
}

// Test hook (docs/RELIABILITY.md): MOBMAP_STOP_AFTER_FRAMES=N stops the process (SIGSTOP)
// once N frames are fused, reported and checkpointed, so a test can signal or kill the run
// at a known frame instead of after a guessed time; a Ctrl-C meanwhile ends the run with
// this frame.
void holdAfter(int frames_fused, int stop_after_frames) {
  if (frames_fused != stop_after_frames) return;
  ::raise(SIGSTOP);
  // A Ctrl-C sent while stopped may be handled by another thread after this one goes on:
  // while it is still pending, wait for its handler, so that the frame the run ends with
  // does not depend on which thread the scheduler runs first.
  sigset_t pending;
  const auto stopPending = [&] {
    if (::sigpending(&pending) != 0) return false;
    for (const int sig : kStopSignals) {
      if (::sigismember(&pending, sig) == 1) return true;
    }
    return false;
  };
  while (stopPending()) std::this_thread::yield();
}

void printSummary(const builder::BuildReport& r, const BuildOptions& o) {
  const std::string keyframe_note =
      r.keyframes_considered > 0 ? ", keyframes of " + std::to_string(r.keyframes_considered) + " selected" : "";
  std::printf("\n%d of %d frames fused (%d without a ground plane%s)%s in %.1f s (%.1f frames/s), %zu points, %zu map nodes (%zu leaves)\n",
              r.frames_fused, r.frames_selected, r.frames_without_ground, keyframe_note.c_str(),
              r.interrupted ? ", INTERRUPTED" : "", r.seconds, r.frames_per_second, r.points, r.map_nodes, r.map_leaves);
  if (r.points_outside_map > 0) {
    std::printf("%zu points lay outside the map's extent (%s) and were left out", r.points_outside_map, r.map_extent.c_str());
    if (r.frames_outside_map > 0) std::printf("; %d frames had no point inside and are not counted as fused", r.frames_outside_map);
    std::printf("\n");
  }
  if (r.extended) std::printf("the map now holds %d frames from %zu runs\n", r.frames_in_map, r.runs_in_map);
  for (const std::string& line : r.depth_check_summary) std::printf("%s\n", cliText(line).c_str());
  if (r.gravity_given) {  // checked against the floor: what was given and what was used
    const Eigen::Vector3d& given = *r.gravity_given;
    const Eigen::Vector3d& used = r.gravity_used;
    std::printf("gravity (down): (%.4f, %.4f, %.4f) given, (%.4f, %.4f, %.4f) used: %s\n", given.x(), given.y(), given.z(),
                used.x(), used.y(), used.z(), cliText(r.gravity_source).c_str());
  }
  if (r.frames_without_pose > 0) {
    std::printf("%d frames skipped: no pose within %g s of their time stamp in %s\n", r.frames_without_pose, o.max_pose_gap,
                o.poses.c_str());
  }
  if (!r.live_skipped.empty()) std::printf("%s\n", cliText(r.live_skipped).c_str());
  if (!r.unreadable.empty()) {
    if (r.unreadable.size() == 1) {
      std::printf("1 frame skipped as unreadable (--skip-bad-frames): %s\n", r.unreadable.front().c_str());
    } else {
      std::printf("%zu frames skipped as unreadable (--skip-bad-frames), the first: %s (MAP.json lists them all)\n",
                  r.unreadable.size(), r.unreadable.front().c_str());
    }
  }
  std::printf("time per frame (ms): read %.1f", r.read_ms);
  for (const auto& [name, ms] : r.stage_ms) std::printf(", %s %.1f", name.c_str(), ms);
  std::printf(", fusion %.1f\n", r.fusion_ms);
  std::printf("wrote %s, %s.bt, %s.octovis.ot (view: octovis %s.octovis.ot), %s.json\n", o.out.c_str(), r.stem.c_str(),
              r.stem.c_str(), r.stem.c_str(), r.stem.c_str());
  if (!o.surface_ply.empty()) {
    std::printf("wrote the fused fine surface to %s (%zu voxels scored as rough ground)\n", o.surface_ply.c_str(),
                r.rough_voxels);
  }
}

}  // namespace

builder::BuildOptions build::toLibrary(const BuildOptions& o) {
  builder::BuildOptions b;
  b.input = o.input;
  if (o.given.device->count() > 0) b.device = o.device;
  b.out = o.out;
  b.frames = o.frames;
  if (o.given.max_range->count() > 0) b.max_range_m = o.max_range;
  if (o.given.resolution->count() > 0) b.resolution_m = o.resolution;
  if (o.given.voxel->count() > 0) b.voxel_size_m = o.voxel;
  if (o.given.depth_scale->count() > 0) b.depth_scale = o.depth_scale;
  b.depth_format = o.depth_format;
  if (o.gravity == "floor") {
    b.gravity_from_floor = true;
  } else if (!o.gravity.empty()) {
    const std::vector<double> v = splitNumbers(o.gravity);
    if (v.size() != 3) throw UsageError("--gravity must be three numbers X,Y,Z or 'floor', got '" + o.gravity + "'");
    b.gravity = Eigen::Vector3d(v[0], v[1], v[2]);
  }
  b.refine_gravity = o.gravity_refine == "on";
  if (o.given.origin->count() > 0) b.origin = Eigen::Vector3d(o.origin[0], o.origin[1], o.origin[2]);
  b.force = o.force;
  b.extend = o.extend;
  b.checkpoint_frames = o.checkpoint;
  if (o.given.keyframes->count() > 0) b.keyframes = std::make_pair(o.keyframes[0], o.keyframes[1]);
  b.free_space = !o.no_free_space;
  b.fine_surface_ply = o.surface_ply;
  b.skip_bad_frames = o.skip_bad_frames;
  b.config = o.config;
  b.intrinsics = o.given.fov->count() > 0 ? fovSpec(o.fov) : o.intrinsics;
  b.max_pose_gap_s = o.max_pose_gap;
  b.poses = o.poses;
  b.recording = o.recording;
  b.extrinsics = o.extrinsics;
  return b;
}

Command addBuildCommand(CLI::App& app) {
  const std::shared_ptr<BuildOptions> o = addBuildOptions(app);
  return [o]() { return runBuild(*o, nullptr); };
}

int build::runBuild(BuildOptions& o, const LiveHooks* live) {
  const builder::BuildOptions options = toLibrary(o);
  // From here a stop signal ends the run as it stands (with what was fused saved), never
  // the process in the middle of it: the frames read before the first is fused are the
  // only ones it can cost.
  for (const int sig : kStopSignals) std::signal(sig, onBuildStopSignal);
  const char* stop_env = std::getenv("MOBMAP_STOP_AFTER_FRAMES");
  const int stop_after_frames = stop_env ? std::atoi(stop_env) : -1;
  std::optional<Progress> progress;
  builder::BuildHooks hooks = live ? *live : builder::BuildHooks{};
  hooks.message = [&o](builder::Message kind, const std::string& line) {
    if (kind == builder::Message::kDetail && o.quiet) return;
    Progress::message(line);
  };
  hooks.progress = [&](int done, int total, std::size_t nodes, std::chrono::steady_clock::time_point start) {
    if (!progress) progress.emplace("build", total, o.quiet, start);
    progress->update(done, "map " + std::to_string(nodes) + " nodes");
  };
  hooks.stop = [] { return g_interrupted.load(); };
  hooks.frame_done = [stop_after_frames](int frames_fused) { holdAfter(frames_fused, stop_after_frames); };
  hooks.frames_done = [] {
    for (const int sig : kStopSignals) std::signal(sig, SIG_DFL);
  };
  if (options.device && !o.quiet) {
    std::fprintf(stderr, "reading OpenNI2 device %s (Ctrl-C stops and saves the map)\n",
                 options.device->empty() ? "(first attached)" : options.device->c_str());
  }
  const builder::BuildReport report = builder::buildMap(options, hooks);
  if (!report.written) {
    // Stopped before the first frame was fused: there is nothing to save, and a map
    // being extended stays exactly as it was.
    std::fprintf(stderr, "interrupted before any frame was fused: %s\n",
                 report.extended ? ("the map at " + o.out + " is unchanged").c_str() : "no map written");
    return interruptedCode();
  }
  printSummary(report, o);
  if (report.interrupted) {
    if (report.extended) {
      std::fprintf(stderr, "interrupted: saved the map with the first %d frames of this run added\n", report.frames_fused);
    } else {
      std::fprintf(stderr, "interrupted: saved the map of the first %d frames\n", report.frames_fused);
    }
    return interruptedCode();
  }
  return 0;
}

}  // namespace mobmap::app
