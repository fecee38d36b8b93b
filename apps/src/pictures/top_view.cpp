#include "pictures/top_view.hpp"

#include "io/io_error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace mobmap::app {

TopView computeTopView(const mapping::MobilityOcTree& t, const std::vector<Eigen::Vector2d>& also_cover,
                       int max_cells_per_side, double max_z) {
  if (std::isnan(max_z)) throw std::invalid_argument("the height to cut at is not a number");
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) {
    if (!t.isNodeOccupied(*it)) continue;
    x0 = std::min(x0, it.getX()), x1 = std::max(x1, it.getX());
    y0 = std::min(y0, it.getY()), y1 = std::max(y1, it.getY());
  }
  if (x1 < x0) throw std::invalid_argument("the map has no surface voxels");
  for (const Eigen::Vector2d& p : also_cover) {
    if (!p.allFinite()) throw std::invalid_argument("a point to cover is not finite");
    x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x());
    y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
  }
  const double res = t.getResolution();
  // The corner columns' centres (OctoMap's voxel faces lie at multiples of res). A
  // camera position taken as a corner as it is would put voxel centres half way between
  // cells, where rounding sends some columns into their neighbour's cell and leaves
  // empty lines across the picture.
  const auto centre = [res](double c) { return (std::floor(c / res) + 0.5) * res; };
  const double col_x0 = centre(x0), col_y0 = centre(y0);
  const double span_columns = std::max(std::round((centre(x1) - col_x0) / res), std::round((centre(y1) - col_y0) / res)) + 1;
  // Cells of k x k columns when the columns would not fit (a large map, or a camera
  // path far from the surfaces); the count is bounded before it becomes an int.
  double k = 1.0;
  if (max_cells_per_side > 0) k = std::max(1.0, std::ceil(span_columns / max_cells_per_side));
  if (span_columns / k > (1 << 20)) throw std::invalid_argument("the top view would have more than 2^20 cells per side");
  const int per = static_cast<int>(k);
  const auto cells = [&](double first, double last) {
    return static_cast<int>((std::lround((centre(last) - first) / res) + 1 + per - 1) / per);
  };
  TopView v;
  v.columns_per_cell = per;
  v.resolution = res * per;
  v.columns = cells(col_x0, x1);
  v.rows = cells(col_y0, y1);
  v.x0 = col_x0 + (per - 1) * res / 2, v.y0 = col_y0 + (per - 1) * res / 2;
  v.top.assign(static_cast<std::size_t>(v.columns) * static_cast<std::size_t>(v.rows),
               -std::numeric_limits<double>::infinity());
  v.colour.assign(v.top.size(), {255, 255, 255});
  v.top_key.assign(v.top.size(), octomap::OcTreeKey());
  for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) {
    if (!t.isNodeOccupied(*it)) continue;
    // A pruned leaf covers span x span columns.
    const int span = static_cast<int>(std::lround(it.getSize() / res));
    const long col0 = std::lround((it.getX() - it.getSize() / 2 + res / 2 - col_x0) / res);
    const long row0 = std::lround((it.getY() - it.getSize() / 2 + res / 2 - col_y0) / res);
    // Its top face, or under a cut through a pruned block, the top of its highest voxel
    // below the cut (the block's voxels are all alike).
    const double bottom = it.getZ() - it.getSize() / 2;
    double z = it.getZ() + it.getSize() / 2;
    if (z > max_z + 1e-9) {
      const double voxels_below = std::floor((max_z - bottom) / res + 1e-9);
      if (voxels_below < 1) continue;
      z = bottom + voxels_below * res;
    }
    const Rgb colour = voxelColour(*it);
    // The cells its columns fall in (one, unless the leaf is larger than a cell).
    const auto cellOf = [per](long column) { return column >= 0 ? column / per : -((-column + per - 1) / per); };
    const long cx_first = std::max(0L, cellOf(col0)), cx_last = std::min<long>(v.columns - 1, cellOf(col0 + span - 1));
    const long cy_first = std::max(0L, cellOf(row0)), cy_last = std::min<long>(v.rows - 1, cellOf(row0 + span - 1));
    for (long cy = cy_first; cy <= cy_last; ++cy) {
      for (long cx = cx_first; cx <= cx_last; ++cx) {
        const std::size_t i = v.cell(static_cast<int>(cx), static_cast<int>(cy));
        if (z > v.top[i]) {
          v.top[i] = z;
          v.colour[i] = colour;
          const long column = std::max(col0, cx * per), row = std::max(row0, cy * per);
          v.top_key[i] = t.coordToKey(octomap::point3d(static_cast<float>(col_x0 + static_cast<double>(column) * res),
                                                       static_cast<float>(col_y0 + static_cast<double>(row) * res),
                                                       static_cast<float>(z - res / 2)));
        }
      }
    }
  }
  return v;
}

namespace {

// The side of a cell in pixels: the longer side of the map fits in max_pixels.
int pixelsPerCell(const TopView& view, int max_pixels) {
  return std::max(1, max_pixels / std::max(view.columns, view.rows));
}

const Rgb kBlack{0, 0, 0};
const Rgb kPathBlue{20, 60, 230};

// Returns the height it took below the bar (the "UNKNOWN" entry and the swatches).
int drawColourBar(Canvas& c, int x0, int y0, int height, const std::vector<std::pair<Rgb, std::string>>& swatches) {
  for (int y = 0; y < height; ++y) c.fillRect(x0, y0 + y, x0 + 14, y0 + y, mobilityColour(1.0 - static_cast<double>(y) / (height - 1)));
  c.rect(x0 - 1, y0 - 1, x0 + 15, y0 + height, kBlack);
  for (double m : {0.0, 0.5, 1.0}) {
    const int y = y0 + static_cast<int>(std::lround((1.0 - m) * (height - 1)));
    char buf[8];
    std::snprintf(buf, sizeof(buf), "%.1f", m);
    c.text(x0 + 20, y - 3, buf, kBlack);
  }
  c.text(x0 - 10, y0 - 14, "MOBILITY", kBlack);
  int y = y0 + height + 12;
  c.fillRect(x0, y, x0 + 14, y + 12, kUnknownGrey);
  c.text(x0 + 20, y + 3, "UNKNOWN", kBlack);
  for (const auto& [colour, label] : swatches) {
    y += 18;
    c.fillRect(x0, y, x0 + 14, y + 12, colour);
    c.text(x0 + 20, y + 3, label, kBlack);
  }
  return y + 12 - (y0 + height);
}

}  // namespace

void requireSurfaceBelowCut(const TopView& view, const mapping::MobilityOcTree& t, double max_z) {
  if (!std::all_of(view.top.begin(), view.top.end(), [](double z) { return std::isinf(z); })) return;
  double lowest = std::numeric_limits<double>::infinity();
  for (auto it = t.begin_leafs(); it != t.end_leafs(); ++it) {
    if (t.isNodeOccupied(*it)) lowest = std::min(lowest, it.getZ() + it.getSize() / 2);
  }
  char msg[160];
  std::snprintf(msg, sizeof msg, "--max-z %g: no surface voxel has its top at or below it (the lowest top is at z = %.2f m)",
                max_z, lowest);
  throw UsageError(msg);
}

Contours computeContours(const TopView& view, double voxel_m, std::size_t min_label_cells) {
  Contours out;
  const std::size_t n = view.top.size();
  out.right.assign(n, 0);
  out.up.assign(n, 0);
  // The 5x5 median of the cells holding a surface around each such cell.
  const double empty = -std::numeric_limits<double>::infinity();
  std::vector<double> smooth(n, empty), window;
  window.reserve(25);
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (int cy = 0; cy < view.rows; ++cy) {
    for (int cx = 0; cx < view.columns; ++cx) {
      if (view.empty(cx, cy)) continue;
      window.clear();
      for (int dy = -2; dy <= 2; ++dy) {
        for (int dx = -2; dx <= 2; ++dx) {
          const int x = cx + dx, y = cy + dy;
          if (x >= 0 && y >= 0 && x < view.columns && y < view.rows && !view.empty(x, y)) window.push_back(view.top[view.cell(x, y)]);
        }
      }
      const auto mid = window.begin() + static_cast<std::ptrdiff_t>(window.size() / 2);
      std::nth_element(window.begin(), mid, window.end());
      const double z = *mid;
      smooth[view.cell(cx, cy)] = z;
      lo = std::min(lo, z), hi = std::max(hi, z);
    }
  }
  if (!(hi >= lo)) return out;
  out.z_min = lo, out.z_max = hi;
  // The interval: 1-2-5 steps from 1 cm up.
  out.interval_m = 0.01;
  for (double decade = 0.01;; decade *= 10) {
    bool found = false;
    for (const double f : {1.0, 2.0, 5.0}) {
      const double step = decade * f;
      if (step >= 2 * voxel_m - 1e-9 && (hi - lo) / step <= 20) {
        out.interval_m = step;
        found = true;
        break;
      }
    }
    if (found) break;
  }
  const double step = out.interval_m;
  // A level crossed between heights a < b: some k with a < k step <= b (heights are voxel
  // tops; a level on the lower top is not crossed).
  const auto crossing = [step](double a, double b) -> std::uint8_t {
    if (a > b) std::swap(a, b);
    const double first = std::floor(a / step + 1e-9) + 1, last = std::floor(b / step + 1e-9);
    if (last < first) return 0;
    for (double k = first; k <= last; ++k) {
      if (std::fmod(std::abs(k), 5.0) == 0) return 2;
    }
    return 1;
  };
  for (int cy = 0; cy < view.rows; ++cy) {
    for (int cx = 0; cx < view.columns; ++cx) {
      const std::size_t i = view.cell(cx, cy);
      if (smooth[i] == empty) continue;
      if (cx + 1 < view.columns && smooth[view.cell(cx + 1, cy)] != empty) out.right[i] = crossing(smooth[i], smooth[view.cell(cx + 1, cy)]);
      if (cy + 1 < view.rows && smooth[view.cell(cx, cy + 1)] != empty) out.up[i] = crossing(smooth[i], smooth[view.cell(cx, cy + 1)]);
    }
  }
  if (min_label_cells == 0) return out;
  // Areas: cells joined across boundaries no contour crosses.
  std::vector<int> area(n, -1);
  std::vector<std::size_t> stack;
  int areas = 0;
  for (std::size_t start = 0; start < n; ++start) {
    if (smooth[start] == empty || area[start] >= 0) continue;
    std::vector<std::size_t> members;
    area[start] = areas;
    stack.assign(1, start);
    while (!stack.empty()) {
      const std::size_t i = stack.back();
      stack.pop_back();
      members.push_back(i);
      const int cx = static_cast<int>(i % static_cast<std::size_t>(view.columns)), cy = static_cast<int>(i / static_cast<std::size_t>(view.columns));
      const auto join = [&](int x, int y, bool open) {
        if (!open || x < 0 || y < 0 || x >= view.columns || y >= view.rows) return;
        const std::size_t j = view.cell(x, y);
        if (smooth[j] == empty || area[j] >= 0) return;
        area[j] = areas;
        stack.push_back(j);
      };
      join(cx + 1, cy, cx + 1 < view.columns && !out.right[i]);
      join(cx, cy + 1, cy + 1 < view.rows && !out.up[i]);
      join(cx - 1, cy, cx > 0 && !out.right[view.cell(std::max(cx - 1, 0), cy)]);
      join(cx, cy - 1, cy > 0 && !out.up[view.cell(cx, std::max(cy - 1, 0))]);
    }
    ++areas;
    if (members.size() < min_label_cells) continue;
    double sx = 0, sy = 0;
    std::vector<double> zs;
    for (const std::size_t i : members) {
      sx += static_cast<double>(i % static_cast<std::size_t>(view.columns));
      sy += static_cast<double>(i / static_cast<std::size_t>(view.columns));
      zs.push_back(smooth[i]);
    }
    const double mx = sx / static_cast<double>(members.size()), my = sy / static_cast<double>(members.size());
    // The member nearest the centroid (an L-shaped area's centroid may lie outside it).
    std::size_t best = members.front();
    double best_d = std::numeric_limits<double>::infinity();
    for (const std::size_t i : members) {
      const double dx = static_cast<double>(i % static_cast<std::size_t>(view.columns)) - mx;
      const double dy = static_cast<double>(i / static_cast<std::size_t>(view.columns)) - my;
      if (dx * dx + dy * dy < best_d) best_d = dx * dx + dy * dy, best = i;
    }
    const auto mid = zs.begin() + static_cast<std::ptrdiff_t>(zs.size() / 2);
    std::nth_element(zs.begin(), mid, zs.end());
    out.labels.push_back({static_cast<int>(best % static_cast<std::size_t>(view.columns)),
                          static_cast<int>(best / static_cast<std::size_t>(view.columns)), *mid, members.size()});
  }
  std::sort(out.labels.begin(), out.labels.end(), [](const Contours::Label& a, const Contours::Label& b) { return a.cells > b.cells; });
  if (out.labels.size() > 24) out.labels.resize(24);
  return out;
}

Canvas drawTopView(const TopView& view, const TopViewPicture& pic, int max_pixels) {
  const double res = view.resolution, x0 = view.x0, y0 = view.y0;
  const double extent = std::max(view.columns, view.rows) * res;
  const int ppv = pixelsPerCell(view, max_pixels);
  const int w = view.columns * ppv, h = view.rows * ppv;
  const int margin = 50;
  // The legend (colour bar, swatches, path and mark) and the title need room even when
  // the map is a thin strip (a corridor) or a small picture was asked for.
  std::size_t longest_label = pic.contours ? 32 : 11;  // "(BOLD 0.5 M), Z -10.50..-10.45 M", "CAMERA PATH"
  for (const auto& s : pic.swatches) longest_label = std::max(longest_label, s.second.size());
  longest_label = std::max(longest_label, pic.mark_label.size());
  std::vector<std::pair<Rgb, std::string>> outline_labels;
  for (const auto& o : pic.outlines) {
    if (o.label.empty()) continue;
    bool known = false;
    for (const auto& l : outline_labels) known = known || l.second == o.label;
    if (!known) outline_labels.emplace_back(o.colour, o.label), longest_label = std::max(longest_label, o.label.size());
  }
  const int right = std::max(110, 20 + 6 * static_cast<int>(longest_label));  // labels start 50 px right of the map
  const int extra_rows =
      static_cast<int>(pic.swatches.size() + (pic.mark ? 1 : 0) + outline_labels.size() + (pic.contours ? 2 : 0));
  const int bar_h = std::clamp(h - 60 - 18 * extra_rows, 100, 200);
  const int legend_h = 20 + bar_h + 60 + 18 * extra_rows;
  Canvas c(std::max(w + 2 * margin + right, margin + 6 * static_cast<int>(pic.title.size()) + 10),
           std::max(h, legend_h) + 2 * margin + 20);
  for (int cy = 0; cy < view.rows; ++cy) {
    for (int cx = 0; cx < view.columns; ++cx) {
      const int px = margin + cx * ppv, py = margin + (view.rows - 1 - cy) * ppv;
      c.fillRect(px, py, px + ppv - 1, py + ppv - 1, view.colour[view.cell(cx, cy)]);
    }
  }
  // Contours: a line along the boundary between two cells a level lies between, drawn
  // in the cell on the right of (above) the boundary.
  Contours contours;
  if (pic.contours) {
    // A label ("Z -1.50", 7 characters) needs an area of about twice its own size.
    const std::size_t label_px = 2 * static_cast<std::size_t>(Canvas::textWidth("Z -1.50") + 4) * 12;
    contours = computeContours(view, view.resolution / view.columns_per_cell,
                               std::max<std::size_t>(4, label_px / static_cast<std::size_t>(ppv * ppv)));
    const Rgb minor{95, 95, 95};
    for (int cy = 0; cy < view.rows; ++cy) {
      for (int cx = 0; cx < view.columns; ++cx) {
        const std::size_t i = view.cell(cx, cy);
        const int px = margin + cx * ppv, py = margin + (view.rows - 1 - cy) * ppv;
        if (contours.right[i]) {
          const Rgb col = contours.right[i] == 2 ? kBlack : minor;
          c.fillRect(px + ppv, py, px + ppv, py + ppv - 1, col);
        }
        if (contours.up[i]) {
          const Rgb col = contours.up[i] == 2 ? kBlack : minor;
          c.fillRect(px, py - 1, px + ppv - 1, py - 1, col);
        }
      }
    }
  }
  for (const Contours::Label& l : contours.labels) {
    char text[24];
    std::snprintf(text, sizeof text, "Z %.2f", l.z_m);
    const int tw = Canvas::textWidth(text);
    const int px = margin + l.cx * ppv + ppv / 2 - tw / 2, py = margin + (view.rows - 1 - l.cy) * ppv + ppv / 2 - 4;
    c.fillRect(px - 2, py - 2, px + tw + 1, py + 9, Rgb{255, 255, 255});
    c.text(px, py, text, kBlack);
  }
  c.rect(margin - 1, margin - 1, margin + w, margin + h, kBlack);
  auto toPixel = [&](const Eigen::Vector2d& p) {
    return std::make_pair(margin + static_cast<int>((p.x() - x0) / res * ppv + ppv / 2),
                          margin + static_cast<int>((view.rows - 1 - (p.y() - y0) / res) * ppv + ppv / 2));
  };
  const int legend_x = margin + w + 30;
  const int below_bar = drawColourBar(c, legend_x, margin + 20, bar_h, pic.swatches);
  int legend_y = margin + 20 + bar_h + below_bar + 18;
  if (!pic.path.empty()) {  // one position (a single frame) is drawn as a start mark alone
    for (std::size_t i = 1; i < pic.path.size(); ++i) {
      if (std::find(pic.run_starts.begin(), pic.run_starts.end(), i) != pic.run_starts.end()) continue;
      const auto a = toPixel(pic.path[i - 1]);
      const auto b = toPixel(pic.path[i]);
      c.line(a.first, a.second, b.first, b.second, kPathBlue);
      c.line(a.first, a.second + 1, b.first, b.second + 1, kPathBlue);
    }
    for (const std::size_t start : pic.run_starts) {
      if (start >= pic.path.size()) continue;
      const auto s = toPixel(pic.path[start]);
      c.fillRect(s.first - 3, s.second - 3, s.first + 3, s.second + 3, kPathBlue);
    }
    c.fillRect(legend_x, legend_y + 3, legend_x + 14, legend_y + 4, kPathBlue);
    c.text(legend_x + 20, legend_y, pic.path.size() > 1 ? "CAMERA PATH" : "CAMERA", kPathBlue);
    legend_y += 18;
  }
  for (const auto& o : pic.outlines) {
    for (std::size_t i = 0; i < o.corners.size(); ++i) {
      const auto a = toPixel(o.corners[i]);
      const auto b = toPixel(o.corners[(i + 1) % o.corners.size()]);
      c.line(a.first, a.second, b.first, b.second, o.colour);
      c.line(a.first + 1, a.second, b.first + 1, b.second, o.colour);
      c.line(a.first, a.second + 1, b.first, b.second + 1, o.colour);
    }
  }
  for (const auto& [colour, label] : outline_labels) {
    c.rect(legend_x, legend_y, legend_x + 14, legend_y + 7, colour);
    c.rect(legend_x + 1, legend_y + 1, legend_x + 13, legend_y + 6, colour);
    c.text(legend_x + 20, legend_y, label, colour);
    legend_y += 18;
  }
  if (contours.interval_m > 0) {
    char text[96];
    c.fillRect(legend_x, legend_y + 3, legend_x + 14, legend_y + 3, Rgb{95, 95, 95});
    std::snprintf(text, sizeof text, "HEIGHT LINES EVERY %g M", contours.interval_m);
    c.text(legend_x + 20, legend_y, text, kBlack);
    legend_y += 12;
    std::snprintf(text, sizeof text, "(BOLD %g M), Z %.2f..%.2f M", 5 * contours.interval_m, contours.z_min, contours.z_max);
    c.text(legend_x + 20, legend_y, text, kBlack);
    legend_y += 18;
  }
  if (pic.mark) {
    const auto drawRing = [&](int px, int py) {
      for (int r : {6, 7}) {
        for (int a = 0; a < 64; ++a) {
          const double t = a * 2 * M_PI / 64;
          c.set(px + static_cast<int>(std::lround(r * std::cos(t))), py + static_cast<int>(std::lround(r * std::sin(t))), kBlack);
        }
      }
    };
    const auto m = toPixel(*pic.mark);
    drawRing(m.first, m.second);
    drawRing(legend_x + 7, legend_y + 3);
    c.text(legend_x + 20, legend_y, pic.mark_label, kBlack);
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
  c.fillRect(margin, by, margin + bar_px, by + 4, kBlack);
  char bar_label[32];
  std::snprintf(bar_label, sizeof(bar_label), "%g M", bar_m);
  c.text(margin + bar_px + 8, by - 1, bar_label, kBlack);
  c.text(margin, 14, pic.title, kBlack);
  return c;
}

std::string describeTopView(const TopView& view, const Canvas& picture, int max_pixels) {
  const int ppv = pixelsPerCell(view, max_pixels);
  char text[200];
  if (view.columns_per_cell == 1) {
    std::snprintf(text, sizeof text, "%dx%d px, %d px per %g cm voxel", picture.width(), picture.height(), ppv,
                  view.resolution * 100);
  } else {
    std::snprintf(text, sizeof text, "%dx%d px, %d px per %g cm cell: the highest of %dx%d voxels; --max-pixels for more",
                  picture.width(), picture.height(), ppv, view.resolution * 100, view.columns_per_cell,
                  view.columns_per_cell);
  }
  return text;
}

}  // namespace mobmap::app
