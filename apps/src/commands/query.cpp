#include "answers/answers.hpp"
#include "commands/commands.hpp"
#include "commands/reach_options.hpp"
#include "commands/recording_info.hpp"
#include "io/cli_text.hpp"
#include "io/io_error.hpp"
#include "io/map_files.hpp"
#include "mobmap/mapping/levels.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <vector>

namespace mobmap::app {
namespace {

// Each answer to a line of standard input leaves at once, so a planner can keep one
// process open and ask a question at a time (a pipe would otherwise hold it).
void flushAnswer() {
  std::cout.flush();
  std::fflush(stdout);
}

// Reads standard input a line at a time: blank lines are skipped, every other line must
// hold exactly `fields.size()` finite numbers (named in `fields`, e.g. "x y z"), which go
// to `answer` with the line's name for errors; each answer is flushed before the next
// line is read.
void answerEachInputLine(const std::string& fields,
                         const std::function<void(const std::vector<double>&, const std::string&)>& answer) {
  const auto n = static_cast<std::size_t>(std::count(fields.begin(), fields.end(), ' ') + 1);
  std::string line;
  int line_no = 0;
  while (std::getline(std::cin, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::istringstream in(line);
    std::vector<double> values(n);
    std::string extra;
    bool ok = true;
    for (double& v : values) ok = ok && static_cast<bool>(in >> v) && std::isfinite(v);
    const std::string where = "standard input line " + std::to_string(line_no);
    if (!ok || (in >> extra)) throw UsageError(where + ": expected '" + fields + "', got '" + line + "'");
    answer(values, where);
    flushAnswer();
  }
}

// The reach line of a point's answer (text).
void printPlace(const mapping::Place* p, double drop) {
  if (!p) {
    std::printf("  reach: no surface within %.3f m below\n", drop);
  } else if (p->reachable) {
    std::printf("  reach: surface top at z = %.3f m, reachable\n", p->top_z);
  } else if (p->standable) {
    std::printf("  reach: surface top at z = %.3f m, can be stood on but not reached\n", p->top_z);
  } else {
    std::printf("  reach: surface top at z = %.3f m, cannot be stood on (no sole the robot can stand on rests on it; "
                "ask with --foot for the reason)\n",
                p->top_z);
  }
}

void printPoint(const mapping::PointQuery& q) {
  std::printf("%-8s voxel (%.3f, %.3f, %.3f) size %.3f m", mapping::toString(q.state), q.centre.x(), q.centre.y(),
              q.centre.z(), q.size_m);
  if (q.has_mobility) {
    std::printf("  mobility %.3f  variance %.4g  observations %d\n", q.mobility, q.variance, q.count);
  } else {
    std::printf("  mobility unknown\n");
  }
}

}  // namespace

Command addQueryCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("query", "Ask a map about points (state, mobility) or about a foot placement");
  struct Options {
    std::string map;
    std::vector<double> xyz;
    std::vector<double> foot;
    bool feet = false;
    double snap = -1;
    std::string frame = "map";
    bool json = false;
    bool reach = false;
    ReachOptions robot;
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("MAP", o->map, "A .ot map written by `mobmap build`")->required();
  cmd->add_option("XYZ", o->xyz, "A point X Y Z (metres); without it, points are read as 'x y z' lines from standard input")->expected(3);
  auto* foot = cmd->add_option("--foot", o->foot, "X Y Z YAW LENGTH WIDTH: a rectangular sole (yaw in radians about +z)")->expected(6);
  cmd->add_flag("--feet", o->feet, "Soles as 'x y z yaw length width' lines from standard input, one answer line each")
      ->excludes(foot);
  cmd->add_option("--snap", o->snap,
                  "Search down along gravity up to this many metres for the supporting surface (points; for soles, "
                  "below Z, default 0.1, and 0.1 above it)")
      ->check(finiteNonNegative());
  cmd->add_option("--input-frame", o->frame, "Frame of the given coordinates: map (gravity aligned) or world (the data's own)")
      ->check(CLI::IsMember({"map", "world"}))->capture_default_str();
  cmd->add_flag("--json", o->json, "One JSON object per answer");
  auto* reach = cmd->add_flag(
      "--reach", o->reach,
      "Also say whether the robot can get there (as `mobmap reach`, with its options below): for a point, the surface "
      "under it (the top of the occupied run at or below it, within --snap or one voxel: is it under a sole the robot "
      "can stand on, and reach?); for a sole, can the robot stand on it, and get there in one step from a reachable "
      "sole?");
  addReachOptions(*cmd, o->robot, "--input-frame");
  for (CLI::Option* opt : o->robot.options) opt->needs(reach);
  return [o]() {
    if (o->reach) resolveReachOptions(o->robot);
    const OpenedMap opened = openMapFiles(o->map);
    const mapping::MapMetadata& metadata = opened.metadata;
    const mapping::MobilityMap& map = opened.map;
    // With --reach: which places the robot can get to, worked out once for every answer.
    std::optional<ReachRun> run;
    if (o->reach) {
      run = runReach(o->robot, map, o->map, o->frame == "world", cameraPath(metadata));
      const mapping::FootPlace& s = run->result.footPlaces()[*run->result.start()];
      std::fprintf(stderr,
                   "note: reach from the surface at (%.2f, %.2f, %.2f) m, map frame (%s rule): %zu of %zu surface voxels "
                   "under soles the robot can stand on are reachable\n",
                   s.x, s.y, s.z, o->robot.rule.c_str(), run->result.reachableCount(), run->result.standableCount());
      const std::string sparse = sparseStartNote(run->result, o->robot);
      if (!sparse.empty()) std::fprintf(stderr, "note: %s\n", sparse.c_str());
    }
    // A sole: X Y Z YAW LENGTH WIDTH. `where` names its source in errors.
    const InputFrame frame = o->frame == "world" ? InputFrame::kWorld : InputFrame::kMap;
    const mapping::Reachability* reach_run = run ? &run->result : nullptr;
    // A sole: X Y Z YAW LENGTH WIDTH. `where` names its source in errors.
    auto answerFoot = [&](const std::vector<double>& s, const std::string& where) {
      FootAnswer a;
      try {
        a = app::answerFoot(map, {s[0], s[1], s[2], s[3], s[4], s[5]}, frame, o->snap, reach_run);
      } catch (const std::invalid_argument& e) {
        throw UsageError(where + ": " + cliText(e));
      }
      if (o->json) {
        std::cout << toJson(a).dump() << "\n";
        return;
      }
      const mapping::FootprintQuery& f = a.footprint;
      const Eigen::Vector3d& under = a.support_point;
      const Eigen::Vector3d& n = a.support_normal;
      std::printf("sole: min mobility %.3f, mean %.3f, known %.0f %% of %d samples, height difference %.3f m", f.min_mobility,
                  f.mean_mobility, 100 * f.known_fraction, f.samples, f.max_height_difference_m);
      if (f.has_support_plane) {
        std::printf("; support plane through (%.3f, %.3f, %.3f), normal (%.3f, %.3f, %.3f), tilt %.1f deg, rms %.3f m\n",
                    under.x(), under.y(), under.z(), n.x(), n.y(), n.z(), f.support_tilt_deg, f.support_rms_m);
      } else {
        std::printf("; no support plane (fewer than 3 supported samples, or all on one line)\n");
      }
      if (a.reach) {
        const mapping::SoleReach& r = *a.reach;
        const mapping::Foothold& fh = r.foothold;
        if (r.reachable) {
          std::printf("  reach: the robot can stand here and get here (support z = %.3f m)\n", fh.z);
        } else if (r.standable) {
          std::printf("  reach: the robot can stand here (support z = %.3f m) but not get here from the start\n", fh.z);
        } else {
          std::printf("  reach: the robot cannot stand here: %s (known surface %.0f %% of the sole, min mobility %.2f, "
                      "tilt %.1f deg, unevenness %.3f m)\n",
                      mapping::toString(fh.problem), 100 * fh.support_fraction, fh.min_mobility, fh.tilt_deg,
                      fh.unevenness_m);
        }
      }
    };
    if (!o->foot.empty()) {
      if (!Eigen::Map<const Eigen::VectorXd>(o->foot.data(), 6).allFinite()) throw UsageError("--foot: values must be finite");
      answerFoot(o->foot, "--foot");
      return 0;
    }
    if (o->feet) {
      if (!o->xyz.empty()) throw UsageError("--feet reads soles from standard input; give no point");
      answerEachInputLine("x y z yaw length width", answerFoot);
      return 0;
    }
    auto answer = [&](const Eigen::Vector3d& p_in) {
      const PointAnswer a = answerPoint(map, p_in, frame, o->snap, reach_run);
      if (o->json) {
        std::cout << toJson(a).dump() << "\n";
        return;
      }
      if (a.outside_map) {
        const Eigen::Vector3d& p = a.query_map;
        const double res = map.tree().getResolution();
        std::printf("outside the map: (%.4g, %.4g, %.4g) lies beyond the +-%.2f m a map of %g m voxels spans around its "
                    "origin (map frame)\n",
                    p.x(), p.y(), p.z(), 32768 * res, res);
      } else if (a.voxel) {
        printPoint(*a.voxel);
      } else {
        const Eigen::Vector3d& p = a.query_map;
        std::printf("no surface within %.3f m below (%.3f, %.3f, %.3f)\n", o->snap, p.x(), p.y(), p.z());
      }
      if (a.with_reach) printPlace(a.place, a.reach_drop_m);
    };
    if (!o->xyz.empty()) {
      if (!Eigen::Vector3d(o->xyz[0], o->xyz[1], o->xyz[2]).allFinite()) throw UsageError("X Y Z: values must be finite");
      answer({o->xyz[0], o->xyz[1], o->xyz[2]});
      return 0;
    }
    answerEachInputLine("x y z", [&](const std::vector<double>& v, const std::string&) { answer({v[0], v[1], v[2]}); });
    return 0;
  };
}

namespace {

// The metadata in a few lines: what the map was built from and how. The whole file
// (with the camera path, one position per frame) is `info --json` or STEM.json.
void printMetadataSummary(const mapping::MapMetadata& meta) {
  const auto frameRange = [](const mapping::MapRun& run) {
    if (!run.frame_numbers) return std::string();
    return " (frames " + std::to_string((*run.frame_numbers)[0]) + ".." + std::to_string((*run.frame_numbers)[1]) + ")";
  };
  const mapping::MapRun& run = meta.latest;
  // A map extended with `build --extend`: the earlier runs first, one line each.
  if (!meta.earlier_runs.empty()) {
    std::printf("built in %zu runs, %d frames in the map:\n", meta.earlier_runs.size() + 1, meta.frames);
    for (std::size_t i = 0; i < meta.earlier_runs.size(); ++i) {
      const mapping::MapRun& r = meta.earlier_runs[i];
      std::printf("  run %zu: %s", i + 1, r.input.value_or("an unrecorded input").c_str());
      if (r.frames_in_run) std::printf(", %d frames fused", *r.frames_in_run);
      if (r.keyframes) std::printf(" (keyframes of %lld)", r.keyframes->frames_considered);
      std::printf("%s", frameRange(r).c_str());
      if (r.interrupted) std::printf(", INTERRUPTED");
      if (r.checkpoint.value_or(false)) std::printf(", ended at a checkpoint (the run did not finish)");
      std::printf("\n");
    }
    std::printf("  run %zu (latest): ", meta.earlier_runs.size() + 1);
  }
  std::printf("built by %s from %s\n", run.tool.value_or("an unknown tool").c_str(), run.input.value_or("an unrecorded input").c_str());
  // This run's frames (all of the map's unless it was extended).
  std::printf("frames: %d fused", run.frames_in_run.value_or(meta.frames));
  if (run.frames_selected) std::printf(" of %lld selected", *run.frames_selected);
  if (run.keyframes) {
    const std::string rule = describeKeyframeRule(run.keyframes->min_translation_m, run.keyframes->min_rotation_deg);
    std::printf(" (keyframes of %lld%s%s)", run.keyframes->frames_considered, rule.empty() ? "" : ": ", rule.c_str());
  }
  std::printf("%s", frameRange(run).c_str());
  if (run.frames_without_pose) std::printf(", %lld skipped without a pose", *run.frames_without_pose);
  if (run.interrupted) std::printf(", INTERRUPTED (Ctrl-C): the map holds these frames only");
  if (run.checkpoint.value_or(false)) std::printf(", CHECKPOINT: saved while the run went on, which did not finish or is still going");
  if (run.seconds && run.frames_per_second) std::printf(", %.1f s (%.1f frames/s)", *run.seconds, *run.frames_per_second);
  std::printf("\n");
  if (run.skipped && !run.skipped->empty()) std::printf("skipped while reading: %s\n", run.skipped->c_str());
  if (const auto g = meta.gravityDownWorld()) {
    std::printf("gravity (down, in the input's world frame): (%.3f, %.3f, %.3f)", g->x(), g->y(), g->z());
    if (run.gravity_source) std::printf(", from %s", run.gravity_source->c_str());
    std::printf("\n");
  }
  const Eigen::Vector3d origin = meta.originWorld();
  if (origin != Eigen::Vector3d::Zero()) {
    std::printf("map origin in the world frame: (%.3f, %.3f, %.3f)%s: map = R_map_world (world - origin)\n", origin.x(),
                origin.y(), origin.z(), run.origin_source ? (", " + *run.origin_source).c_str() : "");
  }
  if (run.perception && run.perception->voxel_size_m && run.perception->max_range_m) {
    std::printf("perception: %.0f mm voxels, range %.1f m", *run.perception->voxel_size_m * 1000, *run.perception->max_range_m);
    if (run.model && run.model->kind) {
      std::printf("; mobility model: %s", *run.model->kind == "gp" ? "Gaussian process" : "rule table");
      if (run.model->table) std::printf(" over %s", *run.model->table == "paper" ? "the paper's table" : run.model->table->c_str());
    }
    std::printf("\n");
  }
  if (run.config) std::printf("configuration: %s\n", run.config->c_str());
  // How this run read its frames (what `overlay` reads them with again).
  if (const auto& k = run.depth_intrinsics) {
    std::printf("depth camera: %dx%d, fx %.2f fy %.2f cx %.2f cy %.2f\n", k->width, k->height, k->fx, k->fy, k->cx, k->cy);
  }
  if (run.poses) {
    std::printf("poses: %s", run.poses->c_str());
    if (run.max_pose_gap_s) std::printf(" (frames whose neighbouring poses are over %.3g s apart are skipped)", *run.max_pose_gap_s);
    std::printf("\n");
  }
  double length = 0.0;
  for (std::size_t i = 1; i < meta.trajectory_map.size(); ++i) length += (meta.trajectory_map[i] - meta.trajectory_map[i - 1]).norm();
  std::printf("camera path: %zu position%s, %.2f m long\n", meta.trajectory_map.size(), meta.trajectory_map.size() == 1 ? "" : "s", length);
  std::printf("all metadata: %s (or info --json)\n", meta.path.c_str());
}

}  // namespace

Command addInfoCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("info", "Describe a map: resolution, bounds, nodes, memory, mobility histogram, walkable "
                                         "levels, how it was built; or a robot's recording: its topics, its TF tree and what "
                                         "build would read from it");
  struct Options {
    std::string map;
    bool json = false;
    RecordingChoice choice;
    double max_pose_gap = 0.05;
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("MAP", o->map, "A .ot map, or a ROS 2 bag (folder, .db3 or .mcap)")->required();
  cmd->add_flag("--json", o->json, "One JSON object: the figures above and the whole metadata file (camera path included)");
  addRecordingOptions(*cmd, o->choice);
  cmd->add_option("--max-pose-gap", o->max_pose_gap, "A ROS 2 bag: as for build (s)")->check(finiteNonNegative())->capture_default_str();
  return [o]() {
    if (sources::isRecording(o->map)) return describeRecording(o->map, o->choice, o->max_pose_gap, o->json);
    const OpenedMap opened = openMapFiles(o->map);
    const mapping::MapMetadata& metadata = opened.metadata;
    const mapping::MobilityMap& map = opened.map;
    if (o->json) {
      std::printf("%s\n", infoJson(o->map, map, &metadata).dump().c_str());
      return 0;
    }
    const auto& t = map.tree();
    double x0, y0, z0, x1, y1, z1;
    t.getMetricMin(x0, y0, z0);
    t.getMetricMax(x1, y1, z1);
    const LeafCounts counts = countLeaves(t);
    const std::size_t surface = counts.surface, free = counts.free, unknown_mob = counts.surface_without_mobility;
    const std::vector<std::size_t>& hist = counts.histogram;
    std::printf("%s: %s, resolution %.3f m\n", o->map.c_str(), t.getTreeType().c_str(), t.getResolution());
    if (surface + free > 0) {
      std::printf("bounds (map frame, z up): x %.2f..%.2f  y %.2f..%.2f  z %.2f..%.2f m\n", x0, x1, y0, y1, z0, z1);
    } else {
      std::printf("empty: no voxels\n");
    }
    std::printf("nodes %zu, leaves %zu (surface %zu, free %zu), memory %.1f MB (%zu bytes per node)\n", t.size(),
                t.getNumLeafNodes(), surface, free, t.memoryUsage() / 1e6, t.memoryUsageNode());
    std::printf("surface voxels without a mobility estimate: %zu\nmobility histogram of surface voxels:\n", unknown_mob);
    const std::size_t known = surface - unknown_mob;
    for (std::size_t b = 0; b < 10; ++b) {
      const int bar = known ? static_cast<int>(50.0 * static_cast<double>(hist[b]) / static_cast<double>(known)) : 0;
      std::printf("  %.1f-%.1f %8zu %s\n", static_cast<double>(b) / 10.0, static_cast<double>(b + 1) / 10.0, hist[b],
                  std::string(static_cast<std::size_t>(bar), '#').c_str());
    }
    const std::vector<Level> levels = walkableLevels(t);
    if (!levels.empty()) {
      std::printf("walkable levels (surface tops with mobility >= 0.75, one per column and run; share of them):");
      for (std::size_t i = 0; i < levels.size(); ++i) {
        std::printf("%s z = %.2f m (%.0f %%)", i ? "," : "", levels[i].z_m, 100 * levels[i].share);
      }
      std::printf("\n");
    }
    if (!metadata.found) {
      std::printf("no metadata (%s is absent)\n", metadata.path.c_str());
    } else {
      printMetadataSummary(metadata);
    }
    return 0;
  };
}

}  // namespace mobmap::app
