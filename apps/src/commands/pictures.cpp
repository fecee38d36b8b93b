// Pictures of a map: a top view (`export --png`) and the map projected into a frame
// of the input (`overlay`, paper eq. 13 and Figs. 4 and 6).
#include "commands/commands.hpp"
#include "commands/picture_options.hpp"
#include "commands/export_layers.hpp"
#include "io/extrinsics.hpp"
#include "io/files.hpp"
#include "io/frame_source.hpp"
#include "io/io_error.hpp"
#include "io/map_files.hpp"
#include "mobmap/sources/openni.hpp"
#include "io/sequence.hpp"
#include "pictures/top_view.hpp"

#include <cmath>
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>

namespace mobmap::app {
Command addExportCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "export", "Export a map: a top-view PNG, surface voxels as PCD, and/or 2.5D layers per level (GeoTIFF, nav2 map_server)");
  struct Options {
    std::string map, png, pcd;
    int max_pixels = 1400;
    ColourScale colours = ColourScale::kViridis;
    double max_z = std::numeric_limits<double>::infinity();
    LayersOptions layers;
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("MAP", o->map, "A .ot map")->required();
  cmd->add_option("--png", o->png,
                  "Top view of the highest surface per column, coloured by mobility, with the camera path; a .svg or .pdf "
                  "name draws it in that format")
      ->check(pictureFile());
  cmd->add_option("--pcd", o->pcd, "Surface voxel centres with mobility, variance and count");
  cmd->add_option("--max-pixels", o->max_pixels,
                  "Longest side of the picture's map area; a map with more columns than this is drawn with one "
                  "cell for k x k voxels (the highest)")
      ->check(CLI::Range(64, 16384))
      ->capture_default_str();
  auto* max_z = cmd->add_option("--max-z", o->max_z,
                                "Top view: draw the highest surface at or below this height (map frame, z up, metres; "
                                "`info` gives the bounds) to see the floor under tables or a room under its ceiling");
  addColoursOption(*cmd, o->colours);
  addLayersOptions(*cmd, o->layers);
  return [o, max_z]() {
    if (o->png.empty() && o->pcd.empty() && o->layers.dir.empty()) {
      throw UsageError("export needs --png OUT.png, --pcd OUT.pcd and/or --layers DIR");
    }
    resolveLayersOptions(o->layers);
    if (max_z->count() > 0 && o->png.empty()) throw UsageError("--max-z cuts the top view: it needs --png");
    if (!std::isfinite(o->max_z) && max_z->count() > 0) throw UsageError("--max-z must be a finite height in metres");
    refuseToOverwriteInputs({{"--png", o->png}, {"--pcd", o->pcd}}, mapFilesAsInputs(o->map));
    const OpenedMap opened = openMapFiles(o->map);
    const mapping::MapMetadata& metadata = opened.metadata;
    const mapping::MobilityMap& map = opened.map;
    const auto& t = map.tree();
    if (!o->pcd.empty()) mapping::saveSurfacePcd(t, o->pcd);
    if (!o->layers.dir.empty()) {
      std::error_code failed;
      std::filesystem::create_directories(o->layers.dir, failed);
      if (failed) throw IoError(o->layers.dir, "cannot create the folder for --layers: " + failed.message());
      refuseToOverwriteInputs({{"--layers", (std::filesystem::path(o->layers.dir) / "layers.json").string()}},
                              mapFilesAsInputs(o->map));
      o->layers.max_pixels = o->max_pixels;
      o->layers.colours = o->colours;
      exportLayers(o->layers, opened, o->map);
    }
    if (o->png.empty()) return 0;
    // The camera path may run outside the mapped surfaces: draw all of it. A map extended
    // by later runs: each run's path starts afresh, marked by a square like the first.
    const CameraPath camera = cameraPath(metadata);
    std::vector<Eigen::Vector2d> path = camera.xy();
    TopView view;
    try {
      view = computeTopView(t, path, o->max_pixels, o->max_z, o->colours);
    } catch (const std::invalid_argument& e) {
      throw IoError(o->map, std::string("cannot draw a top view: ") + e.what());
    }
    requireSurfaceBelowCut(view, t, o->max_z);
    TopViewPicture picture;
    picture.title = "Top view of " + std::filesystem::path(o->map).filename().string() + ": the highest surface per column";
    if (max_z->count() > 0) {
      char cut[64];
      std::snprintf(cut, sizeof cut, " at or below z = %.2f m", o->max_z);
      picture.title += cut;
    }
    picture.colours = o->colours;
    picture.path = std::move(path);
    picture.run_starts = camera.run_starts;
    const Picture c = drawTopView(view, picture, o->max_pixels);
    c.save(o->png);
    std::printf("wrote %s (%s)\n", o->png.c_str(), describeTopView(view, c, o->max_pixels).c_str());
    return 0;
  };
}

namespace {

// An input path as build records it in MAP.json ("input"), without a trailing '/'.
std::string normalInput(const std::string& path) {
  std::error_code ec;
  std::filesystem::path p = std::filesystem::absolute(path, ec).lexically_normal();
  if (p.filename().empty()) p = p.parent_path();
  return p.string();
}

// The record in MAP.json of the latest run that read `input` (the run itself, or one of
// its earlier_runs after build --extend), or null.
const mapping::MapRun* runOfInput(const mapping::MapMetadata& meta, const std::string& input) {
  const std::string wanted = normalInput(input);
  const std::vector<const mapping::MapRun*> runs = meta.runs();
  for (auto it = runs.rbegin(); it != runs.rend(); ++it) {
    if ((*it)->input && normalInput(*(*it)->input) == wanted) return *it;
  }
  return nullptr;
}

}  // namespace

Command addOverlayCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("overlay", "Project a map's surface voxels into a frame of its input, coloured by mobility");
  struct Options {
    std::string map, frame, out, poses, intrinsics, extrinsics;
    RecordingChoice choice;
    double max_pose_gap = 0.05;
    std::string background = "colour";
    ColourScale colours = ColourScale::kViridis;
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("MAP", o->map, "A .ot map")->required();
  cmd->add_option("--frame", o->frame,
                  "INPUT:N: frame N of a posed input as `build` reads it and numbers it with --frames (a 7-Scenes / "
                  "3DMatch directory, a TUM RGB-D directory, .pcd frames with --poses, an .oni recording, a ROS 2 bag); N alone: "
                  "of the input the map was built from")
      ->required();
  cmd->add_option("--out", o->out, "Picture to write: .png, .svg or .pdf")->required()->check(pictureFile());
  addColoursOption(*cmd, o->colours);
  cmd->add_option("--poses", o->poses, "For .pcd frames and .oni recordings: their trajectory (default: the one the map was built with)");
  cmd->add_option("--intrinsics", o->intrinsics,
                  "fx,fy,cx,cy or a camera-intrinsics.txt file (default: those the map was built with, else the input's own)");
  cmd->add_option("--background", o->background, kBackgroundHelp)
      ->check(CLI::IsMember({"colour", "depth"}))
      ->capture_default_str();
  addRecordingOptions(*cmd, o->choice);
  cmd->add_option("--extrinsics", o->extrinsics, std::string(kExtrinsicsHelp) + " (default: the map's run's)");
  auto* gap = cmd->add_option("--max-pose-gap", o->max_pose_gap,
                              "TUM / timestamped --poses: as for build, which numbers the frames by it (default: the "
                              "map's, else 0.05)")
                 ->check(finiteNonNegative());
  return [o, gap]() {
    // The map first: a mistyped map name is reported as such, not as a MAP.json that is missing.
    std::unique_ptr<mapping::MobilityOcTree> tree = mapping::loadMobilityMap(o->map);
    // MAP.json says how the map's runs read their frames: overlay reads them the same
    // way unless told otherwise (wrong intrinsics would shift the picture silently).
    const mapping::MapMetadata metadata = mapping::readMapMetadata(o->map);
    const auto colon = o->frame.rfind(':');
    std::string input;
    if (colon == std::string::npos) {
      const std::optional<std::string>& built_from = metadata.latest.input;
      if (!built_from || built_from->rfind("OpenNI2 device", 0) == 0) {
        throw UsageError("--frame " + o->frame + ": give INPUT:N (" +
                         (metadata.found ? "MAP.json names no input to read frames from" : "there is no MAP.json to name the input") + ")");
      }
      input = *built_from;
    } else {
      input = o->frame.substr(0, colon);
    }
    const std::string number = colon == std::string::npos ? o->frame : o->frame.substr(colon + 1);
    int n = -1;
    try {
      std::size_t used = 0;
      n = std::stoi(number, &used);
      if (used != number.size()) throw std::invalid_argument("trailing characters");
    } catch (const std::exception&) {
      throw UsageError("--frame must be INPUT:N or N (a frame number), got '" + o->frame + "'");
    }
    std::error_code ec;
    if (!std::filesystem::exists(input, ec)) throw IoError(input, "no such file or directory");
    std::string intrinsics = o->intrinsics, poses = o->poses;
    RecordingChoice choice = o->choice;
    std::string extrinsics = o->extrinsics;
    double max_pose_gap = o->max_pose_gap;
    std::optional<double> depth_units_per_m;  // the run's --depth-scale
    std::string depth_format;                 // and --depth-format
    if (const mapping::MapRun* run = runOfInput(metadata, input)) {
      depth_units_per_m = run->depth_units_per_m;
      depth_format = run->depth_format.value_or("");
      // A recording's run names its topics and world frame; its camera_info (and the
      // distortion it undoes) is read again rather than replaced by the numbers.
      if (extrinsics.empty() && run->extrinsics) extrinsics = *run->extrinsics;
      if (choice.depth_topic.empty() && run->depth_topic) choice.depth_topic = *run->depth_topic;
      if (choice.camera_info_topic.empty() && run->camera_info_topic) choice.camera_info_topic = *run->camera_info_topic;
      if (choice.world_frame.empty() && run->world_frame) choice.world_frame = *run->world_frame;
      if (intrinsics.empty() && run->depth_intrinsics && !run->camera_info_topic) {
        const mapping::DepthCameraRecord& k = *run->depth_intrinsics;
        if (!(k.fx > 0 && k.fy > 0)) {
          char got[200];
          std::snprintf(got, sizeof got, "fx %g, fy %g", k.fx, k.fy);
          throw IoError(metadata.path, "\"depth_intrinsics\" of the run that read " + input + " must have fx and fy > 0, got " +
                                           got + " (--intrinsics gives the camera instead)");
        }
        char spec[160];
        std::snprintf(spec, sizeof spec, "%.17g,%.17g,%.17g,%.17g", k.fx, k.fy, k.cx, k.cy);
        intrinsics = spec;
      }
      if (poses.empty() && run->poses) poses = *run->poses;
      if (gap->count() == 0 && run->max_pose_gap_s) max_pose_gap = *run->max_pose_gap_s;
    }
    // One .pcd or .png frame mapped in its own camera frame has no pose to read it by.
    const std::string ext = std::filesystem::path(input).extension().string();
    const bool lone_pcd = ext == ".pcd" && poses.empty();
    const bool bag = sources::isRecording(input);
    if (!bag && !std::filesystem::is_directory(input, ec) && ext != ".oni" && (ext != ".pcd" || lone_pcd)) {
      throw UsageError("--frame: overlay reads frames of a 7-Scenes / 3DMatch or TUM directory, of .pcd frames with "
                       "--poses or of an .oni recording; " + input +
                       " is none of these (for one frame on its own: mobmap analyze FILE --overlay OUT.png)");
    }
    {
      std::vector<NamedPath> inputs = mapFilesAsInputs(o->map);
      inputs.push_back({"the input", input});
      inputs.push_back({"the poses", poses});
      if (std::filesystem::is_regular_file(intrinsics, ec)) inputs.push_back({"the intrinsics", intrinsics});
      refuseToOverwriteInputs({{"--out", o->out}}, inputs);
    }
    std::unique_ptr<Sequence> seq;
    if (ext == ".oni") {
      // Frame n as `build` numbers a recording's depth frames; without poses the camera
      // is static and the map is in its frame, as build made it.
      sources::OpenNiOptions on;
      on.uri = input;
      on.is_file = true;
      on.intrinsics_spec = intrinsics;
      on.poses_path = poses;
      on.max_pose_gap_s = max_pose_gap;
      on.first = on.last = n;
      seq = sources::openOpenNi(on);
    } else {
      seq = openSequence(input, {intrinsics, max_pose_gap, poses, choice, depth_format});
    }
    if (!extrinsics.empty() && !seq->recording()) seq = withExtrinsics(std::move(seq), parseExtrinsics(extrinsics));
    // The frames in the depth unit the map's run read them in.
    if (depth_units_per_m && *depth_units_per_m > 0 && std::isfinite(*depth_units_per_m)) {
      seq = withDepthScale(std::move(seq), *depth_units_per_m);
    }
    if (!seq->hasDepth()) {
      throw IoError(input, "its frames are unorganized clouds, not images: there is no picture to draw the map into");
    }
    const Frame f = loadSequenceFrame(*seq, input, n);
    {
      std::vector<NamedPath> frame_files;
      for (const std::string& file : f.sources) frame_files.push_back({"the frame's file", file});
      refuseToOverwriteInputs({{"--out", o->out}}, frame_files);
    }
    const mapping::MobilityMap map = mapping::openMap(std::move(tree), metadata);
    const auto& k = f.intrinsics;
    // Base image: the frame's colour image in grey when the input has one, else shaded depth.
    const bool colour = f.colour && o->background == "colour";
    ImageRgb c = framePicture(k.width, k.height, colour ? &*f.colour : nullptr, f.depth->depth_m);
    // Project voxels (eq. 13) with a z-buffer; a voxel covers ~fx * size / z pixels.
    Eigen::Isometry3d T_world_camera(f.T_world_camera->matrix());
    const Eigen::Isometry3d T_camera_world = T_world_camera.inverse();
    std::vector<float> zbuf(static_cast<std::size_t>(k.width) * k.height, std::numeric_limits<float>::infinity());
    std::vector<Rgb> paint(zbuf.size());
    const auto& t = map.tree();
    for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) {
      if (!t.isNodeOccupied(*it)) continue;
      const Eigen::Vector3d pc = T_camera_world * map.mapToWorld(Eigen::Vector3d(it.getX(), it.getY(), it.getZ()));
      if (pc.z() < 0.1) continue;
      const double u = k.fx * pc.x() / pc.z() + k.cx, v = k.fy * pc.y() / pc.z() + k.cy;
      const int half = std::max(0, static_cast<int>(0.5 * k.fx * it.getSize() / pc.z()));
      for (int dv = -half; dv <= half; ++dv) {
        for (int du = -half; du <= half; ++du) {
          const int ui = static_cast<int>(std::lround(u)) + du, vi = static_cast<int>(std::lround(v)) + dv;
          if (ui < 0 || vi < 0 || ui >= k.width || vi >= k.height) continue;
          const std::size_t i = static_cast<std::size_t>(vi) * k.width + ui;
          // Only voxels at the measured surface: hidden ones would paint through walls.
          const float d = f.depth->depth_m[i];
          if (d > 0 && pc.z() > d + 0.05) continue;
          if (pc.z() < zbuf[i]) {
            zbuf[i] = static_cast<float>(pc.z());
            paint[i] = voxelColour(*it, o->colours);
          }
        }
      }
    }
    for (int v = 0; v < k.height; ++v) {
      for (int u = 0; u < k.width; ++u) {
        const std::size_t i = static_cast<std::size_t>(v) * k.width + u;
        if (std::isfinite(zbuf[i])) paintOver(c, u, v, paint[i]);
      }
    }
    const std::string caption = "The map's surfaces seen in frame " + std::to_string(n) + " (camera frame)";
    framePictureWithLegend(c, caption, o->colours).save(o->out);
    std::printf("wrote %s\n", o->out.c_str());
    return 0;
  };
}

}  // namespace mobmap::app
