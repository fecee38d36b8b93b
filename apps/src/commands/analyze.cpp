#include "commands/commands.hpp"
#include "io/cli_text.hpp"
#include "io/config.hpp"
#include "io/depth_checks.hpp"
#include "io/files.hpp"
#include "io/frame_source.hpp"
#include "io/io_error.hpp"
#include "commands/picture_options.hpp"
#include "pictures/picture.hpp"

#include "mobmap/perception/pipeline.hpp"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <cstring>
#include <fstream>
#include <iostream>
#include <memory>

namespace mobmap::app {

nlohmann::json frameResultJson(const perception::FrameResult& r) {
  using nlohmann::json;
  json j;
  json stages = json::array();
  for (const auto& s : r.stages) {
    stages.push_back({{"stage", s.name}, {"ms", s.milliseconds}, {"points_in", s.points_in}, {"points_out", s.points_out}});
  }
  j["stages"] = stages;
  j["total_ms"] = r.totalMilliseconds();
  j["slope_reference"] = perception::toString(r.reference);
  j["ground_rule"] = perception::toString(r.ground_rule);
  if (r.ground_plane) {
    const auto& g = *r.ground_plane;
    j["ground_plane"] = {g(0), g(1), g(2), g(3)};
    j["ground_distance_m"] = g(3);
  } else {
    j["ground_plane"] = nullptr;
  }
  json segs = json::array();
  for (const auto& s : r.segments) {
    segs.push_back({{"id", s.id}, {"points", s.points.size()}, {"is_ground", s.is_ground},
                    {"is_rough", s.is_rough},
                    {"centroid", {s.centroid.x(), s.centroid.y(), s.centroid.z()}},
                    {"normal", {s.normal.x(), s.normal.y(), s.normal.z()}},
                    {"slope_deg", s.slope_deg}, {"roughness", s.roughness}, {"area_m2", s.area_m2},
                    {"mobility", s.mobility}, {"variance", s.variance}});
  }
  j["segments"] = segs;
  const perception::RangeReport& range = r.range;
  j["range"] = {{"valid_points", range.valid_points},
                {"beyond_max_range", range.beyond_max_range},
                {"nearer_than_min_range", range.nearer_than_min_range},
                {"share_beyond", range.shareBeyond()},
                {"min_range_m", range.min_range_m},
                {"max_range_m", range.max_range_m},
                {"median_range_m", range.median_range_m},
                {"range_p95_m", range.range_p95_m},
                {"down_from_gravity", range.down_from_gravity},
                {"down_from_ground", range.down_from_ground}};
  if (range.lowest) {
    j["range"]["lowest_surface"] = {{"below_camera_m", range.lowest->below_camera_m},
                                    {"share_beyond", range.lowest->share_beyond},
                                    {"range_p95_m", range.lowest->range_p95_m},
                                    {"sampled_points", range.lowest->sampled}};
  } else {
    j["range"]["lowest_surface"] = nullptr;
  }
  return j;
}

namespace {

void writeSegmentsPcd(const std::string& path, const perception::FrameResult& r, ColourScale scale) {
  std::size_t n = 0;
  for (int s : r.segment_of_point) n += s >= 0;
  std::string text;
  text += std::string("# .PCD v0.7 - mobmap segments: rgb = mobility colour (") + mapping::toString(scale) + ")\n";
  text += "VERSION 0.7\nFIELDS x y z rgb segment mobility\nSIZE 4 4 4 4 4 4\nTYPE F F F F I F\nCOUNT 1 1 1 1 1 1\n";
  text += "WIDTH " + std::to_string(n) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + std::to_string(n) + "\nDATA ascii\n";
  char line[160];
  for (std::size_t i = 0; i < r.points.size(); ++i) {
    const int s = r.segment_of_point[i];
    if (s < 0) continue;
    const double m = r.segments[static_cast<std::size_t>(s)].mobility;
    const Rgb c = mobilityColour(m, scale);
    const std::uint32_t packed = (static_cast<std::uint32_t>(c[0]) << 16) | (static_cast<std::uint32_t>(c[1]) << 8) | c[2];
    float rgb = 0.f;
    std::memcpy(&rgb, &packed, sizeof(rgb));
    std::snprintf(line, sizeof(line), "%.5f %.5f %.5f %.9g %d %.4f\n", r.points[i].x(), r.points[i].y(),
                  r.points[i].z(), rgb, s, m);
    text += line;
  }
  writeTextFileAtomically(path, text);
}

Picture overlay(const Frame& f, const perception::FrameResult& r, int width, int height, bool colour, ColourScale scale,
                const std::string& caption) {
  // Depth for the shaded background: the depth image, or an organized cloud's z.
  std::vector<float> cloud_z;
  if (!f.depth) {
    const std::size_t pixels = static_cast<std::size_t>(width) * height;
    cloud_z.assign(pixels, 0.f);
    for (std::size_t i = 0; i < pixels && i < f.points.size(); ++i) {
      cloud_z[i] = std::isfinite(f.points[i].z()) ? f.points[i].z() : 0.f;
    }
  }
  ImageRgb c = framePicture(width, height, colour && f.colour ? &*f.colour : nullptr, f.depth ? f.depth->depth_m : cloud_z);
  for (int v = 0; v < height && !r.point_of_pixel.empty(); ++v) {
    for (int u = 0; u < width; ++u) {
      const int p = r.point_of_pixel[static_cast<std::size_t>(v) * width + u];
      const int s = p >= 0 ? r.segment_of_point[static_cast<std::size_t>(p)] : -1;
      if (s >= 0) paintOver(c, u, v, mobilityColour(r.segments[static_cast<std::size_t>(s)].mobility, scale));
    }
  }
  return framePictureWithLegend(c, caption, scale);
}

}  // namespace

Command addAnalyzeCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("analyze", "Run the per-frame pipeline on one frame and print stages and segments");
  struct Options {
    std::string input;
    int frame = -1;
    std::string gravity;
    std::string intrinsics;
    double fov = 0;
    bool json = false;
    std::string segments;
    std::string overlay;
    std::string background = "colour";
    ColourScale colours = ColourScale::kViridis;
    double max_range = -1;
    double depth_scale = 0;
    std::string depth_format;
    double voxel = 0;
    std::string config;
    RecordingChoice choice;
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("INPUT", o->input, "A .pcd, a 16-bit depth .png (millimetres), a 7-Scenes layout directory, a TUM RGB-D directory or a ROS 2 bag (folder, .db3 or .mcap)")->required();
  cmd->add_option("--frame", o->frame, "Frame number in a directory, as build numbers them (default: the first)");
  cmd->add_option("--gravity", o->gravity, "Gravity (down) in the frame of the input's points (the camera's, unless an organized cloud is in another frame), X,Y,Z (default: from the pose and gravity-direction.txt if present; without gravity the largest plane is the ground, or, if it leans more than ground_upright_prior_deg from the image's up axis, the largest floor within that cone; 0,1,0 for a level camera)");
  auto* intrinsics = cmd->add_option("--intrinsics", o->intrinsics, kIntrinsicsHelp);
  auto* fov = cmd->add_option("--fov", o->fov, kFovHelp)->excludes(intrinsics);
  cmd->add_option("--max-range", o->max_range, "Maximum range in metres (default 3)");
  addRecordingOptions(*cmd, o->choice);
  auto* depth_scale = cmd->add_option("--depth-scale", o->depth_scale, kDepthScaleHelp)->check(CLI::PositiveNumber);
  cmd->add_option("--depth-format", o->depth_format, kDepthFormatHelp);
  cmd->add_option("--config", o->config, "YAML file with any of the parameters of `mobmap config --print-default`");
  auto* voxel = cmd->add_option("--voxel", o->voxel, kVoxelHelp);
  cmd->add_flag("--json", o->json, "Print one JSON object instead of tables");
  cmd->add_option("--segments", o->segments, "Write the segmented points as PCD (x y z rgb segment mobility)");
  cmd->add_option("--overlay", o->overlay,
                  "Write a picture (.png, .svg or .pdf) of the frame coloured by its segments' mobility, with a legend")
      ->check(pictureFile());
  addColoursOption(*cmd, o->colours);
  cmd->add_option("--background", o->background, kBackgroundHelp)
      ->check(CLI::IsMember({"colour", "depth"}))
      ->capture_default_str();
  return [o, voxel, depth_scale, fov]() {
    if (fov->count() > 0) o->intrinsics = fovSpec(o->fov);
    {
      std::vector<NamedPath> inputs{{"the input", o->input}, {"--config", o->config}};
      std::error_code ec;
      if (std::filesystem::is_regular_file(o->intrinsics, ec)) inputs.push_back({"--intrinsics", o->intrinsics});
      const auto beside = std::filesystem::path(o->input).parent_path() / "camera-intrinsics.txt";
      if (o->intrinsics.empty() && std::filesystem::is_regular_file(beside, ec)) inputs.push_back({"the intrinsics", beside.string()});
      refuseToOverwriteInputs({{"--segments", o->segments}, {"--overlay", o->overlay}}, inputs);
    }
    Frame f = loadSingleFrame(o->input, o->frame, o->intrinsics, o->choice);
    {
      std::vector<NamedPath> inputs;  // a directory's frame: its depth image and pose file
      for (const std::string& file : f.sources) inputs.push_back({"the frame's file", file});
      refuseToOverwriteInputs({{"--segments", o->segments}, {"--overlay", o->overlay}}, inputs);
    }
    if (!f.note.empty()) std::fprintf(stderr, "note: %s\n", cliText(f.note).c_str());
    if (!o->depth_format.empty()) decodeDepthFormat(f, o->depth_format, o->input);
    if (depth_scale->count() > 0) rescaleDepth(f, o->depth_scale);
    if (!o->gravity.empty()) {
      // Given in the frame of the input's points: a cloud in another frame than its camera's.
      const Eigen::Vector3f g = parseVector3(o->gravity, "--gravity");
      const Eigen::Matrix3f R = f.T_cloud_camera ? Eigen::Matrix3f(f.T_cloud_camera->linear().cast<float>()) : Eigen::Matrix3f(Eigen::Matrix3f::Identity());
      f.gravity_camera = Eigen::Vector3f(R.transpose() * g);
    }
    Config config = o->config.empty() ? Config{} : loadConfig(o->config);
    if (o->max_range > 0) config.perception.max_range_m = o->max_range;
    try {
      if (voxel->count() > 0) config.perception = perception::scaledToVoxel(config.perception, o->voxel);
      perception::validate(config.perception);
    } catch (const std::invalid_argument& e) {
      throw UsageError(cliText(e));
    }
    const perception::FramePipeline pipeline(config.perception, makeModel(config));
    perception::FrameResult r = perceiveFrame(pipeline, f, f.gravity_camera);
    // The image grid for --overlay; 0 for an unorganized cloud.
    const int width = f.depth ? f.depth->width : f.height > 1 ? f.width : 0;
    const int height = f.depth ? f.depth->height : f.height > 1 ? f.height : 0;
    // Without gravity the paper's rule takes the largest plane as the ground, which in
    // a corridor seen end-on is the far wall: say how the ground was chosen.
    if (!f.gravity_camera) {
      const std::string note = groundChoiceNote(r, config.perception.ground_upright_prior_deg);
      if (!note.empty()) std::fprintf(stderr, "%s\n", cliText(note).c_str());
    }
    // Depth in another unit, or a range that cuts away most of the frame or its floor.
    const std::optional<LowZeroBits> bits = f.depth ? lowZeroBits(*f.depth, f.depth_unit) : std::nullopt;
    if (const auto unit = depthUnitProblem(r.range, f.depth_unit, bits)) {
      std::fprintf(stderr, "warning: %s: %s\n", o->input.c_str(), cliText(*unit).c_str());
    } else {
      const std::optional<double> ground = r.ground_plane ? std::optional<double>((*r.ground_plane)(3)) : std::nullopt;
      for (const auto& problem : {rangeCutProblem(r.range), floorCutProblem(r.range, ground)}) {
        if (problem) std::fprintf(stderr, "warning: %s: %s\n", o->input.c_str(), cliText(*problem).c_str());
      }
    }
    // The ground's distance from the camera, before the results go to the input's frame.
    const double camera_ground = r.ground_plane ? static_cast<double>((*r.ground_plane)(3)) : 0.0;
    toInputFrame(r, f);  // points, normals and planes as the input gave them
    if (!o->segments.empty()) writeSegmentsPcd(o->segments, r, o->colours);
    if (!o->overlay.empty()) {
      if (width == 0) throw UsageError("--overlay needs an organized input (depth image or organized PCD)");
      const std::string caption = "The frame's segments by mobility" +
                                  (o->frame >= 0 ? " (frame " + std::to_string(o->frame) + ", camera frame)" : std::string(" (camera frame)"));
      overlay(f, r, width, height, o->background == "colour", o->colours, caption).save(o->overlay);
    }
    if (o->json) {
      auto j = frameResultJson(r);
      j["input"] = f.description;
      if (r.ground_plane) j["ground_distance_m"] = camera_ground;
      if (f.T_cloud_camera) {
        const Eigen::Matrix4d T = f.T_cloud_camera->matrix();
        j["T_cloud_camera"] = nlohmann::json::array();
        for (int i = 0; i < 4; ++i) j["T_cloud_camera"].push_back({T(i, 0), T(i, 1), T(i, 2), T(i, 3)});
      }
      std::cout << j.dump() << "\n";
      return 0;
    }
    std::printf("%s\n\n%-20s %10s %10s %10s\n", f.description.c_str(), "stage", "ms", "points in", "points out");
    for (const auto& s : r.stages) std::printf("%-20s %10.2f %10zu %10zu\n", s.name.c_str(), s.milliseconds, s.points_in, s.points_out);
    std::printf("%-20s %10.2f\n\n", "total", r.totalMilliseconds());
    const perception::RangeReport& range = r.range;
    std::printf("range: %zu valid points, %zu (%.1f %%) beyond --max-range %g m, %zu nearer than %g m; median range %.2f m, "
                "95 %% within %.2f m\n",
                range.valid_points, range.beyond_max_range, 100.0 * range.shareBeyond(), range.max_range_m,
                range.nearer_than_min_range, range.min_range_m, range.median_range_m, range.range_p95_m);
    if (r.ground_plane) {
      std::printf("ground plane: normal (%.3f, %.3f, %.3f)%s, %.3f m from the camera (chosen as: %s)\n", (*r.ground_plane)(0),
                  (*r.ground_plane)(1), (*r.ground_plane)(2), f.T_cloud_camera ? " in the cloud's frame" : "",
                  camera_ground, perception::toString(r.ground_rule));
    } else {
      std::printf("no ground plane found (no floor in view?)\n");
    }
    std::printf("slope measured against: %s\n\n", perception::toString(r.reference));
    std::printf("%4s %7s %-26s %-24s %7s %9s %8s %8s %6s\n", "id", "points", "centroid (m)", "normal", "slope", "roughness",
                "mobility", "variance", "kind");
    for (const auto& s : r.segments) {
      std::printf("%4d %7zu (%6.2f,%6.2f,%6.2f)    (%6.3f,%6.3f,%6.3f)  %6.1f° %9.3f %8.2f %8.4f %6s\n", s.id, s.points.size(),
                  s.centroid.x(), s.centroid.y(), s.centroid.z(), s.normal.x(), s.normal.y(), s.normal.z(), s.slope_deg,
                  s.roughness, s.mobility, s.variance, s.is_ground ? "ground" : s.is_rough ? "rough" : "");
    }
    if (r.segments.empty()) std::printf("no segments (empty frame or nothing in range)\n");
    return 0;
  };
}

}  // namespace mobmap::app
