#include "pictures/top_view.hpp"

#include "io/io_error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <optional>
#include <stdexcept>

namespace mobmap::app {

TopView computeTopView(const mapping::MobilityOcTree& t, const std::vector<Eigen::Vector2d>& also_cover,
                       int max_cells_per_side, double max_z, ColourScale scale) {
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
    const Rgb colour = voxelColour(*it, scale);
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
const Rgb kMinorContour{95, 95, 95};

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
    // Only a level: an area between two contours on a ramp spans up to an interval of
    // heights, a level's heights stay within a voxel (the 10th to 90th percentile).
    std::sort(zs.begin(), zs.end());
    const double spread = zs[zs.size() * 9 / 10] - zs[zs.size() / 10];
    if (spread > std::max(voxel_m, 0.5 * step) + 1e-9) continue;
    const double median = zs[zs.size() / 2];
    // Nor the top band of a gentle ramp, flat at the map's resolution. The label goes on
    // the member nearest the centroid (an L-shaped area's centroid may lie outside it)
    // whose surroundings are level: of the smoothed heights within 0.3 m (and 8 cells)
    // and within an interval of the area's, at least 70 % lie within half a voxel of it.
    // Around a ramp's band the ramp's other bands take their share wherever it is; a
    // floor passes away from the ramps at its edge. Areas with no such member get none.
    const int r = std::max(8, static_cast<int>(std::ceil(0.3 / view.resolution)));
    const auto levelAround = [&](std::size_t at) {
      const int bx = static_cast<int>(at % static_cast<std::size_t>(view.columns));
      const int by = static_cast<int>(at / static_cast<std::size_t>(view.columns));
      std::size_t near = 0, level = 0;
      for (int y = std::max(0, by - r); y <= std::min(view.rows - 1, by + r); ++y) {
        for (int x = std::max(0, bx - r); x <= std::min(view.columns - 1, bx + r); ++x) {
          const double z = smooth[view.cell(x, y)];
          if (z == empty || std::abs(z - median) > step + 1e-9 || (x - bx) * (x - bx) + (y - by) * (y - by) > r * r) continue;
          ++near;
          level += std::abs(z - median) <= 0.5 * voxel_m + 1e-9;
        }
      }
      return 10 * level >= 7 * near;
    };
    std::vector<std::pair<double, std::size_t>> by_distance;
    for (const std::size_t i : members) {
      const double dx = static_cast<double>(i % static_cast<std::size_t>(view.columns)) - mx;
      const double dy = static_cast<double>(i / static_cast<std::size_t>(view.columns)) - my;
      by_distance.emplace_back(dx * dx + dy * dy, i);
    }
    std::sort(by_distance.begin(), by_distance.end());
    // At most 64 tries, spread over the members from the centroid outwards.
    const std::size_t stride = std::max<std::size_t>(1, by_distance.size() / 64);
    std::optional<std::size_t> found;
    for (std::size_t k = 0; k < by_distance.size() && !found; k += stride) {
      if (levelAround(by_distance[k].second)) found = by_distance[k].second;
    }
    if (!found) continue;
    const std::size_t best = *found;
    out.labels.push_back({static_cast<int>(best % static_cast<std::size_t>(view.columns)),
                          static_cast<int>(best / static_cast<std::size_t>(view.columns)), median, members.size()});
  }
  std::sort(out.labels.begin(), out.labels.end(), [](const Contours::Label& a, const Contours::Label& b) { return a.cells > b.cells; });
  if (out.labels.size() > 24) out.labels.resize(24);
  return out;
}

Picture drawTopView(const TopView& view, const TopViewPicture& pic, int max_pixels) {
  const double res = view.resolution, x0 = view.x0, y0 = view.y0;
  const double extent = std::max(view.columns, view.rows) * res;
  const int ppv = pixelsPerCell(view, max_pixels);
  const int w = view.columns * ppv, h = view.rows * ppv;
  constexpr double kMargin = kTopViewMapX, kGap = 30;
  constexpr double kTitle = 14, kText = 12, kLabel = 11, kRow = 20;
  // The legend's entries below the colour bar, each a mark and a text.
  std::vector<std::pair<Rgb, std::string>> outline_labels;
  for (const auto& o : pic.outlines) {
    if (o.label.empty()) continue;
    bool known = false;
    for (const auto& l : outline_labels) known = known || l.second == o.label;
    if (!known) outline_labels.emplace_back(o.colour, o.label);
  }
  // Contours first: their legend entry names their interval.
  Contours contours;
  if (pic.contours) {
    // A label needs an area of about twice its own size (a label is ~48 x 17 units).
    const std::size_t label_px = 2 * 48 * 17;
    contours = computeContours(view, view.resolution / view.columns_per_cell,
                               std::max<std::size_t>(4, label_px / static_cast<std::size_t>(ppv * ppv)));
  }
  // The legend's rows after the colour bar and swatches, each a text and what marks it
  // (drawn with the row's top-left corner); one list sizes the legend and draws it.
  struct LegendRow {
    std::string text;
    std::function<void(Picture&, double, double)> mark;  // may be empty
    double above = 0;     // room above the row (the axes' arrows)
    double after = kRow;  // down to the next row
  };
  std::vector<LegendRow> entries;
  if (!pic.path.empty()) {
    entries.push_back({pic.path.size() > 1 ? "camera path" : "camera", [](Picture& p, double x, double y) {
                         p.polyline({{x, y + 7}, {x + 14, y + 7}}, kPathBlue, 2);
                       }});
  }
  for (const auto& [colour, label] : outline_labels) {
    entries.push_back({label, [colour = colour](Picture& p, double x, double y) { p.strokeRect(x + 1, y + 2, 12, 10, colour, 2); }});
  }
  if (contours.interval_m > 0) {
    char text[2][96];
    std::snprintf(text[0], sizeof text[0], "height lines every %g m", contours.interval_m);
    std::snprintf(text[1], sizeof text[1], "(bold %g m), z %.2f to %.2f m", 5 * contours.interval_m, contours.z_min,
                  contours.z_max);
    entries.push_back({text[0],
                       [](Picture& p, double x, double y) { p.segments({{x, y + 7, x + 14, y + 7}}, kMinorContour, 0.8); },
                       0, 16});
    entries.push_back({text[1], {}});
  }
  if (pic.mark) {
    entries.push_back({pic.mark_label, [](Picture& p, double x, double y) { p.circle(x + 7, y + 7, 6, kBlack, 2); }});
  }
  // Axes: x to the right, y up, in the map frame, their arrows above the row.
  entries.push_back({"x, y: map frame",
                     [](Picture& p, double x, double y) {
                       const double ox = x + 4, oy = y - 10;
                       p.polyline({{ox, oy}, {ox + 30, oy}}, kBlack, 1.5);
                       p.triangle({ox + 36, oy}, {ox + 28, oy - 4}, {ox + 28, oy + 4}, kBlack);
                       p.polyline({{ox, oy}, {ox, oy - 30}}, kBlack, 1.5);
                       p.triangle({ox, oy - 36}, {ox - 4, oy - 28}, {ox + 4, oy - 28}, kBlack);
                       p.text(ox + 40, oy - 8, "x", kBlack, kText);
                       p.text(ox + 6, oy - 44, "y", kBlack, kText);
                     },
                     54});
  double legend_w = mobilityLegendWidth(pic.swatches);
  for (const LegendRow& e : entries) legend_w = std::max(legend_w, 20 + Picture::textBox(e.text, kText).x1);
  const double title_w = Picture::textBox(pic.title, kTitle, true).x1;
  const double map_x = kTopViewMapX, map_y = kTopViewMapY;
  const double legend_rows = static_cast<double>(pic.swatches.size() + entries.size() + 1);
  const double bar_h = std::clamp(h - 70 - kRow * legend_rows - 60, 80.0, 200.0);
  const double legend_h = 30 + bar_h + kRow * legend_rows + 70;
  const int width = static_cast<int>(std::ceil(std::max(map_x + w + kGap + legend_w + kMargin, kMargin + title_w + kMargin)));
  const int height = static_cast<int>(std::ceil(map_y + std::max<double>(h + 40, legend_h) + kMargin / 2));
  Picture c(width, height);
  c.text(kMargin, 14, pic.title, kBlack, kTitle, true);
  // The cells, one pixel each in an image enlarged ppv times (y up: the top row first).
  ImageRgb cells;
  cells.width = view.columns;
  cells.height = view.rows;
  cells.pixels.resize(view.colour.size());
  for (int cy = 0; cy < view.rows; ++cy) {
    for (int cx = 0; cx < view.columns; ++cx) {
      cells.pixels[static_cast<std::size_t>(view.rows - 1 - cy) * static_cast<std::size_t>(view.columns) +
                   static_cast<std::size_t>(cx)] = view.colour[view.cell(cx, cy)];
    }
  }
  c.image(cells, map_x, map_y, ppv);
  // Contours: a line along the boundary between two cells a level lies between.
  if (pic.contours) {
    std::vector<std::array<double, 4>> minor, major;
    for (int cy = 0; cy < view.rows; ++cy) {
      for (int cx = 0; cx < view.columns; ++cx) {
        const std::size_t i = view.cell(cx, cy);
        const double px = map_x + cx * ppv, py = map_y + (view.rows - 1 - cy) * ppv;
        // A minor line one unit wide in the cell right of (above) the boundary, a major
        // one two units wide across it: both on whole pixels, so they stay crisp.
        if (contours.right[i] == 1) minor.push_back({px + ppv + 0.5, py + 0.5, px + ppv + 0.5, py + ppv - 0.5});
        if (contours.right[i] == 2) major.push_back({px + ppv, py + 1, px + ppv, py + ppv - 1});
        if (contours.up[i] == 1) minor.push_back({px + 0.5, py - 0.5, px + ppv - 0.5, py - 0.5});
        if (contours.up[i] == 2) major.push_back({px + 1, py, px + ppv - 1, py});
      }
    }
    c.segments(minor, kMinorContour, 1);
    c.segments(major, kBlack, 2);
  }
  c.strokeRect(map_x - 0.5, map_y - 0.5, w + 1, h + 1, kBlack, 1);
  const auto toPixel = [&](const Eigen::Vector2d& p) {
    return Eigen::Vector2d(map_x + ((p.x() - x0) / res + 0.5) * ppv, map_y + (view.rows - 0.5 - (p.y() - y0) / res) * ppv);
  };
  // The camera path, a line per run; a square where each run starts.
  std::vector<Eigen::Vector2d> run;
  for (std::size_t i = 0; i <= pic.path.size(); ++i) {
    const bool starts = i == pic.path.size() || std::find(pic.run_starts.begin(), pic.run_starts.end(), i) != pic.run_starts.end();
    if (starts && !run.empty()) {
      c.polyline(run, kPathBlue, 2);
      run.clear();
    }
    if (i < pic.path.size()) run.push_back(toPixel(pic.path[i]));
  }
  for (const std::size_t start : pic.run_starts) {
    if (start >= pic.path.size()) continue;
    const Eigen::Vector2d s = toPixel(pic.path[start]);
    c.fillRect(s.x() - 3.5, s.y() - 3.5, 7, 7, kPathBlue);
  }
  // Outlines (soles): a white casing under the colour, so they read on any mobility.
  for (const auto& o : pic.outlines) {
    std::vector<Eigen::Vector2d> corners;
    for (const auto& p : o.corners) corners.push_back(toPixel(p));
    c.polyline(corners, {255, 255, 255}, 4, true);
    c.polyline(corners, o.colour, 2, true);
  }
  std::optional<Eigen::Vector2d> mark_px;
  if (pic.mark) {
    mark_px = toPixel(*pic.mark);
    c.circle(mark_px->x(), mark_px->y(), 7, {255, 255, 255}, 4);
    c.circle(mark_px->x(), mark_px->y(), 7, kBlack, 2);
    c.keepClear({mark_px->x() - 9, mark_px->y() - 9, mark_px->x() + 9, mark_px->y() + 9});
  }
  // Height labels on the levels, largest first; one that would cover another moves
  // beside its spot or is left out.
  const Box map_box{map_x, map_y, map_x + w, map_y + h};
  for (const Contours::Label& l : contours.labels) {
    char text[24];
    std::snprintf(text, sizeof text, "%.2f m", l.z_m);
    const Eigen::Vector2d at(map_x + (l.cx + 0.5) * ppv, map_y + (view.rows - 1 - l.cy + 0.5) * ppv);
    const Box b = c.textBox(text, kLabel);
    const double dx = b.x1 + 8, dy = b.y1 + 6;
    c.label({at, at + Eigen::Vector2d(0, dy), at - Eigen::Vector2d(0, dy), at + Eigen::Vector2d(dx, 0),
             at - Eigen::Vector2d(dx, 0)},
            text, kBlack, kLabel, map_box);
  }
  // The legend.
  const double legend_x = map_x + w + kGap;
  double legend_y = map_y + drawMobilityLegend(c, legend_x, map_y, bar_h, pic.colours, pic.swatches) + 6;
  for (const LegendRow& e : entries) {
    legend_y += e.above;
    if (e.mark) e.mark(c, legend_x, legend_y);
    c.text(legend_x + 20, legend_y + 7 - Picture::textBox(e.text, kText).y1 / 2, e.text, kBlack, kText);
    legend_y += e.after;
  }
  // Scale bar: the longest of 0.1, 0.2, 0.5, 1, 2, 5 ... m within a quarter of the map.
  double bar_m = 0.1;
  for (double decade = 0.1; decade <= extent / 4; decade *= 10) {
    for (const double f : {1.0, 2.0, 5.0}) {
      if (decade * f <= extent / 4) bar_m = decade * f;
    }
  }
  const double bar_px = std::max(1.0, bar_m / res * ppv);
  const double by = map_y + h + 16;
  c.fillRect(map_x, by, bar_px, 4, kBlack);
  c.segments({{map_x, by - 3, map_x, by + 7}, {map_x + bar_px, by - 3, map_x + bar_px, by + 7}}, kBlack, 1);
  char bar_label[32];
  std::snprintf(bar_label, sizeof(bar_label), "%g m", bar_m);
  c.text(map_x + bar_px + 8, by + 2 - c.textBox(bar_label, kText).y1 / 2, bar_label, kBlack, kText);
  return c;
}

std::string describeTopView(const TopView& view, const Picture& picture, int max_pixels) {
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
