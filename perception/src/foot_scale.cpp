// Roughness at foot scale (docs/ALGORITHM.md, "Roughness"). A surface that holds a
// flat square of foot_support_m keeps its own segment's slope and roughness (the
// paper's measure). The rest (rough segments, faces and tops narrower than a foot, the
// floor between stones) is scored by the ground within foot_window_m: its mean plane
// gives the slope, and its points' normals against that plane the area ratio A/A'.
#include "pipeline_steps.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numeric>
#include <unordered_map>

namespace mobmap::perception::steps {
namespace {

constexpr double kRadToDeg = 57.29577951308232;
constexpr double kRoughnessStep = 0.01;  // per-point scores are grouped at this step ...
constexpr double kSlopeStepDeg = 1.0;    // ... and this one into segments
using Array3L = Eigen::Array<long, 3, 1>;

// Chebyshev distance (in cells) from each cell to the nearest cell that is not `inside`;
// beyond the grid is outside, or with `beyond_inside` inside. Two raster passes, exact
// for this metric.
void chebyshevToOutside(const std::vector<std::uint8_t>& inside, int w, int h, std::vector<int>& d,
                        bool beyond_inside = false) {
  d.assign(inside.size(), 0);
  const int beyond = beyond_inside ? w + h : 0;
  const auto at = [&](int x, int y) { return x < 0 || y < 0 || x >= w || y >= h ? beyond : d[static_cast<std::size_t>(y) * w + x]; };
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      if (!inside[i]) continue;
      d[i] = 1 + std::min({at(x - 1, y), at(x - 1, y - 1), at(x, y - 1), at(x + 1, y - 1)});
    }
  }
  for (int y = h - 1; y >= 0; --y) {
    for (int x = w - 1; x >= 0; --x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      if (!inside[i]) continue;
      d[i] = std::min(d[i], 1 + std::min({at(x + 1, y), at(x + 1, y + 1), at(x, y + 1), at(x - 1, y + 1)}));
    }
  }
}

// Morphological opening of `full` by a square of (2 half + 1) cells: the cells some
// such square inside `full` covers.
std::vector<std::uint8_t> opening(const std::vector<std::uint8_t>& full, int w, int h, int half) {
  std::vector<int> d;
  chebyshevToOutside(full, w, h, d);
  std::vector<std::uint8_t> not_centre(full.size());
  for (std::size_t i = 0; i < full.size(); ++i) not_centre[i] = d[i] <= half;  // a square centred here leaves `full`
  chebyshevToOutside(not_centre, w, h, d, true);                                   // distance to the nearest centre
  std::vector<std::uint8_t> out(full.size());
  for (std::size_t i = 0; i < full.size(); ++i) out[i] = d[i] <= half;
  return out;
}

// What the frame saw: the cone of its points' directions and the range limit. Beyond
// them a surface is unknown, not absent: a tread cut by the image's edge still holds a
// foot.
struct View {
  float tx0 = -INFINITY, tx1 = INFINITY, ty0 = -INFINITY, ty1 = INFINITY;  // x/z, y/z
  float max_range = INFINITY;
  [[nodiscard]] bool sees(const Eigen::Vector3f& q) const {
    if (!(q.z() > 0)) return false;
    const float tx = q.x() / q.z(), ty = q.y() / q.z();
    return tx > tx0 && tx < tx1 && ty > ty0 && ty < ty1 && q.norm() < max_range;
  }
};

View viewOf(const FrameResult& out, double max_range_m, double margin_m) {
  View v;
  if (out.points.empty()) return v;
  v.tx0 = v.ty0 = INFINITY;
  v.tx1 = v.ty1 = -INFINITY;
  for (const Eigen::Vector3f& q : out.points) {
    if (!(q.z() > 0)) return View{};  // not a camera's cloud: everything counts as seen
    const float tx = q.x() / q.z(), ty = q.y() / q.z();
    v.tx0 = std::min(v.tx0, tx), v.tx1 = std::max(v.tx1, tx), v.ty0 = std::min(v.ty0, ty), v.ty1 = std::max(v.ty1, ty);
  }
  // The outermost points sit on the edge itself: pull the edge in by about a voxel.
  const float shrink = static_cast<float>(margin_m / std::max(0.3, max_range_m / 2));
  v.tx0 += shrink, v.tx1 -= shrink, v.ty0 += shrink, v.ty1 -= shrink;
  v.max_range = static_cast<float>(max_range_m - margin_m);
  return v;
}

// Marks in `unsupported` the points of `seg` that no flat square of side `support_m`
// within the segment covers. Cells are the voxel size; one closing step fills the
// gaps between sampled rows first.
void markUnsupported(const FrameResult& out, const Segment& seg, const View& view, double cell_m, double support_m,
                     std::vector<std::uint8_t>& unsupported) {
  const Eigen::Vector3f n = seg.normal;
  const Eigen::Vector3f helper = std::abs(n.x()) < 0.9f ? Eigen::Vector3f::UnitX() : Eigen::Vector3f::UnitY();
  const Eigen::Vector3f e1 = n.cross(helper).normalized();
  const Eigen::Vector3f e2 = n.cross(e1);
  float x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
  for (int i : seg.points) {
    const Eigen::Vector3f& q = out.points[static_cast<std::size_t>(i)];
    const float x = q.dot(e1), y = q.dot(e2);
    x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
  }
  // At most ~4 million cells (a 20 m floor at 1 cm) with the margins; coarser cells
  // beyond. Sized in doubles, so a long thin segment cannot overflow the count.
  double cell = cell_m;
  int half = 0, pad = 0;
  const auto size = [&](double c) {
    half = std::max(0, static_cast<int>(std::ceil((support_m / c - 1.0) / 2.0 - 1e-9)));
    pad = half + 2;  // room for a square that reaches into what the frame did not see
    return std::array<double, 2>{std::floor((x1 - x0) / c) + 1 + 2 * pad, std::floor((y1 - y0) / c) + 1 + 2 * pad};
  };
  for (auto wh = size(cell); wh[0] * wh[1] > 4e6; wh = size(cell)) cell *= 2;
  const int w = static_cast<int>((x1 - x0) / cell) + 1 + 2 * pad;
  const int h = static_cast<int>((y1 - y0) / cell) + 1 + 2 * pad;
  std::vector<std::uint8_t> full(static_cast<std::size_t>(w) * h, 0);
  std::vector<std::size_t> cell_of(seg.points.size());
  for (std::size_t j = 0; j < seg.points.size(); ++j) {
    const Eigen::Vector3f& q = out.points[static_cast<std::size_t>(seg.points[j])];
    const int cx = static_cast<int>((q.dot(e1) - x0) / cell) + pad;
    const int cy = static_cast<int>((q.dot(e2) - y0) / cell) + pad;
    cell_of[j] = static_cast<std::size_t>(cy) * w + cx;
    full[cell_of[j]] = 1;
  }
  // Cells the frame did not see may hold the surface.
  float depth = 0;
  for (int i : seg.points) depth += out.points[static_cast<std::size_t>(i)].dot(n);
  depth /= static_cast<float>(seg.points.size());
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float u = x0 + (static_cast<float>(x - pad) + 0.5f) * static_cast<float>(cell);
      const float v = y0 + (static_cast<float>(y - pad) + 0.5f) * static_cast<float>(cell);
      if (!view.sees(u * e1 + v * e2 + depth * n)) full[static_cast<std::size_t>(y) * w + x] = 1;
    }
  }
  // Closing (one cell): sampled rows a cell apart read as one surface.
  std::vector<int> d;
  std::vector<std::uint8_t> empty(full.size());
  for (std::size_t i = 0; i < full.size(); ++i) empty[i] = !full[i];
  chebyshevToOutside(empty, w, h, d);  // distance to the nearest occupied cell
  std::vector<std::uint8_t> dilated(full.size());
  for (std::size_t i = 0; i < full.size(); ++i) dilated[i] = d[i] <= 1;
  chebyshevToOutside(dilated, w, h, d);
  for (std::size_t i = 0; i < full.size(); ++i) full[i] = d[i] > 1;
  const std::vector<std::uint8_t> fits = opening(full, w, h, half);
  for (std::size_t j = 0; j < seg.points.size(); ++j) {
    if (!fits[cell_of[j]]) unsupported[static_cast<std::size_t>(seg.points[j])] = 1;
  }
}

}  // namespace

Eigen::MatrixX2d scoreAtFootScale(FrameResult& out, const Eigen::MatrixX2d& features, const Eigen::Vector3f& reference,
                                  const PerceptionParams& p) {
  const std::size_t n = out.points.size();
  std::vector<std::uint8_t> unsupported(n, 0);
  std::size_t count = 0;
  const View view = viewOf(out, p.max_range_m, 2 * p.voxel_size_m);
  for (const Segment& seg : out.segments) {
    if (seg.is_rough) {
      for (int i : seg.points) unsupported[static_cast<std::size_t>(i)] = 1;
    } else {
      markUnsupported(out, seg, view, p.voxel_size_m, p.foot_support_m, unsupported);
    }
  }
  for (std::size_t i = 0; i < n; ++i) count += unsupported[i] && out.segment_of_point[i] >= 0;
  if (count == 0) return features;

  // The ground around each unsupported point, summed over cells a third of the window
  // wide: the area ratio over the 3 x 3 x 3 cells around the point's own (the window),
  // its mean plane over the 5 x 5 x 5 (two windows wide: a plane fitted to the visible
  // side of one ridge would lean with it).
  const double a = p.foot_window_m / 3.0;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (std::size_t i = 0; i < n; ++i) {
    if (!unsupported[i] || out.segment_of_point[i] < 0) continue;
    lo = lo.cwiseMin(out.points[i].cast<double>());
    hi = hi.cwiseMax(out.points[i].cast<double>());
  }
  lo.array() -= 2.5 * a;
  hi.array() += 2.5 * a;
  // Cells per axis, checked before any index is formed from them: the linear index of
  // a cell must fit a long (validate() keeps a >= 3.3 mm and points within max_range_m).
  const Eigen::Array3d extent = ((hi - lo) / a).array() + 1;
  if (!extent.allFinite() || extent.maxCoeff() > 2e6) {
    throw std::invalid_argument("scoreAtFootScale: foot_window_m " + std::to_string(p.foot_window_m) + " over points " +
                                std::to_string((hi - lo).maxCoeff()) + " m apart gives more than 2e6 cells a side");
  }
  const Array3L dim = ((hi - lo) / a).cast<long>().array() + 1;
  const auto cellOf = [&](const Eigen::Vector3f& q, Array3L& c) {
    const Eigen::Vector3d f = (q.cast<double>() - lo) / a;
    if ((f.array() < 0).any() || (f.array() >= dim.cast<double>()).any()) return false;
    c = f.cast<long>().array();
    return true;
  };
  // Occupied cells, found through a dense index where it is small enough (the usual
  // case: the unsupported points of one frame) and a hash map otherwise.
  const bool dense = dim.prod() <= 4'000'000;
  std::vector<int> dense_index(dense ? static_cast<std::size_t>(dim.prod()) : 0, -1);
  std::unordered_map<long, int> sparse_index;
  const auto linear = [&](const Array3L& c) { return (c.z() * dim.y() + c.y()) * dim.x() + c.x(); };
  struct Sums {
    double w = 0;
    Eigen::Vector3d wp = Eigen::Vector3d::Zero(), wn = Eigen::Vector3d::Zero();
    Eigen::Matrix3d wpp = Eigen::Matrix3d::Zero();
    void add(const Sums& o) { w += o.w, wp += o.wp, wn += o.wn, wpp += o.wpp; }
  };
  std::vector<Sums> sums;
  const auto find = [&](const Array3L& c, bool create) -> int {
    if ((c < 0).any() || (c >= dim).any()) return -1;
    int* slot = nullptr;
    if (dense) {
      slot = &dense_index[static_cast<std::size_t>(linear(c))];
    } else {
      auto it = sparse_index.find(linear(c));
      if (it == sparse_index.end()) {
        if (!create) return -1;
        it = sparse_index.emplace(linear(c), -1).first;
      }
      slot = &it->second;
    }
    if (*slot < 0 && create) {
      *slot = static_cast<int>(sums.size());
      sums.emplace_back();
    }
    return *slot;
  };
  // Voxel reduction keeps about one point per voxel a surface crosses: a plane with
  // unit normal m crosses |m|_1 voxels per voxel area, so a point stands for
  // 1 / |m|_1 of a voxel's area of surface.
  const Eigen::Vector3d origin = (lo + hi) / 2;  // sums about a nearby origin keep precision
  for (std::size_t i = 0; i < n; ++i) {
    Array3L c;
    if (!cellOf(out.points[i], c)) continue;
    Sums& s = sums[static_cast<std::size_t>(find(c, true))];
    const double w = 1.0 / std::max(1.0f, out.normals[i].cwiseAbs().sum());
    const Eigen::Vector3d q = out.points[i].cast<double>() - origin;
    s.w += w;
    s.wp += w * q;
    s.wpp += w * q * q.transpose();
    s.wn += w * out.normals[i].cast<double>();
  }
  const Eigen::Vector3d up = reference.normalized().cast<double>();
  struct Score {
    bool done = false, valid = false;
    int slope_step = 0, roughness_step = 0;
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  };
  std::vector<Score> scores(sums.size());
  const auto around = [&](const Array3L& c, int reach) {
    Sums total;
    for (long z = -reach; z <= reach; ++z) {
      for (long y = -reach; y <= reach; ++y) {
        for (long x = -reach; x <= reach; ++x) {
          const int k = find(c + Array3L(x, y, z), false);
          if (k >= 0) total.add(sums[static_cast<std::size_t>(k)]);
        }
      }
    }
    return total;
  };
  std::map<std::pair<int, int>, int> group;  // (slope step, roughness step) -> new segment
  std::vector<Segment> added;
  for (std::size_t i = 0; i < n; ++i) {
    if (!unsupported[i] || out.segment_of_point[i] < 0) continue;
    Array3L c;
    if (!cellOf(out.points[i], c)) continue;
    Score& sc = scores[static_cast<std::size_t>(find(c, false))];
    if (!sc.done) {
      sc.done = true;
      const Sums wide = around(c, 2);
      const Sums near = around(c, 1);
      if (wide.w * (1.0 / (a * a)) * p.voxel_size_m * p.voxel_size_m < 0.25 || near.w <= 0) continue;
      const Eigen::Vector3d mean = wide.wp / wide.w;
      const Eigen::Matrix3d cov = wide.wpp / wide.w - mean * mean.transpose();
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
      eig.computeDirect(cov);
      Eigen::Vector3d m = eig.eigenvectors().col(0);
      if (m.dot(up) < 0) m = -m;
      const double projected = near.wn.dot(m);
      const double roughness = projected > 0 ? std::clamp(near.w / projected, 1.0, 5.0) : 5.0;
      const double slope = std::acos(std::clamp(m.dot(up), -1.0, 1.0)) * kRadToDeg;
      sc.valid = true;
      sc.slope_step = static_cast<int>(std::lround(slope / kSlopeStepDeg));
      sc.roughness_step = static_cast<int>(std::lround((roughness - 1.0) / kRoughnessStep));
      sc.normal = m;
    }
    if (!sc.valid) continue;
    const std::pair<int, int> key{sc.slope_step, sc.roughness_step};
    auto [it, fresh] = group.try_emplace(key, static_cast<int>(added.size()));
    if (fresh) {
      Segment s;
      s.is_rough = true;
      s.slope_deg = key.first * kSlopeStepDeg;
      s.roughness = 1.0 + key.second * kRoughnessStep;
      added.push_back(std::move(s));
    }
    Segment& s = added[static_cast<std::size_t>(it->second)];
    s.points.push_back(static_cast<int>(i));
    Eigen::Vector3f towards = sc.normal.cast<float>();
    if (towards.dot(-out.points[i]) < 0) towards = -towards;
    s.normal += towards;
    s.area_m2 += p.voxel_size_m * p.voxel_size_m / std::max(1.0f, out.normals[i].cwiseAbs().sum());
  }
  if (added.empty()) return features;

  // The old segments give up the points scored at foot scale; empty ones go.
  std::vector<Segment> kept;
  std::vector<int> rows;
  std::vector<std::uint8_t> moved(n, 0);
  for (const Segment& s : added) {
    for (int i : s.points) moved[static_cast<std::size_t>(i)] = 1;
  }
  for (std::size_t s = 0; s < out.segments.size(); ++s) {
    Segment& seg = out.segments[s];
    seg.points.erase(std::remove_if(seg.points.begin(), seg.points.end(), [&](int i) { return moved[static_cast<std::size_t>(i)] != 0; }),
                     seg.points.end());
    if (seg.points.empty()) continue;
    rows.push_back(static_cast<int>(s));
    kept.push_back(std::move(seg));
  }
  for (Segment& s : added) {
    Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
    for (int i : s.points) centroid += out.points[static_cast<std::size_t>(i)];
    s.centroid = centroid / static_cast<float>(s.points.size());
    s.normal.normalize();
  }
  Eigen::MatrixX2d all(static_cast<Eigen::Index>(kept.size() + added.size()), 2);
  for (std::size_t k = 0; k < rows.size(); ++k) all.row(static_cast<Eigen::Index>(k)) = features.row(rows[k]);
  for (std::size_t k = 0; k < added.size(); ++k) {
    all(static_cast<Eigen::Index>(rows.size() + k), 0) = added[k].slope_deg;
    all(static_cast<Eigen::Index>(rows.size() + k), 1) = added[k].roughness;
  }
  out.segments = std::move(kept);
  for (Segment& s : added) out.segments.push_back(std::move(s));
  std::fill(out.segment_of_point.begin(), out.segment_of_point.end(), -1);
  for (std::size_t s = 0; s < out.segments.size(); ++s) {
    out.segments[s].id = static_cast<int>(s);
    for (int i : out.segments[s].points) out.segment_of_point[static_cast<std::size_t>(i)] = static_cast<int>(s);
  }
  return all;
}

}  // namespace mobmap::perception::steps
