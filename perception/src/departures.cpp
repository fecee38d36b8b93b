// The refinements of the ground and the segments that the paper does not have (departures.hpp says why).

#include "mobmap/perception/departures.hpp"

#include "graph_walk.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <stdexcept>

namespace mobmap::perception {

namespace {

// First and second moments of a point set, for its PCA.
struct PointMoments {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  OuterSum outer;
  std::size_t n = 0;
  void add(const Eigen::Vector3f& p) {
    const Eigen::Vector3d q = p.cast<double>();
    sum += q;
    outer.add(q);
    ++n;
  }
  // Eigenvalues ascending, eigenvectors in columns (col(0): the plane normal).
  [[nodiscard]] Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen() const {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    const Eigen::Vector3d mean = sum / static_cast<double>(std::max<std::size_t>(n, 1));
    es.computeDirect(outer.matrix() / static_cast<double>(std::max<std::size_t>(n, 1)) - mean * mean.transpose());
    return es;
  }
  // Extent across the set's main direction: the width of a uniform strip is sqrt(12)
  // times its standard deviation.
  [[nodiscard]] static double width(const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>& es) {
    return std::sqrt(12.0 * std::max(0.0, es.eigenvalues()(1)));
  }
  [[nodiscard]] double width() const { return width(eigen()); }
};

}  // namespace

std::vector<int> mergeFragments(const std::vector<Eigen::Vector3f>& points, const std::vector<Eigen::Vector3f>& normals,
                                const KnnGraph& g, double max_neighbour_distance_m, const std::vector<int>& labels,
                                int min_segment_points, int fragment_max_points, double fragment_max_width_m,
                                int min_fragments, int min_points, double min_width_m, double min_spread_deg,
                                const std::optional<Eigen::Vector3f>& up, double max_slope_deg, int* regions,
                                std::vector<bool>* rough, const std::vector<bool>* ground) {
  const double cos_max_slope = std::cos(max_slope_deg * M_PI / 180.0);
  const std::size_t n = points.size();
  if (labels.size() != n || normals.size() != n || g.count.size() != n || (ground && ground->size() != n)) {
    throw std::invalid_argument("mergeFragments: points, normals, graph, labels and ground mask sizes differ");
  }
  int n_in = 0;
  for (int l : labels) n_in = std::max(n_in, l + 1);
  std::vector<int> size(static_cast<std::size_t>(n_in), 0);
  for (int l : labels) {
    if (l >= 0) ++size[static_cast<std::size_t>(l)];
  }
  // A fragment is a small region, or a narrow one: where fragments of the same
  // orientation touch at their corners (a row of pyramid faces) they grow into a long
  // zigzag strip a few centimetres wide.
  std::vector<bool> fragment(static_cast<std::size_t>(n_in), false);
  {
    std::vector<PointMoments> moments(static_cast<std::size_t>(n_in));
    for (std::size_t i = 0; i < n; ++i) {
      if (labels[i] >= 0) moments[static_cast<std::size_t>(labels[i])].add(points[i]);
    }
    for (std::size_t r = 0; r < fragment.size(); ++r) {
      fragment[r] = size[r] < fragment_max_points || moments[r].width() < fragment_max_width_m;
    }
  }
  auto is_fragment = [&](std::size_t i) { return labels[i] >= 0 && fragment[static_cast<std::size_t>(labels[i])]; };
  // Groups of connected fragment points (-1: not in a group).
  std::vector<int> group(n, -1);
  std::vector<bool> group_kept;
  {
    const float max_d2 = static_cast<float>(max_neighbour_distance_m * max_neighbour_distance_m);
    std::vector<int> queue;
    std::vector<int> seen_stamp(static_cast<std::size_t>(n_in), -1);
    std::vector<int> bridge_stamp(ground ? n : 0, -1);
    for (std::size_t seed = 0; seed < n; ++seed) {
      if (group[seed] >= 0 || !is_fragment(seed)) continue;
      const int id = static_cast<int>(group_kept.size());
      queue.assign(1, static_cast<int>(seed));
      group[seed] = id;
      int fragments = 0;
      for (std::size_t head = 0; head < queue.size(); ++head) {
        const auto i = static_cast<std::size_t>(queue[head]);
        prefetchRow(g, queue, head + 6);
        int& stamp = seen_stamp[static_cast<std::size_t>(labels[i])];
        if (stamp != id) {
          stamp = id;
          ++fragments;
        }
        auto take = [&](std::size_t nb) {
          if (group[nb] >= 0 || !is_fragment(nb)) return;
          group[nb] = id;
          queue.push_back(static_cast<int>(nb));
        };
        forNeighboursWithin(g, i, max_d2, [&](std::size_t nb) {
          take(nb);
          // Across one ground point to the fragments on its other side.
          if (ground && (*ground)[nb] && bridge_stamp[nb] != id) {
            bridge_stamp[nb] = id;
            forNeighboursWithin(g, nb, max_d2, take);
          }
        });
      }
      bool keep = fragments >= min_fragments && static_cast<int>(queue.size()) >= min_points;
      if (keep) {
        // Areal, not a strip: fragments along a crease (a stair's nose, a box edge)
        // also form groups, long and a few centimetres wide. The width of a uniform
        // strip is sqrt(12) times its standard deviation across.
        PointMoments m;
        for (int i : queue) m.add(points[static_cast<std::size_t>(i)]);
        const auto es = m.eigen();
        keep = PointMoments::width(es) >= min_width_m;
        // Walking surfaces only: a steep group is a staircase or a wall at a range
        // where noise fragments it, not rough ground.
        const Eigen::Vector3d plane_normal = es.eigenvectors().col(0);
        if (keep && up) keep = std::abs(plane_normal.dot(up->cast<double>().normalized())) >= cos_max_slope;
        // Rough: the point normals turn away from the group's plane. Fragments of a
        // smooth surface that noise broke up (a far floor, a gentle ramp) lean only a
        // few degrees off it.
        if (keep) {
          double spread = 0.0;
          for (int i : queue) {
            const double c = std::abs(normals[static_cast<std::size_t>(i)].cast<double>().dot(plane_normal));
            spread += std::acos(std::min(1.0, c));
          }
          keep = spread / static_cast<double>(queue.size()) * 180.0 / M_PI >= min_spread_deg;
        }
      }
      group_kept.push_back(keep);
    }
  }
  // Final labels, numbered in order of first point: kept groups, then regions that are
  // large enough on their own.
  std::vector<int> out(n, -1);
  std::vector<int> region_id(static_cast<std::size_t>(n_in), -1), group_id(group_kept.size(), -1);
  int next = 0;
  std::vector<bool> flags;
  for (std::size_t i = 0; i < n; ++i) {
    if (labels[i] < 0) continue;
    if (group[i] >= 0 && group_kept[static_cast<std::size_t>(group[i])]) {
      int& id = group_id[static_cast<std::size_t>(group[i])];
      if (id < 0) {
        id = next++;
        flags.push_back(true);
      }
      out[i] = id;
    } else if (size[static_cast<std::size_t>(labels[i])] >= min_segment_points) {
      int& id = region_id[static_cast<std::size_t>(labels[i])];
      if (id < 0) {
        id = next++;
        flags.push_back(false);
      }
      out[i] = id;
    }
  }
  if (regions) *regions = next;
  if (rough) *rough = std::move(flags);
  return out;
}

std::size_t absorbGroundIntoRough(const KnnGraph& g, double max_neighbour_distance_m,
                                  const std::vector<bool>& region_is_rough, double min_fraction, int passes,
                                  std::vector<int>& labels, std::vector<bool>& ground) {
  const std::size_t n = labels.size();
  if (ground.size() != n || g.count.size() != n) {
    throw std::invalid_argument("absorbGroundIntoRough: graph, labels and ground mask sizes differ");
  }
  const float max_d2 = static_cast<float>(max_neighbour_distance_m * max_neighbour_distance_m);
  std::size_t moved = 0;
  std::vector<std::pair<std::size_t, int>> moves;
  for (int pass = 0; pass < passes; ++pass) {
    moves.clear();
    for (std::size_t i = 0; i < n; ++i) {
      if (!ground[i]) continue;
      // Votes for rough regions as a whole (a valley between two pieces of one rough
      // surface has both around it); the point joins the one most of them belong to.
      int near = 0, votes = 0;
      std::array<std::pair<int, int>, 4> tally{};  // (region, count), the first few seen
      int kinds = 0;
      forNeighboursWithin(g, i, max_d2, [&](std::size_t nb) {
        ++near;
        const int l = labels[nb];
        if (l < 0 || static_cast<std::size_t>(l) >= region_is_rough.size() || !region_is_rough[static_cast<std::size_t>(l)]) return;
        ++votes;
        int t = 0;
        while (t < kinds && tally[static_cast<std::size_t>(t)].first != l) ++t;
        if (t == kinds && kinds < static_cast<int>(tally.size())) tally[static_cast<std::size_t>(kinds++)] = {l, 0};
        if (t < kinds) ++tally[static_cast<std::size_t>(t)].second;
      });
      if (kinds > 0 && votes > min_fraction * near) {
        const auto best = std::max_element(tally.begin(), tally.begin() + kinds,
                                           [](const auto& a, const auto& b) { return a.second < b.second; });
        moves.emplace_back(i, best->first);
      }
    }
    if (moves.empty()) break;
    for (const auto& [i, region] : moves) {
      ground[i] = false;
      labels[i] = region;
    }
    moved += moves.size();
  }
  return moved;
}

int joinTouchingRoughRegions(const KnnGraph& g, double max_neighbour_distance_m, std::vector<bool>& region_is_rough,
                             std::vector<int>& labels, int* regions) {
  const std::size_t n = labels.size();
  if (g.count.size() != n || !regions || static_cast<std::size_t>(*regions) != region_is_rough.size()) {
    throw std::invalid_argument("joinTouchingRoughRegions: graph, labels and region counts differ");
  }
  std::vector<int> parent(region_is_rough.size());
  for (std::size_t r = 0; r < parent.size(); ++r) parent[r] = static_cast<int>(r);
  const auto root = [&](int r) {
    while (parent[static_cast<std::size_t>(r)] != r) r = parent[static_cast<std::size_t>(r)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(r)])];
    return r;
  };
  const auto rough = [&](int l) { return l >= 0 && region_is_rough[static_cast<std::size_t>(l)]; };
  const float max_d2 = static_cast<float>(max_neighbour_distance_m * max_neighbour_distance_m);
  int joins = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!rough(labels[i])) continue;
    forNeighboursWithin(g, i, max_d2, [&](std::size_t nb) {
      if (!rough(labels[nb])) return;
      const int a = root(labels[i]), b = root(labels[nb]);
      if (a == b) return;
      parent[static_cast<std::size_t>(std::max(a, b))] = std::min(a, b);
      ++joins;
    });
  }
  if (joins == 0) return 0;
  // Renumber: surviving regions keep their order.
  std::vector<int> new_id(parent.size(), -1);
  std::vector<bool> new_rough;
  for (std::size_t r = 0; r < parent.size(); ++r) {
    if (root(static_cast<int>(r)) != static_cast<int>(r)) continue;
    new_id[r] = static_cast<int>(new_rough.size());
    new_rough.push_back(region_is_rough[r]);
  }
  for (auto& l : labels) {
    if (l >= 0) l = new_id[static_cast<std::size_t>(root(l))];
  }
  region_is_rough.swap(new_rough);
  *regions = static_cast<int>(region_is_rough.size());
  return joins;
}

std::size_t reclaimGroundPoints(const std::vector<Eigen::Vector3f>& points, const KnnGraph& g,
                                double max_neighbour_distance_m, const Eigen::Vector4f& ground_plane,
                                const std::vector<Eigen::Vector4f>& region_planes, double min_angle_deg,
                                double max_angle_deg, double max_plane_distance_m, std::vector<int>& labels,
                                std::vector<bool>& ground, const std::vector<Eigen::Vector3f>* normals,
                                const std::vector<bool>* no_footprint) {
  const std::size_t n = points.size();
  if (labels.size() != n || ground.size() != n || g.count.size() != n) {
    throw std::invalid_argument("reclaimGroundPoints: points, graph, labels and ground mask sizes differ");
  }
  if (no_footprint && no_footprint->size() != region_planes.size()) {
    throw std::invalid_argument("reclaimGroundPoints: no_footprint and region_planes sizes differ");
  }
  const Eigen::Vector3f gn = ground_plane.head<3>().normalized();
  const float gd = ground_plane(3) / ground_plane.head<3>().norm();
  const double cos_min = std::cos(min_angle_deg * M_PI / 180.0);
  const double cos_max = std::cos(max_angle_deg * M_PI / 180.0);
  std::vector<bool> tilted(region_planes.size(), false);
  std::vector<Eigen::Vector4f> unit(region_planes.size());
  for (std::size_t r = 0; r < region_planes.size(); ++r) {
    const float len = region_planes[r].head<3>().norm();
    if (!(len > 0.f)) continue;
    unit[r] = region_planes[r] / len;
    const double c = std::abs(static_cast<double>(unit[r].head<3>().dot(gn)));
    tilted[r] = c < cos_min && c >= cos_max - 1e-9;
  }
  const float max_d2 = static_cast<float>(max_neighbour_distance_m * max_neighbour_distance_m);
  const float max_plane = static_cast<float>(max_plane_distance_m);
  std::vector<int> queue;
  for (std::size_t i = 0; i < n; ++i) {
    const int r = labels[i];
    if (r >= 0 && static_cast<std::size_t>(r) < tilted.size() && tilted[static_cast<std::size_t>(r)]) {
      queue.push_back(static_cast<int>(i));
    }
  }
  // Each tilted region's footprint on the ground: the side of the line where its plane
  // meets the ground plane on which the region rises, and its extent along that line.
  // Near the line the two planes are closer than the noise, so distances and normals
  // cannot tell the ramp's foot from the floor; the footprint can (the floor cannot lie
  // under the ramp), and it measures positions along the ground, which noise barely moves.
  struct Footprint {
    Eigen::Vector3f along = Eigen::Vector3f::Zero();  // direction of the line
    float rise_sign = 0.f;                             // sign of the region plane's value on the ramp side (0: unknown)
    float lo = std::numeric_limits<float>::max(), hi = std::numeric_limits<float>::lowest();
  };
  // Where the region's plane is this far above the ground plane: its fitted plane is off
  // by a few millimetres at its foot (a tilt error over half a metre of ramp), and
  // nearer the line that error alone would put floor points under the region.
  constexpr float kFootprintClearance = 0.007f;
  std::vector<Footprint> foot(region_planes.size());
  std::vector<double> height_sum(region_planes.size(), 0.0);  // region points' signed distance to the ground plane
  for (int idx : queue) {
    const auto i = static_cast<std::size_t>(idx);
    const auto r = static_cast<std::size_t>(labels[i]);
    Footprint& f = foot[r];
    if (f.along.isZero()) f.along = gn.cross(unit[r].head<3>()).normalized();
    const float a = f.along.dot(points[i]);
    f.lo = std::min(f.lo, a);
    f.hi = std::max(f.hi, a);
    height_sum[r] += gn.dot(points[i]) + gd;
  }
  for (std::size_t r = 0; r < region_planes.size(); ++r) {
    // A point p of the region at signed height h over the ground plane has its foot
    // p - h gn on the ground, where the region's plane has the value -h (nr . gn): the
    // sign of that value marks the side the region stands over (either orientation of
    // either plane).
    const double side = -height_sum[r] * static_cast<double>(unit[r].head<3>().dot(gn));
    const bool planar = !(no_footprint && (*no_footprint)[r]);
    foot[r].rise_sign = !planar ? 0.f : side > 0 ? 1.f : side < 0 ? -1.f : 0.f;
  }
  // +1: under the region (beyond the line by the clearance, between its sides); -1: in
  // front of the line by the clearance (the region's plane lies below the floor there);
  // 0: near the line or beside the region, where the distances and normals decide.
  const auto footprintSide = [&](std::size_t r, const Eigen::Vector3f& q) {
    const Footprint& f = foot[r];
    if (f.rise_sign == 0.f) return 0;
    const Eigen::Vector3f on_ground = q - (gn.dot(q) + gd) * gn;
    const float rise = f.rise_sign * (unit[r].head<3>().dot(on_ground) + unit[r](3));
    if (rise < -kFootprintClearance) return -1;
    // Half a centimetre of slack: the line's direction comes from the fitted plane, and a
    // tenth of a degree off it moves a corner of the ramp by about a millimetre.
    const float a = f.along.dot(q);
    return rise > kFootprintClearance && a >= f.lo - 0.005f && a <= f.hi + 0.005f ? 1 : 0;
  };
  std::size_t moved = 0;
  for (std::size_t head = 0; head < queue.size(); ++head) {
    const auto i = static_cast<std::size_t>(queue[head]);
    const auto r = static_cast<std::size_t>(labels[i]);
    const Eigen::Vector4f& pl = unit[r];
    forNeighboursWithin(g, i, max_d2, [&](std::size_t nb) {
      if (!ground[nb]) return;
      const Eigen::Vector3f& q = points[nb];
      const float to_region = std::abs(pl.head<3>().dot(q) + pl(3));
      const float to_ground = std::abs(gn.dot(q) + gd);
      if (to_region > max_plane) return;
      const int side = footprintSide(r, q);
      if (side < 0) return;
      if (side == 0) {
        if (to_region >= to_ground) return;
        if (normals && !(*normals)[nb].isZero() &&
            std::abs((*normals)[nb].dot(pl.head<3>())) <= std::abs((*normals)[nb].dot(gn))) {
          return;  // its normal says floor
        }
      }
      ground[nb] = false;
      labels[nb] = static_cast<int>(r);
      queue.push_back(static_cast<int>(nb));
      ++moved;
    });
  }
  return moved;
}

std::size_t adoptUnsegmentedPoints(const std::vector<Eigen::Vector3f>& points, const std::vector<Eigen::Vector3f>& normals,
                                   const KnnGraph& g, double max_neighbour_distance_m,
                                   const std::vector<Eigen::Vector4f>& region_planes,
                                   const std::vector<bool>& region_excluded, double max_plane_distance_m,
                                   double max_angle_deg, std::vector<int>& labels, const std::vector<bool>& ground) {
  const std::size_t n = points.size();
  if (labels.size() != n || ground.size() != n || normals.size() != n || g.count.size() != n) {
    throw std::invalid_argument("adoptUnsegmentedPoints: points, normals, graph, labels and ground mask sizes differ");
  }
  std::vector<Eigen::Vector4f> unit(region_planes.size(), Eigen::Vector4f::Zero());
  std::vector<bool> open(region_planes.size(), false);
  for (std::size_t r = 0; r < region_planes.size(); ++r) {
    const float len = region_planes[r].head<3>().norm();
    if (!(len > 0.f) || !region_planes[r].allFinite()) continue;
    unit[r] = region_planes[r] / len;
    open[r] = !(r < region_excluded.size() && region_excluded[r]);
  }
  const float max_d2 = static_cast<float>(max_neighbour_distance_m * max_neighbour_distance_m);
  const float max_plane = static_cast<float>(max_plane_distance_m);
  const float min_cos = static_cast<float>(std::cos(max_angle_deg * M_PI / 180.0));
  std::vector<int> orphans;
  for (std::size_t i = 0; i < n; ++i) {
    if (labels[i] < 0 && !ground[i] && !normals[i].isZero()) orphans.push_back(static_cast<int>(i));
  }
  // For each point, the orphans that have it as a neighbour (CSR): only those can
  // change their mind when it joins a region.
  std::vector<int> watch_start(n + 1, 0), watchers;
  for (std::size_t s = 0; s < orphans.size(); ++s) {
    prefetchRow(g, orphans, s + 8);
    forNeighboursWithin(g, static_cast<std::size_t>(orphans[s]), max_d2,
                        [&](std::size_t nb) { ++watch_start[nb + 1]; });
  }
  for (std::size_t i = 0; i < n; ++i) watch_start[i + 1] += watch_start[i];
  watchers.resize(static_cast<std::size_t>(watch_start[n]));
  {
    std::vector<int> fill(watch_start.begin(), watch_start.end() - 1);
    for (int o : orphans) {
      forNeighboursWithin(g, static_cast<std::size_t>(o), max_d2,
                          [&](std::size_t nb) { watchers[static_cast<std::size_t>(fill[nb]++)] = o; });
    }
  }
  // Rounds: each round, every orphan next to a region it fits joins the closest such
  // region (by distance to the plane), decided on the labels of the round before, so
  // the result does not depend on the order points are visited in. After the first
  // round only orphans next to a point that joined in the last round are looked at.
  std::size_t adopted = 0;
  std::vector<std::pair<int, int>> joins;
  std::vector<int> stamp;  // (assigned, not constructed: GCC 12 at -O3 warns falsely of a free otherwise)
  stamp.assign(n, -1);
  for (int round = 0; !orphans.empty(); ++round) {
    joins.clear();
    for (std::size_t s = 0; s < orphans.size(); ++s) {
      prefetchRow(g, orphans, s + 8);
      const int o = orphans[s];
      const auto j = static_cast<std::size_t>(o);
      const Eigen::Vector3f& q = points[j];
      int best = -1;
      float best_d = max_plane;
      forNeighboursWithin(g, j, max_d2, [&](std::size_t nb) {
        const int r = labels[nb];
        if (r < 0 || static_cast<std::size_t>(r) >= open.size() || !open[static_cast<std::size_t>(r)]) return;
        const Eigen::Vector4f& pl = unit[static_cast<std::size_t>(r)];
        const float d = std::abs(pl.head<3>().dot(q) + pl(3));
        if (d > best_d || (d == best_d && best >= 0 && r >= best)) return;
        if (std::abs(pl.head<3>().dot(normals[j])) < min_cos) return;
        best = r;
        best_d = d;
      });
      if (best >= 0) joins.emplace_back(o, best);
    }
    if (joins.empty()) break;
    for (const auto& [o, r] : joins) labels[static_cast<std::size_t>(o)] = r;
    adopted += joins.size();
    orphans.clear();
    for (const auto& jr : joins) {
      const auto a = static_cast<std::size_t>(jr.first);
      for (int w = watch_start[a]; w < watch_start[a + 1]; ++w) {
        const int o = watchers[static_cast<std::size_t>(w)];
        if (labels[static_cast<std::size_t>(o)] >= 0 || stamp[static_cast<std::size_t>(o)] == round) continue;
        stamp[static_cast<std::size_t>(o)] = round;
        orphans.push_back(o);
      }
    }
  }
  return adopted;
}

}  // namespace mobmap::perception
