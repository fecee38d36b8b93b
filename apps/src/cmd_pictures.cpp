// Pictures of a map: a top view (`export --png`) and the map projected into a frame
// of the input (`overlay`, paper eq. 13 and Figs. 4 and 6).
#include "canvas.hpp"
#include "commands.hpp"
#include "dataset.hpp"
#include "frame_source.hpp"
#include "io_error.hpp"
#include "map_files.hpp"
#include "top_view.hpp"

#include <cmath>
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>

namespace mobmap::app {
namespace {

void drawColourBar(Canvas& c, int x0, int y0, int height) {
  for (int y = 0; y < height; ++y) c.fillRect(x0, y0 + y, x0 + 14, y0 + y, mobilityColour(1.0 - static_cast<double>(y) / (height - 1)));
  c.rect(x0 - 1, y0 - 1, x0 + 15, y0 + height, {0, 0, 0});
  for (double m : {0.0, 0.5, 1.0}) {
    const int y = y0 + static_cast<int>(std::lround((1.0 - m) * (height - 1)));
    char buf[8];
    std::snprintf(buf, sizeof(buf), "%.1f", m);
    c.text(x0 + 20, y - 3, buf, {0, 0, 0});
  }
  c.text(x0 - 10, y0 - 14, "MOBILITY", {0, 0, 0});
  c.fillRect(x0, y0 + height + 12, x0 + 14, y0 + height + 24, kUnknownGrey);
  c.text(x0 + 20, y0 + height + 15, "UNKNOWN", {0, 0, 0});
}

}  // namespace

Command addExportCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("export", "Export a map: a top-view PNG and/or surface voxels as PCD");
  struct Options {
    std::string map, png, pcd;
    int max_pixels = 1400;
    double max_z = std::numeric_limits<double>::infinity();
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("MAP", o->map, "A .ot map")->required();
  cmd->add_option("--png", o->png, "Top view of the highest surface per column, coloured by mobility, with the camera path");
  cmd->add_option("--pcd", o->pcd, "Surface voxel centres with mobility, variance and count");
  cmd->add_option("--max-pixels", o->max_pixels,
                  "Longest side of the picture's map area; a map with more columns than this is drawn with one "
                  "cell for k x k voxels (the highest)")
      ->check(CLI::Range(64, 16384))
      ->capture_default_str();
  auto* max_z = cmd->add_option("--max-z", o->max_z,
                                "Top view: draw the highest surface at or below this height (map frame, z up, metres; "
                                "`info` gives the bounds) to see the floor under tables or a room under its ceiling");
  return [o, max_z]() {
    if (o->png.empty() && o->pcd.empty()) throw UsageError("export needs --png OUT.png and/or --pcd OUT.pcd");
    if (max_z->count() > 0 && o->png.empty()) throw UsageError("--max-z cuts the top view: it needs --png");
    if (!std::isfinite(o->max_z) && max_z->count() > 0) throw UsageError("--max-z must be a finite height in metres");
    auto tree = mapping::loadMobilityMap(o->map);  // its errors before MAP.json's, as openMap(path)
    const mapping::MapMetadata metadata = mapping::readMapMetadata(o->map);
    const mapping::MobilityMap map = mapping::openMap(std::move(tree), metadata);
    const auto& t = map.tree();
    if (!o->pcd.empty()) mapping::saveSurfacePcd(t, o->pcd);
    if (o->png.empty()) return 0;
    // The camera path may run outside the mapped surfaces: draw all of it.
    const auto meta = metadataJson(metadata);
    std::vector<Eigen::Vector2d> path;
    if (meta.contains("trajectory_map")) {
      for (const auto& p : meta["trajectory_map"]) path.emplace_back(p[0].get<double>(), p[1].get<double>());
    }
    // A map extended by later runs: each run's path starts afresh (no line from where
    // one run ended to where the next began), marked by a square like the first.
    std::vector<std::size_t> run_starts = {0};
    if (meta.contains("earlier_runs")) {
      for (const auto& run : meta["earlier_runs"]) {
        if (run.contains("frames_in_run")) run_starts.push_back(run_starts.back() + run["frames_in_run"].get<std::size_t>());
      }
    }
    TopView view;
    try {
      view = computeTopView(t, path, o->max_pixels, o->max_z);
    } catch (const std::invalid_argument& e) {
      throw IoError(o->map, std::string("cannot draw a top view: ") + e.what());
    }
    if (std::all_of(view.top.begin(), view.top.end(), [](double z) { return std::isinf(z); })) {
      double lowest = std::numeric_limits<double>::infinity();
      for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) {
        if (t.isNodeOccupied(*it)) lowest = std::min(lowest, it.getZ() + it.getSize() / 2);
      }
      char msg[160];
      std::snprintf(msg, sizeof msg, "--max-z %g: no surface voxel has its top at or below it (the lowest top is at z = %.2f m)",
                    o->max_z, lowest);
      throw UsageError(msg);
    }
    const double res = view.resolution, x0 = view.x0, y0 = view.y0;
    const double extent = std::max(view.columns, view.rows) * res;
    const int ppv = std::max(1, o->max_pixels / std::max(view.columns, view.rows));  // pixels per cell
    const int w = view.columns * ppv, h = view.rows * ppv;
    const int margin = 50, right = 110;
    // The legend (colour bar, "unknown", "camera path") and the title need room even
    // when the map is a thin strip (a corridor) or a small picture was asked for.
    const int bar_h = std::clamp(h - 60, 100, 200);
    const int legend_h = 20 + bar_h + 60;
    std::string title_text = "TOP VIEW: HIGHEST SURFACE PER COLUMN (X RIGHT, Y UP, MAP FRAME)";
    if (max_z->count() > 0) {
      char cut[96];
      std::snprintf(cut, sizeof cut, "TOP VIEW: HIGHEST SURFACE PER COLUMN AT OR BELOW Z = %.2f M (X RIGHT, Y UP, MAP FRAME)",
                    o->max_z);
      title_text = cut;
    }
    const char* title = title_text.c_str();
    Canvas c(std::max(w + 2 * margin + right, margin + 6 * static_cast<int>(std::strlen(title)) + 10),
             std::max(h, legend_h) + 2 * margin + 20);
    // Highest surface per column; x to the right, y up.
    for (int cy = 0; cy < view.rows; ++cy) {
      for (int cx = 0; cx < view.columns; ++cx) {
        const int px = margin + cx * ppv, py = margin + (view.rows - 1 - cy) * ppv;
        c.fillRect(px, py, px + ppv - 1, py + ppv - 1, view.colour[view.cell(cx, cy)]);
      }
    }
    c.rect(margin - 1, margin - 1, margin + w, margin + h, {0, 0, 0});
    // Camera path, from the metadata.
    auto toPixel = [&](const Eigen::Vector2d& p) {
      return std::make_pair(margin + static_cast<int>((p.x() - x0) / res * ppv + ppv / 2),
                            margin + static_cast<int>((view.rows - 1 - (p.y() - y0) / res) * ppv + ppv / 2));
    };
    if (!path.empty()) {  // one position (a single frame) is drawn as a start mark alone
      for (std::size_t i = 1; i < path.size(); ++i) {
        if (std::find(run_starts.begin(), run_starts.end(), i) != run_starts.end()) continue;
        const auto a = toPixel(path[i - 1]);
        const auto b = toPixel(path[i]);
        c.line(a.first, a.second, b.first, b.second, {20, 60, 230});
        c.line(a.first, a.second + 1, b.first, b.second + 1, {20, 60, 230});
      }
      for (const std::size_t start : run_starts) {
        if (start >= path.size()) continue;
        const auto s = toPixel(path[start]);
        c.fillRect(s.first - 3, s.second - 3, s.first + 3, s.second + 3, {20, 60, 230});
      }
      c.fillRect(margin + w + 30, margin + legend_h - 12, margin + w + 44, margin + legend_h - 11, {20, 60, 230});
      c.text(margin + w + 50, margin + legend_h - 15, path.size() > 1 ? "CAMERA PATH" : "CAMERA", {20, 60, 230});
    }
    // Scale bar: the longest of 0.1, 0.2, 0.5, 1, 2, 5 ... m within a quarter of the map.
    double bar_m = 0.1;
    for (double decade = 0.1; decade <= extent / 4; decade *= 10) {
      for (const double f : {1.0, 2.0, 5.0}) {
        if (decade * f <= extent / 4) bar_m = decade * f;
      }
    }
    const int bar_px = std::max(1, static_cast<int>(std::lround(bar_m / res * ppv)));
    const int by = margin + h + 18;
    c.fillRect(margin, by, margin + bar_px, by + 4, {0, 0, 0});
    char bar_label[32];
    std::snprintf(bar_label, sizeof(bar_label), "%g M", bar_m);
    c.text(margin + bar_px + 8, by - 1, bar_label, {0, 0, 0});
    c.text(margin, 14, title, {0, 0, 0});
    drawColourBar(c, margin + w + 30, margin + 20, bar_h);
    c.save(o->png);
    if (view.columns_per_cell == 1) {
      std::printf("wrote %s (%dx%d px, %d px per %g cm voxel)\n", o->png.c_str(), c.width(), c.height(), ppv, res * 100);
    } else {
      std::printf("wrote %s (%dx%d px, %d px per %g cm cell: the highest of %dx%d voxels; --max-pixels for more)\n",
                  o->png.c_str(), c.width(), c.height(), ppv, res * 100, view.columns_per_cell, view.columns_per_cell);
    }
    return 0;
  };
}

Command addOverlayCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("overlay", "Project a map's surface voxels into a frame of its input, coloured by mobility");
  struct Options {
    std::string map, frame, out;
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("MAP", o->map, "A .ot map")->required();
  cmd->add_option("--frame", o->frame, "INPUT:N, a 7-Scenes layout directory and a frame number")->required();
  cmd->add_option("--out", o->out, "PNG to write")->required();
  return [o]() {
    const auto colon = o->frame.rfind(':');
    if (colon == std::string::npos) throw UsageError("--frame must be INPUT:N, got '" + o->frame + "'");
    int n = -1;
    try {
      n = std::stoi(o->frame.substr(colon + 1));
    } catch (const std::exception&) {
      throw UsageError("--frame must end in :N (a frame number), got '" + o->frame + "'");
    }
    const LoadedFrame f = loadSingleFrame(o->frame.substr(0, colon), n, "");
    if (!f.depth || !f.T_world_camera) throw UsageError("--frame needs a directory frame with a pose");
    const mapping::MobilityMap map = mapping::openMap(o->map);
    const auto& k = f.intrinsics;
    // Base image: the colour frame if it is a PNG of the same size, else shaded depth.
    Canvas c(k.width, k.height, {0, 0, 0});
    for (int v = 0; v < k.height; ++v) {
      for (int u = 0; u < k.width; ++u) {
        const std::size_t i = static_cast<std::size_t>(v) * k.width + u;
        if (f.colour && f.colour->width == k.width && f.colour->height == k.height) {
          c.set(u, v, f.colour->pixels[i]);
        } else if (f.depth->depth_m[i] > 0) {
          const auto g = static_cast<std::uint8_t>(std::clamp(250.0 - 40.0 * f.depth->depth_m[i], 40.0, 240.0));
          c.set(u, v, {g, g, g});
        }
      }
    }
    // Project voxels (eq. 13) with a z-buffer; a voxel covers ~fx * size / z pixels.
    Eigen::Isometry3d T_world_camera(f.T_world_camera->matrix());
    const Eigen::Isometry3d T_camera_world = T_world_camera.inverse();
    const Eigen::Matrix3d R_world_map = map.rotationMapWorld().transpose();
    std::vector<float> zbuf(static_cast<std::size_t>(k.width) * k.height, std::numeric_limits<float>::infinity());
    std::vector<Rgb> paint(zbuf.size());
    const auto& t = map.tree();
    for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) {
      if (!t.isNodeOccupied(*it)) continue;
      const Eigen::Vector3d pc = T_camera_world * (R_world_map * Eigen::Vector3d(it.getX(), it.getY(), it.getZ()));
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
            paint[i] = voxelColour(*it);
          }
        }
      }
    }
    for (int v = 0; v < k.height; ++v) {
      for (int u = 0; u < k.width; ++u) {
        const std::size_t i = static_cast<std::size_t>(v) * k.width + u;
        if (!std::isfinite(zbuf[i])) continue;
        const Rgb base = c.get(u, v);
        Rgb out;
        for (std::size_t ch = 0; ch < 3; ++ch) out[ch] = static_cast<std::uint8_t>((base[ch] * 2 + paint[i][ch] * 3) / 5);
        c.set(u, v, out);
      }
    }
    c.save(o->out);
    std::printf("wrote %s\n", o->out.c_str());
    return 0;
  };
}

}  // namespace mobmap::app
