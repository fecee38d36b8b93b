// `mobmap build`'s run: the frames read, perceived and fused with checkpoints, the map
// written, the result checked and summarised (BuildRun, build_run.hpp).
#include "io/cli_text.hpp"
#include "commands/build_run.hpp"

#include "io/extrinsics.hpp"
#include "io/files.hpp"
#include "io/io_error.hpp"
#include "io/map_files.hpp"
#include "mobmap/sources/openni.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <thread>

namespace mobmap::app::build {
namespace fs = std::filesystem;
namespace {

std::string describeExtent(const mapping::MobilityMap& m) {
  char text[160];
  const Eigen::Vector3d& c = m.originWorld();
  std::snprintf(text, sizeof text, "+-%.0f m around its origin (%.1f, %.1f, %.1f) in the world frame", m.extentM(),
                c.x(), c.y(), c.z());
  return std::string(text);
}

}  // namespace

bool BuildRun::checkpointDue() const {
  return o->checkpoint > 0 && used % o->checkpoint == 0 && done() < static_cast<int>(frames.size());
}

void BuildRun::holdIfAsked() {
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
}

mapping::MapMetadata BuildRun::writeMap(const mapping::MobilityMap& map, bool checkpoint, double run_s) {
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
    if (!rec->recovered().empty()) run.recovered = rec->recovered();
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
}

void BuildRun::runFrames() {
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
        f.result = perceiveFrame(*pipeline, single, (T_world_single.linear().transpose() * g_world).cast<float>());
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
  final_map = mapper->snapshot();
  mapper.reset();  // joins its threads: the counts are final
}

int BuildRun::finish() {
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
  if (live && !dir->skipped().empty()) std::printf("%s\n", cliText(dir->skipped()).c_str());
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

}  // namespace mobmap::app::build
