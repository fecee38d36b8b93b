// 2.5D layers per level from the map's surface columns.
#include "mobmap/mapping/layers.hpp"

#include "mobmap/mapping/levels.hpp"
#include "mobmap/mapping/reachability.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace mobmap::mapping {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// The highest run of column `col` on the level's band; -1 if none.
long runOnLevel(const SurfaceColumns& c, long col, const LayerLevel& level) {
  for (std::size_t r = c.runEnd(col); r > c.runBegin(col); --r) {
    const SurfaceColumns::Run& run = c.runs()[r - 1];
    if (c.topFace(run) < level.min_top_m) return -1;  // this and every lower run: a lower level's
    if (c.bottomFace(run) < level.max_bottom_m) return static_cast<long>(r - 1);
  }
  return -1;
}

}  // namespace

std::vector<LayerLevel> layerLevels(const SurfaceColumns& columns, double clearance_m) {
  if (!std::isfinite(clearance_m) || !(clearance_m > 0)) {
    throw std::invalid_argument("layers: the level clearance must be a finite length above 0 m, got " +
                                std::to_string(clearance_m));
  }
  std::vector<Level> found = gatherLevels(walkableBins(columns), columns.resolution(), 16, 0.05);
  std::sort(found.begin(), found.end(), [](const Level& a, const Level& b) { return a.z_m < b.z_m; });
  std::vector<LayerLevel> out;
  for (const Level& l : found) {
    if (!out.empty() && l.z_m - out.back().z_m < clearance_m) {
      out.back().share += l.share;  // the robot cannot stand under it: elevation on the level below
      continue;
    }
    LayerLevel level;
    level.z_m = l.z_m;
    level.share = l.share;
    level.min_top_m = out.empty() ? -std::numeric_limits<double>::infinity() : out.back().max_bottom_m;
    level.max_bottom_m = l.z_m + clearance_m;
    out.push_back(level);
  }
  return out;
}

std::optional<double> startHeight(const Reachability& reach) {
  if (reach.start()) return reach.footPlaces()[*reach.start()].z;
  if (reach.startLevel()) return reach.startLevel()->z_m;
  return std::nullopt;
}

std::size_t nearestLevel(const std::vector<LayerLevel>& levels, double z_m) {
  std::size_t best = 0;
  for (std::size_t k = 1; k < levels.size(); ++k) {
    if (std::abs(levels[k].z_m - z_m) < std::abs(levels[best].z_m - z_m)) best = k;
  }
  return best;
}

const std::vector<std::string>& layerNames() {
  static const std::vector<std::string> names{"elevation", "elevation_variance", "mobility", "mobility_variance",
                                              "step",      "slope_deg",          "known"};
  return names;
}

const std::vector<float>& layerByName(const LevelLayers& l, const std::string& name) {
  if (name == "elevation") return l.elevation;
  if (name == "elevation_variance") return l.elevation_variance;
  if (name == "mobility") return l.mobility;
  if (name == "mobility_variance") return l.mobility_variance;
  if (name == "step") return l.step;
  if (name == "slope_deg") return l.slope_deg;
  if (name == "known") return l.known;
  throw std::invalid_argument("layers: no layer named " + name);
}

void checkLayerCell(double cell_m, double resolution_m) {
  if (!std::isfinite(cell_m) || cell_m < resolution_m - 1e-9 || cell_m > kMaxLayerCellM) {
    std::ostringstream m;
    m << "layers: the cell size must be from the map's resolution (" << resolution_m << " m) to " << kMaxLayerCellM
      << " m, got " << cell_m;
    throw std::invalid_argument(m.str());
  }
}

namespace {

// Fills `out` (its grid placed: x_min, y_min, cols, rows) from the map columns i0..i1,
// j0..j1 (exclusive ends); `cellOf(i, j)` is a column's index in out or out's size.
template <typename CellOf>
void fillLayers(const SurfaceColumns& c, const LayerLevel& level, const Reachability* reach, LevelLayers& out, long i0,
                long i1, long j0, long j1, const CellOf& cellIndex) {
  const double res = c.resolution();
  const double cell_m = out.cell_m;
  const std::size_t n = static_cast<std::size_t>(out.cols) * static_cast<std::size_t>(out.rows);
  out.elevation.assign(n, kNaN);
  out.elevation_variance.assign(n, kNaN);
  out.mobility.assign(n, kNaN);
  out.mobility_variance.assign(n, kNaN);
  out.step.assign(n, kNaN);
  out.slope_deg.assign(n, kNaN);
  out.known.assign(n, 0.0f);
  std::vector<std::uint32_t> columns(n, 0), known(n, 0), standable(n, 0);
  std::vector<double> sum(n, 0.0), sum2(n, 0.0);
  for (long j = j0; j < j1; ++j) {
    for (long i = i0; i < i1; ++i) {
      const std::size_t at = cellIndex(i, j);
      if (at == n) continue;
      ++columns[at];
      const long r = runOnLevel(c, i * c.columnsY() + j, level);
      if (r < 0) continue;
      const SurfaceColumns::Run& run = c.runs()[static_cast<std::size_t>(r)];
      const double top = c.topFace(run);
      ++known[at];
      sum[at] += top;
      sum2[at] += top * top;
      if (reach != nullptr && reach->places()[static_cast<std::size_t>(r)].standable) ++standable[at];
      if (std::isnan(out.elevation[at]) || top > out.elevation[at]) {
        out.elevation[at] = static_cast<float>(top);
        out.mobility[at] = run.mobility;
        out.mobility_variance[at] = run.hasMobility() && std::isfinite(run.variance) ? run.variance : kNaN;
      }
    }
  }
  if (reach != nullptr) out.traversable.assign(n, Traversable::kUnknown);
  for (std::size_t at = 0; at < n; ++at) {
    if (columns[at] > 0) out.known[at] = static_cast<float>(known[at]) / static_cast<float>(columns[at]);
    if (known[at] == 0) continue;
    const double mean = sum[at] / known[at];
    out.elevation_variance[at] = static_cast<float>(std::max(0.0, sum2[at] / known[at] - mean * mean) + res * res / 12);
    if (reach != nullptr) out.traversable[at] = 2 * standable[at] > known[at] ? Traversable::kFree : Traversable::kOccupied;
  }
  // Step and slope from each cell's known neighbours.
  for (int row = 0; row < out.rows; ++row) {
    for (int col = 0; col < out.cols; ++col) {
      const std::size_t at = out.index(row, col);
      const float e = out.elevation[at];
      if (std::isnan(e)) continue;
      float step = 0;
      Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
      Eigen::Vector3d b = Eigen::Vector3d::Zero();
      int used = 0;
      for (int dr = -1; dr <= 1; ++dr) {
        for (int dc = -1; dc <= 1; ++dc) {
          const int r2 = row + dr, c2 = col + dc;
          if (r2 < 0 || c2 < 0 || r2 >= out.rows || c2 >= out.cols) continue;
          const float e2 = out.elevation[out.index(r2, c2)];
          if (std::isnan(e2)) continue;
          step = std::max(step, std::abs(e2 - e));
          const Eigen::Vector3d p(dc * cell_m, -dr * cell_m, 1.0);
          A += p * p.transpose();
          b += p * (e2 - e);
          ++used;
        }
      }
      out.step[at] = step;
      // A height difference no step of the robot's spans is no place to walk.
      if (reach != nullptr && step > reach->params().robot.max_step_m) out.traversable[at] = Traversable::kOccupied;
      if (used < 3) continue;
      const Eigen::FullPivLU<Eigen::Matrix3d> lu(A);
      if (lu.rank() < 3) continue;  // the cells lie in a line
      const Eigen::Vector3d g = lu.solve(b);
      out.slope_deg[at] = static_cast<float>(std::atan(std::hypot(g.x(), g.y())) * 180.0 / M_PI);
    }
  }
}

}  // namespace

LevelLayers levelLayers(const SurfaceColumns& c, const LayerLevel& level, double cell_m, const Reachability* reach) {
  const double res = c.resolution();
  checkLayerCell(cell_m, res);
  if (reach != nullptr && reach->columns().runs().size() != c.runs().size()) {
    throw std::invalid_argument("layers: the reachability was computed on another map");
  }
  LevelLayers out;
  out.level = level;
  out.cell_m = cell_m;
  const double x0 = c.centreOf(c.keyX0()) - res / 2, y0 = c.centreOf(c.keyY0()) - res / 2;
  const auto cellOf = [&](long k, long k0) {
    return static_cast<long>(std::floor(((static_cast<double>(k - k0) + 0.5) * res) / cell_m));
  };
  // The cells holding the level's surface.
  long ci0 = std::numeric_limits<long>::max(), ci1 = -1, cj0 = std::numeric_limits<long>::max(), cj1 = -1;
  for (long j = 0; j < c.columnsY(); ++j) {
    for (long i = 0; i < c.columnsX(); ++i) {
      if (runOnLevel(c, i * c.columnsY() + j, level) < 0) continue;
      const long ci = cellOf(i, 0), cj = cellOf(j, 0);
      ci0 = std::min(ci0, ci), ci1 = std::max(ci1, ci), cj0 = std::min(cj0, cj), cj1 = std::max(cj1, cj);
    }
  }
  if (ci1 < 0) return out;  // nothing on this level
  const double cells = static_cast<double>(ci1 - ci0 + 1) * static_cast<double>(cj1 - cj0 + 1);
  if (cells > static_cast<double>(kMaxLayerCells)) {
    std::ostringstream m;
    m << "layers: " << cells << " cells of " << cell_m << " m for one level; at most " << kMaxLayerCells
      << ": choose a larger cell";
    throw std::length_error(m.str());
  }
  out.cols = static_cast<int>(ci1 - ci0 + 1);
  out.rows = static_cast<int>(cj1 - cj0 + 1);
  out.x_min = x0 + static_cast<double>(ci0) * cell_m;
  out.y_min = y0 + static_cast<double>(cj0) * cell_m;
  const std::size_t n = static_cast<std::size_t>(out.cols) * static_cast<std::size_t>(out.rows);
  fillLayers(c, level, reach, out, 0, c.columnsX(), 0, c.columnsY(), [&](long i, long j) {
    const long ci = cellOf(i, 0) - ci0, cj = cellOf(j, 0) - cj0;
    if (ci < 0 || cj < 0 || ci >= out.cols || cj >= out.rows) return n;
    return out.index(static_cast<int>(out.rows - 1 - cj), static_cast<int>(ci));
  });
  return out;
}

LevelLayers levelLayers(const SurfaceColumns& c, const LayerLevel& level, double cell_m, const LayerWindow& window,
                        const Reachability* reach) {
  const double res = c.resolution();
  checkLayerCell(cell_m, res);
  if (!std::isfinite(window.x_min) || !std::isfinite(window.y_min) || window.cols < 0 || window.rows < 0 ||
      static_cast<double>(window.cols) * static_cast<double>(window.rows) > static_cast<double>(kMaxLayerCells)) {
    std::ostringstream m;
    m << "layers: a window needs a finite corner and at most " << kMaxLayerCells << " cells, got " << window.cols << " x "
      << window.rows << " at (" << window.x_min << ", " << window.y_min << ")";
    throw std::invalid_argument(m.str());
  }
  if (reach != nullptr && reach->columns().runs().size() != c.runs().size()) {
    throw std::invalid_argument("layers: the reachability was computed on another map");
  }
  LevelLayers out;
  out.level = level;
  out.cell_m = cell_m;
  out.x_min = window.x_min;
  out.y_min = window.y_min;
  out.cols = window.cols;
  out.rows = window.rows;
  const std::size_t n = static_cast<std::size_t>(out.cols) * static_cast<std::size_t>(out.rows);
  // The map columns whose centres may fall in the window.
  const double x0 = c.centreOf(c.keyX0()), y0 = c.centreOf(c.keyY0());
  const auto clampTo = [](double v, long hi) { return static_cast<long>(std::clamp(v, 0.0, static_cast<double>(hi))); };
  const long i0 = clampTo(std::floor((window.x_min - x0) / res), c.columnsX());
  const long i1 = clampTo(std::ceil((window.x_min + window.cols * cell_m - x0) / res) + 1, c.columnsX());
  const long j0 = clampTo(std::floor((window.y_min - y0) / res), c.columnsY());
  const long j1 = clampTo(std::ceil((window.y_min + window.rows * cell_m - y0) / res) + 1, c.columnsY());
  fillLayers(c, level, reach, out, i0, i1, j0, j1, [&](long i, long j) {
    const double cx = x0 + static_cast<double>(i) * res, cy = y0 + static_cast<double>(j) * res;
    const double fx = std::floor((cx - window.x_min) / cell_m), fy = std::floor((cy - window.y_min) / cell_m);
    if (fx < 0 || fy < 0 || fx >= out.cols || fy >= out.rows) return n;
    return out.index(out.rows - 1 - static_cast<int>(fy), static_cast<int>(fx));
  });
  return out;
}

}  // namespace mobmap::mapping
