// Pictures of a map: a top view (`export --png`) and the map projected into a frame
// of the input (`overlay`, paper eq. 13 and Figs. 4 and 6).
#include "canvas.hpp"
#include "commands.hpp"
#include "dataset.hpp"
#include "frame_source.hpp"
#include "io_error.hpp"
#include "map_files.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>

namespace mobmap::app {
namespace {

const Rgb kUnknownGrey{150, 150, 150};

Rgb voxelColour(const mapping::MobilityOcTreeNode& n) { return n.hasMobility() ? mobilityColour(n.mobility()) : kUnknownGrey; }

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
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("MAP", o->map, "A .ot map")->required();
  cmd->add_option("--png", o->png, "Top view of the highest surface per column, coloured by mobility, with the camera path");
  cmd->add_option("--pcd", o->pcd, "Surface voxel centres with mobility, variance and count");
  cmd->add_option("--max-pixels", o->max_pixels, "Longest side of the picture's map area")->capture_default_str();
  return [o]() {
    if (o->png.empty() && o->pcd.empty()) throw UsageError("export needs --png OUT.png and/or --pcd OUT.pcd");
    const mapping::MobilityMap map = loadMap(o->map);
    const auto& t = map.tree();
    if (!o->pcd.empty()) mapping::saveSurfacePcd(t, o->pcd);
    if (o->png.empty()) return 0;
    double x0 = 1e9, y0 = 1e9, x1 = -1e9, y1 = -1e9;
    for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) {
      if (!t.isNodeOccupied(*it)) continue;
      x0 = std::min(x0, it.getX());
      x1 = std::max(x1, it.getX());
      y0 = std::min(y0, it.getY());
      y1 = std::max(y1, it.getY());
    }
    if (x1 < x0) throw IoError(o->map, "has no surface voxels to draw");
    // The camera path may run outside the mapped surfaces: draw all of it.
    const auto meta = readMapMetadata(o->map);
    if (meta.contains("trajectory_map")) {
      for (const auto& p : meta["trajectory_map"]) {
        x0 = std::min(x0, p[0].get<double>());
        x1 = std::max(x1, p[0].get<double>());
        y0 = std::min(y0, p[1].get<double>());
        y1 = std::max(y1, p[1].get<double>());
      }
    }
    const double res = t.getResolution();
    const double extent = std::max(x1 - x0, y1 - y0) + res;
    const int ppv = std::max(1, static_cast<int>(o->max_pixels * res / extent));  // pixels per voxel
    const int w = static_cast<int>((x1 - x0) / res + 1) * ppv, h = static_cast<int>((y1 - y0) / res + 1) * ppv;
    const int margin = 50, right = 110;
    Canvas c(w + 2 * margin + right, h + 2 * margin + 20);
    // Highest surface per column; x to the right, y up.
    std::vector<double> top(static_cast<std::size_t>(w / ppv) * (h / ppv), -std::numeric_limits<double>::infinity());
    std::vector<Rgb> colour(top.size(), {255, 255, 255});
    for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) {
      if (!t.isNodeOccupied(*it)) continue;
      const int span = static_cast<int>(std::lround(it.getSize() / res));
      const int cx0 = static_cast<int>(std::lround((it.getX() - it.getSize() / 2 + res / 2 - x0) / res));
      const int cy0 = static_cast<int>(std::lround((it.getY() - it.getSize() / 2 + res / 2 - y0) / res));
      for (int dx = 0; dx < span; ++dx) {
        for (int dy = 0; dy < span; ++dy) {
          const int cx = cx0 + dx, cy = cy0 + dy;
          if (cx < 0 || cy < 0 || cx >= w / ppv || cy >= h / ppv) continue;
          const std::size_t i = static_cast<std::size_t>(cy) * (w / ppv) + cx;
          const double z = it.getZ() + it.getSize() / 2;
          if (z > top[i]) {
            top[i] = z;
            colour[i] = voxelColour(*it);
          }
        }
      }
    }
    for (int cy = 0; cy < h / ppv; ++cy) {
      for (int cx = 0; cx < w / ppv; ++cx) {
        const Rgb col = colour[static_cast<std::size_t>(cy) * (w / ppv) + cx];
        const int px = margin + cx * ppv, py = margin + (h / ppv - 1 - cy) * ppv;
        c.fillRect(px, py, px + ppv - 1, py + ppv - 1, col);
      }
    }
    c.rect(margin - 1, margin - 1, margin + w, margin + h, {0, 0, 0});
    // Camera path, from the metadata.
    auto toPixel = [&](double x, double y) {
      return std::make_pair(margin + static_cast<int>((x - x0) / res * ppv + ppv / 2),
                            margin + static_cast<int>((h / ppv - 1 - (y - y0) / res) * ppv + ppv / 2));
    };
    if (meta.contains("trajectory_map") && meta["trajectory_map"].size() > 1) {
      const auto& tr = meta["trajectory_map"];
      for (std::size_t i = 1; i < tr.size(); ++i) {
        const auto a = toPixel(tr[i - 1][0].get<double>(), tr[i - 1][1].get<double>());
        const auto b = toPixel(tr[i][0].get<double>(), tr[i][1].get<double>());
        c.line(a.first, a.second, b.first, b.second, {20, 60, 230});
        c.line(a.first, a.second + 1, b.first, b.second + 1, {20, 60, 230});
      }
      const auto s = toPixel(tr[0][0].get<double>(), tr[0][1].get<double>());
      c.fillRect(s.first - 3, s.second - 3, s.first + 3, s.second + 3, {20, 60, 230});
      c.text(margin + w + 10, margin + h - 10, "CAMERA PATH", {20, 60, 230});
    }
    // Scale bar: 1 m (or 0.5 m on small maps).
    const double bar_m = extent > 2.0 ? 1.0 : 0.5;
    const int bar_px = static_cast<int>(bar_m / res * ppv);
    const int by = margin + h + 18;
    c.fillRect(margin, by, margin + bar_px, by + 4, {0, 0, 0});
    c.text(margin + bar_px + 8, by - 1, bar_m == 1.0 ? "1 M" : "0.5 M", {0, 0, 0});
    c.text(margin, 14, "TOP VIEW: HIGHEST SURFACE PER COLUMN (X RIGHT, Y UP, MAP FRAME)", {0, 0, 0});
    drawColourBar(c, margin + w + 30, margin + 20, std::min(200, h - 60 > 60 ? h - 60 : 60));
    c.save(o->png);
    std::printf("wrote %s (%dx%d px, %d px per %.0f cm voxel)\n", o->png.c_str(), c.width(), c.height(), ppv, res * 100);
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
    const mapping::MobilityMap map = loadMap(o->map);
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
