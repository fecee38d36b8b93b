#include "fine_surface.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>

namespace mobmap::mapping::detail {

void PointMoments::merge(const PointMoments& o, float cap) {
  w += o.w;
  for (int i = 0; i < 3; ++i) s[i] += o.s[i];
  for (int i = 0; i < 6; ++i) ss[i] += o.ss[i];
  if (views < 65535) ++views;
  if (w > cap) {
    const float f = cap / w;
    w = cap;
    for (float& v : s) v *= f;
    for (float& v : ss) v *= f;
  }
}

Eigen::Matrix3f PointMoments::covariance() const {
  const Eigen::Vector3f m = mean();
  Eigen::Matrix3f c;
  c << ss[0], ss[1], ss[2], ss[1], ss[3], ss[4], ss[2], ss[4], ss[5];
  return c / w - m * m.transpose();
}

std::size_t FineSurface::memoryBytes() const {
  // A node of the table: its key and moments, the next pointer and the cached hash;
  // the bucket array besides.
  return voxels_.size() * (sizeof(Table::value_type) + 2 * sizeof(void*)) + voxels_.bucket_count() * sizeof(void*);
}

VoxelPlane planeOf(const MobilityOcTree& tree, const octomap::OcTreeKey& key, const PointMoments& m) {
  VoxelPlane p;
  p.key = key;
  const octomap::point3d c = tree.keyToCoord(key);
  p.mean = Eigen::Vector3f(c.x(), c.y(), c.z()) + m.mean();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> eig;
  eig.computeDirect(m.covariance());
  p.normal = eig.eigenvectors().col(0).normalized();
  p.thickness = std::sqrt(std::max(0.0f, eig.eigenvalues()[0]));
  // Points along a line (a voxel an image's last row crossed) fix no plane: level then.
  const float line = 0.01f * static_cast<float>(tree.getResolution());
  if (eig.eigenvalues()[1] < line * line) p.normal = Eigen::Vector3f::UnitZ();
  if (p.normal.z() < 0) p.normal = -p.normal;
  p.weight = m.w;
  p.views = m.views;
  return p;
}

namespace {

constexpr double kBandM = 0.10;          // the surfaces around a voxel lie within this height of it
// A flat rectangle's columns lie this close to its plane, in RMS and at the worst (what
// noise and the voxels' steps leave on a smooth ramp; rough fields a few centimetres
// tall lie well outside).
constexpr double kFlatRmsM = 0.0075, kFlatWorstM = 0.025;
constexpr double kMinCoverage = 0.6;      // of the window's columns, with a surface
constexpr double kReliefOverNoise = 2.5;  // rough ground's relief stands this far above its points' noise
constexpr double kSlopeReachM = 0.12;     // the mean plane's columns lie within this of the voxel's
constexpr std::uint64_t kMaxDenseColumns = std::uint64_t{1} << 25;  // 128 MB of column starts at most

std::uint32_t columnOf(const octomap::OcTreeKey& k) { return (static_cast<std::uint32_t>(k[0]) << 16) | k[1]; }

// The planes sorted by column, then height, and each column's range among them.
struct Columns {
  std::vector<VoxelPlane> planes;
  // Where each column's planes start: over the planes' bounding rectangle, first[c] is
  // the first plane of column c or after it (column c's planes: [first[c], first[c+1])).
  // A map too wide for that array looks its columns up in `range` instead.
  int x0 = 0, y0 = 0, width = 0, height = 0;
  std::vector<std::uint32_t> first;
  std::unordered_map<std::uint32_t, std::pair<std::uint32_t, std::uint32_t>> range;

  void index() {
    if (planes.empty()) return;
    int x1 = planes.front().key[0], y1 = planes.front().key[1];
    x0 = x1, y0 = y1;
    for (const VoxelPlane& p : planes) {
      x0 = std::min<int>(x0, p.key[0]), x1 = std::max<int>(x1, p.key[0]);
      y0 = std::min<int>(y0, p.key[1]), y1 = std::max<int>(y1, p.key[1]);
    }
    width = x1 - x0 + 1, height = y1 - y0 + 1;
    if (static_cast<std::uint64_t>(width) * static_cast<std::uint64_t>(height) <= kMaxDenseColumns) {
      first.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height) + 1, 0);
      std::uint32_t i = 0;
      for (std::size_t c = 0; c + 1 < first.size(); ++c) {
        first[c] = i;
        while (i < planes.size() && cell(planes[i].key[0], planes[i].key[1]) == c) ++i;
      }
      first.back() = static_cast<std::uint32_t>(planes.size());
      return;
    }
    width = height = 0;
    for (std::uint32_t i = 0; i < planes.size();) {
      std::uint32_t j = i;
      const std::uint32_t c = columnOf(planes[i].key);
      while (j < planes.size() && columnOf(planes[j].key) == c) ++j;
      range.emplace(c, std::make_pair(i, j));
      i = j;
    }
  }
  std::size_t cell(int x, int y) const {
    return static_cast<std::size_t>(x - x0) * static_cast<std::size_t>(height) + static_cast<std::size_t>(y - y0);
  }

  // The highest plane of column (x, y) whose voxel lies within [z - band, z + band].
  const VoxelPlane* top(int x, int y, int z, int band) const {
    std::uint32_t begin = 0, end = 0;
    if (width > 0) {
      if (x < x0 || y < y0 || x >= x0 + width || y >= y0 + height) return nullptr;
      const std::size_t c = cell(x, y);
      begin = first[c], end = first[c + 1];
    } else {
      if (x < 0 || y < 0 || x > 65535 || y > 65535) return nullptr;
      const auto it = range.find((static_cast<std::uint32_t>(x) << 16) | static_cast<std::uint32_t>(y));
      if (it == range.end()) return nullptr;
      begin = it->second.first, end = it->second.second;
    }
    for (std::uint32_t i = end; i > begin; --i) {
      const VoxelPlane& p = planes[i - 1];
      if (p.key[2] > z + band) continue;
      if (p.key[2] < z - band) return nullptr;
      return &p;
    }
    return nullptr;
  }
};

// The height of a plane at (x, y), kept within a voxel of its own (a vertical plane has
// none of its own: its mean's). A voxel holding only the top corner of a sloped surface
// has that surface's plane below itself at the column's centre: hence the voxel below.
double heightAt(const VoxelPlane& p, double x, double y, double voxel_bottom, double res) {
  double z = p.mean.z();
  if (std::abs(p.normal.z()) > 0.05) z -= (p.normal.x() * (x - p.mean.x()) + p.normal.y() * (y - p.mean.y())) / p.normal.z();
  return std::clamp(z, voxel_bottom - res, voxel_bottom + res);
}

}  // namespace

namespace {

// The column heights around a voxel, on a grid of side x side columns centred on it,
// each looked up the first time it is asked for (most ground is decided by the first
// rectangle tried: a sole's worth of columns, not the whole grid).
class Window {
 public:
  Window(const Columns& cols, const MobilityOcTree& tree, int band, int reach)
      : cols_(cols), tree_(tree), res_(tree.getResolution()), band_(band), reach_(reach), side_(2 * reach + 1),
        stamp_(static_cast<std::size_t>(side_ * side_), 0), height_(stamp_.size()), plane_(stamp_.size()) {}
  void centre(const octomap::OcTreeKey& key) {
    x0_ = key[0], y0_ = key[1], z0_ = key[2];
    ++now_;
  }
  // Column (i, j) of the grid (0 .. side - 1): its plane, or nullptr for none.
  const VoxelPlane* plane(int i, int j) {
    const std::size_t at = static_cast<std::size_t>(j * side_ + i);
    if (stamp_[at] != now_) {
      stamp_[at] = now_;
      const VoxelPlane* p = cols_.top(x0_ + i - reach_, y0_ + j - reach_, z0_, band_);
      plane_[at] = p;
      if (p) {
        const octomap::point3d c = tree_.keyToCoord(p->key);
        height_[at] = heightAt(*p, c.x(), c.y(), c.z() - res_ / 2, res_);
      }
    }
    return plane_[at];
  }
  // Its height at the column's centre (the column must have a plane).
  double height(int i, int j) {
    plane(i, j);
    return height_[static_cast<std::size_t>(j * side_ + i)];
  }

 private:
  const Columns& cols_;
  const MobilityOcTree& tree_;
  double res_;
  int band_, reach_, side_;
  int x0_ = 0, y0_ = 0, z0_ = 0;
  std::uint32_t now_ = 0;
  std::vector<std::uint32_t> stamp_;
  std::vector<double> height_;
  std::vector<const VoxelPlane*> plane_;
};

// Whether a rectangle of w x l columns (first column (i0, j0) of the grid) has all its
// columns and they lie within kFlatRmsM and kFlatWorstM of their least-squares plane
// z = a + b x + c y (on a regular grid the normal equations separate).
bool flatRectangle(Window& win, int i0, int j0, int w, int l) {
  double sum = 0, sxz = 0, syz = 0;
  const double mi = (w - 1) / 2.0, mj = (l - 1) / 2.0;
  for (int j = 0; j < l; ++j) {
    for (int i = 0; i < w; ++i) {
      if (!win.plane(i0 + i, j0 + j)) return false;
      const double h = win.height(i0 + i, j0 + j);
      sum += h, sxz += (i - mi) * h, syz += (j - mj) * h;
    }
  }
  double sxx = 0, syy = 0;
  for (int i = 0; i < w; ++i) sxx += (i - mi) * (i - mi);
  for (int j = 0; j < l; ++j) syy += (j - mj) * (j - mj);
  const double a = sum / (w * l), b = sxx > 0 ? sxz / (sxx * l) : 0, c = syy > 0 ? syz / (syy * w) : 0;
  double squares = 0;
  for (int j = 0; j < l; ++j) {
    for (int i = 0; i < w; ++i) {
      const double r = win.height(i0 + i, j0 + j) - (a + b * (i - mi) + c * (j - mj));
      if (std::abs(r) > kFlatWorstM) return false;
      squares += r * r;
    }
  }
  return squares <= kFlatRmsM * kFlatRmsM * (w * l);
}

}  // namespace

RoughGroundReport scoreRoughGround(const FineSurface& surface, const std::vector<octomap::OcTreeKey>& voxels,
                                   const MobilityOcTree& tree, const MapParams& params, const gp::MobilityModel& model,
                                   const std::function<MobilityOcTreeNode*(const octomap::OcTreeKey&)>& node_of,
                                   std::vector<RoughVoxel>* rough) {
  RoughGroundReport report;
  const double res = tree.getResolution();
  Columns cols;
  cols.planes.reserve(surface.voxels().size());
  for (const auto& [key, m] : surface.voxels()) {
    if (m.w >= params.fine_min_weight) cols.planes.push_back(planeOf(tree, key, m));
  }
  std::sort(cols.planes.begin(), cols.planes.end(), [](const VoxelPlane& a, const VoxelPlane& b) {
    const std::uint32_t ca = columnOf(a.key), cb = columnOf(b.key);
    return ca != cb ? ca < cb : a.key[2] < b.key[2];
  });
  cols.index();
  report.planes = cols.planes.size();

  const int band = std::max(1, static_cast<int>(std::lround(kBandM / res)));
  // A sole's rectangle in columns, either way round.
  const int width = std::max(2, static_cast<int>(std::lround(params.fine_support_m / res)));
  const int length = std::max(width, static_cast<int>(std::lround(params.fine_support_length_m / res)));
  const int half = std::max(1, static_cast<int>(std::lround(params.fine_window_m / res / 2)));  // window: 2 half + 1 columns
  // The slope: the mean plane of the column heights within about 12 cm (a 25 cm box, so
  // a window over one block's top and the floor beside it does not lean).
  const int slope_reach = std::max(1, static_cast<int>(std::lround(kSlopeReachM / res)));
  const int reach = std::max({length - 1, half, slope_reach});
  // Sub-cells of about 1 cm per column for the window's height field (at most 8 a side:
  // a coarse map's window stays a few hundred cells).
  const int sub = std::clamp(static_cast<int>(std::lround(res / 0.01)), 1, 8);
  const double cell = res / sub;
  const int fine_side = (2 * half + 1) * sub;
  std::vector<double> fine(static_cast<std::size_t>(fine_side * fine_side));
  // The rectangles holding the grid's centre, the centred ones first (most ground is
  // flat, and they answer soonest).
  struct Placement {
    int i0, j0, w, l;
  };
  std::vector<Placement> placements;
  for (const auto& [w, l] : {std::make_pair(width, length), std::make_pair(length, width)}) {
    for (int dj = 0; dj < l; ++dj) {
      for (int di = 0; di < w; ++di) placements.push_back({reach - di, reach - dj, w, l});
    }
  }
  std::stable_sort(placements.begin(), placements.end(), [&](const Placement& a, const Placement& b) {
    const auto off = [&](const Placement& p) {
      return std::abs(2 * (reach - p.i0) - (p.w - 1)) + std::abs(2 * (reach - p.j0) - (p.l - 1));
    };
    return off(a) < off(b);
  });

  Window win(cols, tree, band, reach);
  for (const octomap::OcTreeKey& key : voxels) {
    // The column heights around the voxel: the highest plane within the band of it.
    win.centre(key);
    // Held by a flat rectangle a sole's size: not rough ground, whatever is beside it.
    bool supported = false;
    for (const Placement& p : placements) {
      if (flatRectangle(win, p.i0, p.j0, p.w, p.l)) {
        supported = true;
        break;
      }
    }
    if (supported) {
      ++report.supported;
      continue;
    }
    // Columns by their offset from the voxel's.
    const auto plane = [&](int i, int j) { return win.plane(i + reach, j + reach); };
    const auto height = [&](int i, int j) { return win.height(i + reach, j + reach); };
    // The window's height field at sub-cell centres, each from its column's plane; a
    // column with no surface takes the window's lowest (what the camera did not see
    // there lay behind something higher, or level with the rest).
    int seen = 0;
    double lowest = std::numeric_limits<double>::infinity();
    for (int j = -half; j <= half; ++j) {
      for (int i = -half; i <= half; ++i) {
        if (plane(i, j)) ++seen, lowest = std::min(lowest, height(i, j));
      }
    }
    if (seen < kMinCoverage * (2 * half + 1) * (2 * half + 1)) {
      ++report.too_sparse;
      continue;
    }
    for (int j = 0; j < fine_side; ++j) {
      for (int i = 0; i < fine_side; ++i) {
        double& f = fine[static_cast<std::size_t>(j * fine_side + i)];
        const VoxelPlane* column = plane(i / sub - half, j / sub - half);
        if (!column) {
          f = lowest;
          continue;
        }
        const VoxelPlane& p = *column;
        const octomap::point3d c = tree.keyToCoord(p.key);
        const double x = c.x() - res / 2 + (i % sub + 0.5) * cell, y = c.y() - res / 2 + (j % sub + 0.5) * cell;
        f = heightAt(p, x, y, c.z() - res / 2, res);
      }
    }
    // A/A': two triangles per square of four sub-cells.
    double area = 0;
    for (int j = 0; j + 1 < fine_side; ++j) {
      for (int i = 0; i + 1 < fine_side; ++i) {
        const std::size_t f = static_cast<std::size_t>(j * fine_side + i);
        const std::size_t fx = f + 1, fy = f + static_cast<std::size_t>(fine_side), fxy = fy + 1;
        const Eigen::Vector3d a(0, 0, fine[f]), b(cell, 0, fine[fx]), c(0, cell, fine[fy]), d(cell, cell, fine[fxy]);
        area += 0.5 * (b - a).cross(c - a).norm() + 0.5 * (b - d).cross(c - d).norm();
      }
    }
    // The mean plane z = a + b x + c y by least squares over the column heights in reach.
    double n = 0, sx = 0, sy = 0, sz = 0, sxx = 0, syy = 0, sxy = 0, sxz = 0, syz = 0, thick2 = 0;
    for (int j = -slope_reach; j <= slope_reach; ++j) {
      for (int i = -slope_reach; i <= slope_reach; ++i) {
        const VoxelPlane* column = plane(i, j);
        if (!column) continue;
        const double x = i * res, y = j * res, z = height(i, j);
        n += 1, sx += x, sy += y, sz += z, sxx += x * x, syy += y * y, sxy += x * y, sxz += x * z, syz += y * z;
        thick2 += static_cast<double>(column->thickness) * column->thickness;
      }
    }
    Eigen::Matrix3d A;
    A << n, sx, sy, sx, sxx, sxy, sy, sxy, syy;
    const Eigen::Vector3d coef = A.ldlt().solve(Eigen::Vector3d(sz, sxz, syz));
    // Relief the surface resolves: the column heights about that plane, against how
    // thick the columns' points lie (depth noise smears a far floor over a few
    // centimetres; a facet of a rough field is thin). Relief within the noise says
    // nothing: the frames' score stays.
    double relief2 = 0;
    for (int j = -slope_reach; j <= slope_reach; ++j) {
      for (int i = -slope_reach; i <= slope_reach; ++i) {
        if (!plane(i, j)) continue;
        const double r = height(i, j) - (coef[0] + coef[1] * i * res + coef[2] * j * res);
        relief2 += r * r;
      }
    }
    if (relief2 < kReliefOverNoise * kReliefOverNoise * thick2) {
      ++report.too_noisy;
      continue;
    }
    const double tilt = std::atan(std::hypot(coef[1], coef[2]));
    const double slope = tilt * 180.0 / M_PI;
    // A' is the footprint on that plane: the horizontal one over cos(tilt) (a smooth ramp
    // reads 1).
    const double ratio = std::max(1.0, area * std::cos(tilt) / ((fine_side - 1) * (fine_side - 1) * cell * cell));
    if (!std::isfinite(slope) || !std::isfinite(ratio)) {  // no plane through the columns seen
      ++report.too_sparse;
      continue;
    }
    const gp::MobilityEstimate e = model.predict(slope, ratio);
    const double mobility = std::clamp(e.mobility, 0.0, 1.0);
    MobilityOcTreeNode* node = node_of(key);
    if (!node || !tree.isNodeOccupied(node)) continue;
    ++report.scored;
    if (rough) {
      const octomap::point3d c = tree.keyToCoord(key);
      RoughVoxel r;
      r.centre = Eigen::Vector3d(c.x(), c.y(), c.z());
      r.roughness = ratio;
      r.slope_deg = slope;
      r.mobility = mobility;
      r.frames_mobility = node->hasMobility() ? node->mobility() : std::numeric_limits<double>::quiet_NaN();
      rough->push_back(r);
    }
    const double weight = node->hasMobility() ? node->weight() : 1.0 / std::max(e.variance, 1e-6);
    // Its observations: the frames', or as many as saw the voxel's own points.
    const auto own = surface.voxels().find(key);
    const int views = own == surface.voxels().end() ? 1 : static_cast<int>(own->second.views);
    node->setMobility(mobility, weight, std::clamp(views, std::max(1, node->count()), 255));
  }
  return report;
}

}  // namespace mobmap::mapping::detail
