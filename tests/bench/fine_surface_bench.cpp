// What a fused fine surface would give for roughness (issue: rough ground from the fused
// surface). Each rough field of the simulated rough yard, and its floor (which must stay
// smooth), is seen by the walk's frames; every depth pixel on one (the renderer's labels
// say which) is added to per-voxel point moments (count, mean, covariance) at the map's
// 2 cm. Area ratios (true area over footprint) of each field, against the exact ones and
// as the paper's rule table turns them into mobility:
// - voxel planes: each voxel's plane (the covariance's smallest axis) at the mean area
//   of a plane cutting a cube at a random offset, res^2 / |n|_1, its footprint that
//   times |n_z|: A / A' = sum 1 / |n|_1 / sum |n_z| / |n|_1;
// - a 1 cm height field of the points' mean heights, triangulated;
// - a 1 cm height field of each column's highest voxel plane, triangulated;
// - the last again over all frames, each point weighted by the depth model's variance.
// Noise-free and with the Kinect model; all frames, and those whose camera passes within
// 1.5 m of the point.
//
//   fine_surface_bench [FRAME_STEP] [MIN_POINTS]
#include "mobmap/gp/rule_table.hpp"
#include "mobmap/sim/corridor_scene.hpp"

#include <Eigen/Eigenvalues>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <algorithm>
#include <array>
#include <string>
#include <map>
#include <unordered_map>
#include <vector>

using namespace mobmap;

namespace {

struct Moments {
  double n = 0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
  void add(const Eigen::Vector3d& p, double w = 1) {
    n += w;
    sum += w * p;
    outer += w * p * p.transpose();
  }
};

struct Key {
  long x, y, z;
  bool operator==(const Key& o) const { return x == o.x && y == o.y && z == o.z; }
};
struct KeyHash {
  std::size_t operator()(const Key& k) const {
    return static_cast<std::size_t>(k.x * 73856093L) ^ static_cast<std::size_t>(k.y * 19349663L) ^ static_cast<std::size_t>(k.z * 83492791L);
  }
};

// Per field (surface id): its voxels' moments.
using Fields = std::map<int, std::unordered_map<Key, Moments, KeyHash>>;

// Per field: a height field of fine cells, the mean height of the points in each.
struct Heights {
  std::unordered_map<Key, std::pair<double, double>, KeyHash> cells;  // (x, y, 0) -> (sum z, count)
  void add(const Eigen::Vector3d& p, double res) {
    auto& c = cells[Key{static_cast<long>(std::floor(p.x() / res)), static_cast<long>(std::floor(p.y() / res)), 0}];
    c.first += p.z(), c.second += 1;
  }
};

// The height field's area ratio: each square of four cells with points, two triangles
// through their mean heights, their area over their footprint (a step between cells
// counts as the steep face it implies, seen or not).
double heightRatio(const Heights& h, double res, double min_points) {
  double area = 0, footprint = 0;
  const auto at = [&](long x, long y, double& z) {
    const auto it = h.cells.find(Key{x, y, 0});
    if (it == h.cells.end() || it->second.second < min_points) return false;
    z = it->second.first / it->second.second;
    return true;
  };
  for (const auto& [k, c] : h.cells) {
    double z00, z10, z01, z11;
    if (!at(k.x, k.y, z00) || !at(k.x + 1, k.y, z10) || !at(k.x, k.y + 1, z01) || !at(k.x + 1, k.y + 1, z11)) continue;
    const Eigen::Vector3d a(0, 0, z00), b(res, 0, z10), c2(0, res, z01), d(res, res, z11);
    area += 0.5 * (b - a).cross(c2 - a).norm() + 0.5 * (b - d).cross(c2 - d).norm();
    footprint += res * res;
  }
  return footprint > 0 ? area / footprint : 0.0;
}

// The field's area ratio from its voxels' planes; voxels with fewer than min_points left out.
std::pair<double, std::size_t> areaRatio(const std::unordered_map<Key, Moments, KeyHash>& voxels, double min_points) {
  double area = 0, footprint = 0;
  std::size_t used = 0;
  for (const auto& [key, m] : voxels) {
    if (m.n < min_points) continue;
    const Eigen::Vector3d mean = m.sum / m.n;
    const Eigen::Matrix3d cov = m.outer / m.n - mean * mean.transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    const Eigen::Vector3d normal = eig.eigenvectors().col(0);
    const double l1 = normal.cwiseAbs().sum();
    area += 1.0 / l1;
    footprint += std::abs(normal.z()) / l1;
    ++used;
  }
  return {footprint > 0 ? area / footprint : 0.0, used};
}

// A 1 cm height field from the voxel planes: each cell takes the plane of the highest
// voxel over it with enough points, at the cell's centre, kept within that voxel.
double planeHeightRatio(const std::unordered_map<Key, Moments, KeyHash>& voxels, double res, double fine, double min_points) {
  struct Top {
    long z = 0;
    Eigen::Vector3d mean, normal;
  };
  std::unordered_map<Key, Top, KeyHash> tops;  // per (x, y) voxel column
  for (const auto& [key, m] : voxels) {
    if (m.n < min_points) continue;
    const Key column{key.x, key.y, 0};
    const auto it = tops.find(column);
    if (it != tops.end() && it->second.z >= key.z) continue;
    const Eigen::Vector3d mean = m.sum / m.n;
    const Eigen::Matrix3d cov = m.outer / m.n - mean * mean.transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    tops[column] = Top{key.z, mean, eig.eigenvectors().col(0)};
  }
  const long per = std::lround(res / fine);
  Heights h;
  for (const auto& [column, t] : tops) {
    for (long a = 0; a < per; ++a) {
      for (long b = 0; b < per; ++b) {
        const double x = (column.x * per + a + 0.5) * fine, y = (column.y * per + b + 0.5) * fine;
        double z = t.mean.z();
        if (std::abs(t.normal.z()) > 0.05) z -= (t.normal.x() * (x - t.mean.x()) + t.normal.y() * (y - t.mean.y())) / t.normal.z();
        z = std::clamp(z, t.z * res, (t.z + 1) * res);
        h.add(Eigen::Vector3d(x, y, z), fine);
      }
    }
  }
  return heightRatio(h, fine, 1);
}

}  // namespace

int main(int argc, char** argv) {
  const int step = argc > 1 ? std::max(1, std::atoi(argv[1])) : 2;
  const double min_points = argc > 2 ? std::atof(argv[2]) : 5;
  constexpr double kRes = 0.02, kFine = 0.01, kNear = 1.5;
  std::printf("fine surface benchmark: the rough yard, every %d frame(s), per-voxel point moments at %.0f cm, voxels with >= %.0f points\n",
              step, kRes * 100, min_points);
  std::map<int, std::array<double, 16>> estimates;
  std::map<int, std::pair<std::string, double>> truth;
  std::map<int, std::pair<double, double>> slope_mobility;  // the field's slope and its expected mobility
  int column = 0;
  for (const sim::NoiseModel noise : {sim::NoiseModel::kNone, sim::NoiseModel::kKinect}) {
    sim::CorridorParams p;
    p.layout = sim::Layout::kRoughYard;
    p.noise = noise;
    const sim::CorridorScene scene(p);
    Fields all, near, weighted;
    std::map<int, Heights> heights_all, heights_near;
    for (const sim::Surface& s : scene.surfaces()) {
      if (s.kind == sim::SurfaceKind::kRough || s.kind == sim::SurfaceKind::kFloor || s.kind == sim::SurfaceKind::kRamp) {
        truth[s.id] = {s.name, s.roughness};
        slope_mobility[s.id] = {s.slope_deg, s.expected_mobility};
      }
    }
    for (int f = 0; f < p.frames; f += step) {
      const sim::RenderedFrame r = scene.render(f);
      const Eigen::Vector3d eye = r.T_world_camera.translation();
      for (int v = 0; v < r.depth.height; ++v) {
        for (int u = 0; u < r.depth.width; ++u) {
          const std::size_t i = static_cast<std::size_t>(v) * r.depth.width + u;
          const int label = r.labels[i];
          const float d = r.depth.depth_m[i];
          if (!(d > 0) || !truth.count(label)) continue;
          const Eigen::Vector3d pw = r.T_world_camera * (perception::pixelRay(p.intrinsics, u, v) * d);
          const Key key{static_cast<long>(std::floor(pw.x() / kRes)), static_cast<long>(std::floor(pw.y() / kRes)),
                        static_cast<long>(std::floor(pw.z() / kRes))};
          all[label][key].add(pw);
          {
            // Weighted by the depth model's variance (sigma ~ z^2): one point at 1.5 m counts 1.
            const double w = std::pow(1.5 / d, 4);
            weighted[label][key].add(pw, w);
          }
          heights_all[label].add(pw, kFine);
          if (std::hypot(eye.x() - pw.x(), eye.y() - pw.y()) <= kNear) {
            near[label][key].add(pw);
            heights_near[label].add(pw, kFine);
          }
        }
      }
    }
    for (const auto& [id, t] : truth) {
      estimates[id][column] = areaRatio(all[id], min_points).first;
      estimates[id][column + 1] = areaRatio(near[id], min_points).first;
      estimates[id][column + 4] = heightRatio(heights_all[id], kFine, min_points);
      estimates[id][column + 5] = heightRatio(heights_near[id], kFine, min_points);
      estimates[id][column + 8] = planeHeightRatio(all[id], kRes, kFine, min_points);
      estimates[id][column + 9] = planeHeightRatio(near[id], kRes, kFine, min_points);
      estimates[id][column + 12] = planeHeightRatio(weighted[id], kRes, kFine, min_points);
      estimates[id][column + 13] = planeHeightRatio(weighted[id], kRes, kFine, 2 * min_points);
    }
    column += 2;
  }
  // Each estimate, and the mobility the paper's rule table gives the field for it (its
  // slope and the estimated ratio) against the one it gives for the exact ratio.
  const gp::RuleTable rules = gp::RuleTable::paper();
  for (const int first : {0, 4, 8, 12}) {
    std::printf("\n%s: area ratio (mobility by the rule table)\n%-24s %13s %15s %15s %15s %15s\n",
                first == 0 ? "voxel planes (2 cm)"
                : first == 4 ? "height field of the mean height per 1 cm cell"
                : first == 8 ? "height field of the highest voxel plane per 1 cm cell"
                             : "the same, all frames, each point weighted by (1.5 m / its depth)^4 (the depth model's "
                               "variance); voxels of weight >= MIN_POINTS, and >= twice that",
                "field", "truth", "exact", first == 12 ? "exact,2x" : "exact<1.5", "kinect", first == 12 ? "kinect,2x" : "kinect<1.5");
    std::array<double, 4> error{};
    for (const auto& [id, t] : truth) {
      const auto& e = estimates[id];
      const auto [slope, expected] = slope_mobility[id];
      std::printf("%-24s %6.3f (%.2f)", t.first.c_str(), t.second, expected);
      for (int c = 0; c < 4; ++c) {
        const double m = rules.lookup(slope, std::max(1.0, e[first + c]));
        error[c] += std::abs(m - expected) / static_cast<double>(truth.size());
        std::printf(" %8.3f (%.2f)", e[first + c], m);
      }
      std::printf("\n");
    }
    std::printf("%-24s %13s", "mean |mobility error|", "");
    for (const double v : error) std::printf(" %15.2f", v);
    std::printf("\n");
  }
  return 0;
}
