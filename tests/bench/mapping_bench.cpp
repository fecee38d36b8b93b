// Fusion, query and memory of the MobilityMap against stock OctoMap on the same
// points, in one run. Prints medians and ratios. Release builds only.
//
//   mapping_bench [SEVEN_SCENES_DIR] [FRAMES]
//
// Without a directory it renders the synthetic corridor (Kinect noise).
#include "io/dataset.hpp"

#include "mobmap/mapping/gravity.hpp"
#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/perception/pipeline.hpp"
#include "mobmap/sim/corridor_scene.hpp"

#include <octomap/OcTree.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

using namespace mobmap;
using Clock = std::chrono::steady_clock;

namespace {

double ms(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double, std::milli>(b - a).count(); }

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

struct Frame {
  perception::DepthImage depth;
  perception::PinholeIntrinsics k;
  Eigen::Isometry3d T_world_camera;
  Eigen::Vector3f gravity_camera;
};

}  // namespace

int main(int argc, char** argv) {
#ifndef NDEBUG
  std::fprintf(stderr, "warning: this is not a Release build; the numbers mean little\n");
#endif
  const std::string dir = argc > 1 ? argv[1] : "";
  const int n_frames = argc > 2 ? std::atoi(argv[2]) : 30;
  std::vector<Frame> frames;
  Eigen::Vector3d g_world(0, 0, -1);
  if (!dir.empty()) {
    const app::SevenScenesDirectory d(dir);
    if (d.gravityDown()) g_world = *d.gravityDown();
    const auto& nums = d.frameNumbers();
    const int step = std::max<int>(1, static_cast<int>(nums.size()) / n_frames);
    for (std::size_t i = 0; i < nums.size() && static_cast<int>(frames.size()) < n_frames; i += static_cast<std::size_t>(step)) {
      Frame f;
      f.depth = d.readDepth(nums[i]);
      f.k = d.intrinsics();
      f.T_world_camera.matrix() = d.readPose(nums[i]);
      f.T_world_camera.linear() = mapping::nearestRotation(f.T_world_camera.linear());
      f.gravity_camera = (f.T_world_camera.linear().transpose() * g_world).cast<float>();
      frames.push_back(std::move(f));
    }
  } else {
    sim::CorridorParams p;
    p.noise = sim::NoiseModel::kKinect;
    const sim::CorridorScene scene(p);
    for (int i = 0; i < n_frames; ++i) {
      const auto r = scene.render(i * (p.frames / n_frames));
      frames.push_back({r.depth, p.intrinsics, r.T_world_camera,
                        (r.T_world_camera.linear().transpose() * scene.gravityDown()).cast<float>()});
    }
  }
  std::printf("mapping benchmark: %zu frames of %s, resolution 0.02 m, max range 3 m\n", frames.size(),
              dir.empty() ? "the synthetic corridor (Kinect noise)" : dir.c_str());

  // Perception once per frame (not timed here: see perception_bench).
  const perception::FramePipeline pipeline;
  std::vector<perception::FrameResult> results;
  for (const auto& f : frames) results.push_back(pipeline.process(f.depth, f.k, f.gravity_camera));

  const Eigen::Matrix3d R_map_world = mapping::gravityAlignment(g_world);
  mapping::MapParams mp;
  mp.max_range_m = 3.0;
  mapping::MobilityMap ours(mp, R_map_world);
  octomap::OcTree exact(0.02), discretized(0.02);
  std::vector<double> t_ours, t_exact, t_disc, t_ours_rays;
  mapping::MapParams rays_params = mp;
  rays_params.free_space_ray_stride_px = 16;
  mapping::MobilityMap with_rays(rays_params, R_map_world);
  // The same points for OctoMap: each frame's reduced, denoised points, in the map frame.
  std::vector<octomap::Pointcloud> clouds(frames.size());
  std::vector<octomap::point3d> origins(frames.size());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    Eigen::Isometry3d T_map_camera = frames[i].T_world_camera;
    T_map_camera.linear() = R_map_world * frames[i].T_world_camera.linear();
    T_map_camera.translation() = R_map_world * frames[i].T_world_camera.translation();
    for (const auto& p : results[i].points) {
      const Eigen::Vector3d q = T_map_camera * p.cast<double>();
      clouds[i].push_back(static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z()));
    }
    origins[i] = octomap::point3d(static_cast<float>(T_map_camera.translation().x()),
                                  static_cast<float>(T_map_camera.translation().y()),
                                  static_cast<float>(T_map_camera.translation().z()));
  }
  // Each method in its own pass over all frames, so none runs with the others' data in
  // its caches (interleaving them per frame tripled our time).
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const auto t0 = Clock::now();
    ours.integrate(results[i], frames[i].T_world_camera, &frames[i].depth, &frames[i].k);
    t_ours.push_back(ms(t0, Clock::now()));
  }
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const auto t0 = Clock::now();
    with_rays.integrate(results[i], frames[i].T_world_camera, &frames[i].depth, &frames[i].k);
    t_ours_rays.push_back(ms(t0, Clock::now()));
  }
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const auto t0 = Clock::now();
    exact.insertPointCloud(clouds[i], origins[i], 3.0, false, false);
    t_exact.push_back(ms(t0, Clock::now()));
  }
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const auto t0 = Clock::now();
    discretized.insertPointCloud(clouds[i], origins[i], 3.0, false, true);
    t_disc.push_back(ms(t0, Clock::now()));
  }
  ours.finalize();
  const double mo = median(t_ours), me = median(t_exact), md = median(t_disc), mr = median(t_ours_rays);
  std::printf("\nfusion per frame (median ms), free space included:\n");
  std::printf("  mobmap (surface + projection clearing)      %8.2f\n", mo);
  std::printf("  mobmap with free-space rays every 16 px     %8.2f\n", mr);
  std::printf("  OcTree::insertPointCloud discretize=false   %8.2f   ratio %.1fx\n", me, me / mo);
  std::printf("  OcTree::insertPointCloud discretize=true    %8.2f   ratio %.1fx\n", md, md / mo);

  // Point queries on the same voxels: mobmap's query() vs OcTree::search on a tree
  // holding exactly the occupied voxels of ours.
  octomap::OcTree same(0.02);
  std::vector<octomap::point3d> pts;
  for (auto it = ours.tree().begin_leafs(); it != ours.tree().end_leafs(); ++it) {
    if (!ours.tree().isNodeOccupied(*it)) continue;
    same.updateNode(it.getKey(), it->getLogOdds(), true);
    pts.push_back(it.getCoordinate());
  }
  same.updateInnerOccupancy();
  std::mt19937 rng(1);
  std::shuffle(pts.begin(), pts.end(), rng);
  pts.resize(std::min<std::size_t>(pts.size(), 200000));
  std::vector<double> q_ours, q_stock;
  volatile double sink = 0;
  auto timeOurs = [&] {
    const auto a = Clock::now();
    for (const auto& p : pts) sink = sink + ours.query({p.x(), p.y(), p.z()}).mobility;
    q_ours.push_back(pts.size() / (ms(a, Clock::now()) / 1000.0));
  };
  auto timeStock = [&] {
    const auto a = Clock::now();
    for (const auto& p : pts) {
      const auto* n = same.search(p);
      sink = sink + (n ? n->getValue() : 0.f);
    }
    q_stock.push_back(pts.size() / (ms(a, Clock::now()) / 1000.0));
  };
  for (int rep = 0; rep < 6; ++rep) {  // alternate which runs first, so neither gets the warm cache
    if (rep % 2) {
      timeOurs();
      timeStock();
    } else {
      timeStock();
      timeOurs();
    }
  }
  std::printf("\npoint queries per second (median of 6 x %zu): mobmap %.3g, OcTree::search %.3g, ratio %.2f\n", pts.size(),
              median(q_ours), median(q_stock), median(q_ours) / median(q_stock));
  std::vector<double> f_rate;
  for (int rep = 0; rep < 5; ++rep) {
    auto a = Clock::now();
    const int n = 2000;
    for (int i = 0; i < n; ++i) {
      const auto& p = pts[static_cast<std::size_t>(i) % pts.size()];
      sink = sink + ours.footprint({p.x(), p.y(), p.z(), 0.3 * i, 0.25, 0.12}).min_mobility;
    }
    f_rate.push_back(n / (ms(a, Clock::now()) / 1000.0));
  }
  std::printf("footprint queries per second (25 x 12 cm sole, 2 cm samples, median of 5): %.3g\n", median(f_rate));

  std::printf("\nmemory: node %zu B (OcTree node %zu B); %zu nodes, memoryUsage %.2f MB vs OcTree with the same voxels %zu nodes %.2f MB, ratio %.3f\n",
              sizeof(mapping::MobilityOcTreeNode), sizeof(octomap::OcTreeNode), ours.tree().size(),
              ours.tree().memoryUsage() / 1e6, same.size(), same.memoryUsage() / 1e6,
              static_cast<double>(ours.tree().memoryUsage()) / std::max<std::size_t>(1, same.memoryUsage()));
  std::printf("(the OcTree above holds the occupied voxels only; ours also holds cleared free voxels: %zu leaves vs %zu)\n",
              ours.tree().getNumLeafNodes(), same.getNumLeafNodes());
  return 0;
}
