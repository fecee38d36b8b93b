// End to end on the synthetic corridor with Kinect noise: render, perceive, fuse,
// and compare the map with the exact ground truth.
#include "io/ground_truth.hpp"
#include "io/simulation_writer.hpp"

#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/mapping/footstep_planner.hpp"
#include "mobmap/mapping/reachability.hpp"
#include "mobmap/perception/pipeline.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <fstream>
#include <set>

namespace mobmap {
namespace {

// Bounds of the per-surface check: the 0.1 mean error for every surface
// in view; 100 voxels and 85 % on the right side of 0.5 for each large one. Coarser
// perception voxels blur small surfaces and edges (the moving box's -y face
// most), and see the rough patch's 10 cm pyramids less rough.
struct SurfaceBounds {
  double mean_error = 0.1;
  double rough_patch_mean_error = 0.1;
  int large_surface_voxels = 100;
  double large_surface_right_side = 0.85;
};
// ctest runs each TEST in its own process, so the (expensive) map is built once, in
// one TEST, and checked in three parts.
struct CorridorMap {
  /// `edge_window_px`: the simulated sensor's edge model (KinectNoiseParams); 0 gives
  /// sharp depth edges.
  explicit CorridorMap(const perception::PerceptionParams& params = {}, int edge_window_px = 0) {
    sim::CorridorParams p;
    p.noise = sim::NoiseModel::kKinect;
    p.kinect.edge_window_px = edge_window_px;
    scene_ = new sim::CorridorScene(p);
    map_ = new mapping::MobilityMap();
    const perception::FramePipeline pipeline(params);
    // Every third frame: the moving box's old front face is in view for only ~30
    // frames after it leaves, and clamped occupancy needs ~9 misses to turn free.
    std::vector<long long> pixels_seen;
    for (int f = 0; f < p.frames; f += 3) {
      const auto r = scene_->render(f);
      app::countSurfacePixels(r, pixels_seen);
      const Eigen::Vector3f g = (r.T_world_camera.linear().transpose() * scene_->gravityDown()).cast<float>();
      const auto result = pipeline.process(r.depth, p.intrinsics, g);
      map_->integrate(result, r.T_world_camera, &r.depth, &p.intrinsics);
    }
    map_->finalize();
    const std::string path = (std::filesystem::temp_directory_path() / ("mobmap-truth-" + std::to_string(::getpid()) + ".json")).string();
    std::ofstream(path) << app::groundTruthJson(*scene_, &pixels_seen).dump();
    truth_ = new app::GroundTruth(app::loadGroundTruth(path));
    std::filesystem::remove(path);
  }
  ~CorridorMap() {
    delete truth_;
    delete map_;
    delete scene_;
  }
  sim::CorridorScene* scene_ = nullptr;
  mapping::MobilityMap* map_ = nullptr;
  app::GroundTruth* truth_ = nullptr;

  void walkableAndUntraversableSurfacesScoreAsTheTableSays(const SurfaceBounds& bounds = SurfaceBounds()) const;
  void theMovingBoxLeavesNoSurfaceAtItsOldPlace() const;
  void footprintsOnFloorAndAcrossTheStairs() const;
  void reachabilityFollowsStepsAndSlopes() const;
  void footstepPlansAgreeWithTheTruth() const;
};

// The true surface height and its expected mobility under (x, y): floor, stair treads,
// the ramps and the box top of the corridor (docs/SIMULATOR.md).
std::pair<double, double> trueSupport(double x, double y) {
  if (y > 0.4 && y < 1.4 && x >= 6.0 && x < 7.2) return {0.17 * (std::floor((x - 6.0) / 0.3) + 1), 1.0};
  if (y > 0.6 && y < 1.0 && x > 4.6 && x < 5.0) return {0.5, 1.0};
  if (y > -1.3 && y < -0.5) {
    for (int i = 0; i < 5; ++i) {
      const double x0 = 1.5 + 1.2 * i, deg = 5.0 + 10.0 * i;
      if (x >= x0 && x <= x0 + 0.6) return {(x - x0) * std::tan(deg * M_PI / 180), 1.0 - 0.25 * i};
    }
  }
  return {0.0, 1.0};
}

void CorridorMap::walkableAndUntraversableSurfacesScoreAsTheTableSays(const SurfaceBounds& bounds) const {
  const app::Evaluation ev = app::evaluateMap(*map_, *truth_, 3, 0.04);
  // The large surfaces must be well observed.
  const std::set<std::string> large = {"floor", "rough patch", "ramp 5 deg", "ramp 15 deg", "ramp 25 deg", "ramp 35 deg", "ramp 45 deg",
                                       "box top", "box -x face", "box -y face", "stair tread 1", "stair tread 2", "stair tread 3",
                                       "stair tread 4", "stair riser 1", "stair riser 2", "stair riser 3", "stair riser 4",
                                       "stair inner side", "moving box top", "moving box -x face", "moving box -y face"};
  int checked = 0;
  for (const auto& s : ev.surfaces) {
    if (large.count(s.surface->name)) {
      ASSERT_GE(s.voxels, bounds.large_surface_voxels) << s.surface->name << " was hardly observed";
      EXPECT_GE(s.right_side, bounds.large_surface_right_side) << s.surface->name;
    }
    // Every surface in view, down to 20 voxels (0.008 m2): the per-surface bound.
    if (s.voxels < 20) continue;
    ++checked;
    EXPECT_LE(s.mean_abs_error, s.surface->name == "rough patch" ? bounds.rough_patch_mean_error : bounds.mean_error)
        << s.surface->name << " (" << s.voxels << " voxels)";
  }
  EXPECT_GE(checked, static_cast<int>(large.size()));
  // Voxels on an edge between surfaces with different answers are scored apart; most
  // of them match one of the surfaces they touch.
  EXPECT_LE(ev.edge_mean_abs_error_any, 0.15);
  const int total = ev.true_traversable + ev.false_traversable + ev.true_untraversable + ev.false_untraversable;
  const int right = ev.true_traversable + ev.true_untraversable;
  EXPECT_GE(static_cast<double>(right) / total, 0.97);
  std::printf("[ info ] %d surfaces checked; right side of 0.5: %.1f %% of %d voxels; %d edge voxels, mean |err| %.3f "
              "(nearest surface) / %.3f (best surface they touch)\n",
              checked, 100.0 * right / total, total, ev.edge_voxels, ev.edge_mean_abs_error, ev.edge_mean_abs_error_any);
}

void CorridorMap::theMovingBoxLeavesNoSurfaceAtItsOldPlace() const {
  const auto& box = scene_->movingObstacle();
  int surface = 0, probed = 0;
  // Probe the old box volume above the floor voxels.
  for (double x = box.from.x() - 0.18; x <= box.from.x() + 0.18; x += 0.04) {
    for (double y = box.from.y() - 0.18; y <= box.from.y() + 0.18; y += 0.04) {
      for (double z = 0.05; z <= box.size.z(); z += 0.04) {
        ++probed;
        surface += map_->query({x, y, z}).state == mapping::VoxelState::kSurface;
      }
    }
  }
  EXPECT_GT(probed, 1000);
  EXPECT_EQ(surface, 0);
  // The floor where it stood was seen and is walkable.
  const auto floor = map_->snapDown({box.from.x(), box.from.y(), 0.1}, 0.2);
  ASSERT_TRUE(floor);
  EXPECT_GT(floor->mobility, 0.75);
}

void CorridorMap::footprintsOnFloorAndAcrossTheStairs() const {
  const auto flat = map_->footprint({1.0, 0.0, 0.0, 0.0, 0.25, 0.12});
  EXPECT_GT(flat.min_mobility, 0.75);
  EXPECT_GT(flat.known_fraction, 0.9);
  EXPECT_LT(flat.max_height_difference_m, 0.03);
  // A sole straddling the first riser (x = 6.0) spans a 17 cm step (searched 0.2 m either
  // side of the surface under its centre, the floor or the tread).
  const auto step = map_->footprint({6.0, 0.9, 0.1, 0.0, 0.25, 0.12}, 0.2, 0.2);
  EXPECT_GT(step.max_height_difference_m, 0.12);
  EXPECT_LT(step.min_mobility, 0.5);
  // Soles along the ramps (scene: ramp i rises along +x from x = 1.5 + 1.2 i over 0.6 m):
  // the support plane leans as the ramp does, to within a few degrees in 2 cm voxels.
  for (const int i : {1, 2, 3}) {
    const double angle = 5.0 + 10.0 * i, x = 1.5 + 1.2 * i + 0.3;
    const auto ramp = map_->footprint({x, -0.9, 0.3 * std::tan(angle * M_PI / 180), 0.0, 0.25, 0.12});
    ASSERT_TRUE(ramp.has_support_plane) << angle;
    std::printf("[ info ] ramp %.0f deg: support plane tilt %.1f deg, rms %.3f m\n", angle, ramp.support_tilt_deg,
                ramp.support_rms_m);
    EXPECT_NEAR(ramp.support_tilt_deg, angle, 4.0);
    EXPECT_LT(ramp.support_normal.x(), -0.2);  // leaning downhill, towards -x
  }
}

// The places of a rectangle of columns whose top face is within 5 cm of `height(x)`:
// the share of them that can be stood on, and that are reachable.
struct Share {
  int places = 0;
  double standable = 0, reachable = 0;
};
Share shareOf(const mapping::Reachability& r, double x0, double x1, double y0, double y1,
              const std::function<double(double)>& height) {
  Share s;
  for (const mapping::Place& p : r.places()) {
    if (p.x < x0 || p.x > x1 || p.y < y0 || p.y > y1 || std::abs(p.top_z - height(p.x)) > 0.05) continue;
    ++s.places;
    s.standable += p.standable;
    s.reachable += p.reachable;
  }
  if (s.places) s.standable /= s.places, s.reachable /= s.places;
  return s;
}

void CorridorMap::reachabilityFollowsStepsAndSlopes() const {
  const auto flat = [](double z) { return [z](double) { return z; }; };
  const auto ramp = [](int i) {  // ramp i rises along +x from x = 1.5 + 1.2 i over 0.6 m
    return [i](double x) { return (x - 1.5 - 1.2 * i) * std::tan((5.0 + 10.0 * i) * M_PI / 180); };
  };
  for (const double step : {0.15, 0.20}) {
    SCOPED_TRACE(step);
    mapping::ReachParams p;
    p.robot.max_step_m = step;
    // From the floor in front of the walk's first camera position.
    const mapping::Reachability r = mapping::computeReachability(map_->tree(), {1.2, 0.0, 0.05}, p);
    ASSERT_TRUE(r.start());
    EXPECT_NEAR(r.footPlaces()[*r.start()].z, 0.01, 0.03);
    // The walking path, the moving box's old place included, and the ramps that score walkable.
    const Share path = shareOf(r, 1.0, 5.5, -0.3, 0.3, flat(0.01));
    EXPECT_GT(path.places, 5000);
    EXPECT_GT(path.reachable, 0.95);
    for (const int i : {0, 1}) {
      const Share s = shareOf(r, 1.6 + 1.2 * i, 2.0 + 1.2 * i, -1.2, -0.6, ramp(i));
      EXPECT_GT(s.places, 100) << "ramp " << i;
      EXPECT_GT(s.reachable, 0.9) << "ramp " << i;
    }
    // The 45-degree ramp cannot be stood on at all; the box top can, but not reached.
    const Share steep = shareOf(r, 6.4, 6.8, -1.2, -0.6, ramp(4));
    EXPECT_GT(steep.places, 100);
    EXPECT_LT(steep.standable, 0.05);
    EXPECT_EQ(steep.reachable, 0.0);
    const Share box = shareOf(r, 4.65, 4.95, 0.65, 0.95, flat(0.5));
    EXPECT_GT(box.places, 100);
    EXPECT_GT(box.standable, 0.9);
    EXPECT_EQ(box.reachable, 0.0);
    std::printf("[ info ] steps up to %.2f m: reachable: walking path %.1f %%, ramp 5 deg %.1f %%, ramp 15 deg %.1f %%; box top "
                "standable %.1f %%; stair treads", step, 100 * path.reachable, 100 * shareOf(r, 1.6, 2.0, -1.2, -0.6, ramp(0)).reachable,
                100 * shareOf(r, 2.8, 3.2, -1.2, -0.6, ramp(1)).reachable, 100 * box.standable);
    // 17 cm risers: the stairs are out of reach for 15 cm steps and within reach for 20.
    for (int k = 1; k <= 4; ++k) {
      const Share tread = shareOf(r, 6.0 + 0.3 * (k - 1) + 0.04, 6.3 + 0.3 * (k - 1) - 0.04, 0.45, 1.35, flat(0.17 * k));
      std::printf(" %.1f/%.1f %%", 100 * tread.standable, 100 * tread.reachable);
      EXPECT_GT(tread.places, 100) << "tread " << k;
      EXPECT_GT(tread.standable, 0.8) << "tread " << k;
      if (step < 0.17) {
        EXPECT_EQ(tread.reachable, 0.0) << "tread " << k;
      } else {
        EXPECT_GT(tread.reachable, 0.8) << "tread " << k;
      }
    }
    std::printf(" (standable/reachable)\n");
  }
  footstepPlansAgreeWithTheTruth();
}

// Footstep plans over the noisy map, checked against the scene's exact surfaces: every
// footstep on a true surface (its support within the voxel above it) whose expected
// mobility passes; successive supports within max_step; the stairs climbed on every tread
// with 20 cm steps and refused with 15; never onto the box; up the 15-degree ramp.
void CorridorMap::footstepPlansAgreeWithTheTruth() const {
  const auto check = [](const mapping::Plan& plan, const mapping::PlanParams& p) {
    for (std::size_t i = 0; i < plan.footsteps.size(); ++i) {
      const auto& f = plan.footsteps[i];
      const auto [z, mobility] = trueSupport(f.x, f.y);
      EXPECT_NEAR(f.z, z + 0.01, 0.025) << "footstep " << i << " at " << f.x << " " << f.y;
      EXPECT_GE(mobility, p.robot.min_mobility) << "footstep " << i;
      if (i > 0) {
        EXPECT_LE(std::abs(f.z - plan.footsteps[i - 1].z), p.robot.max_step_m) << "footstep " << i;
      }
    }
  };
  mapping::PlanParams p;
  p.robot.max_step_m = 0.2;
  const mapping::Plan stairs = mapping::planFootsteps(map_->tree(), {5.6, 0.9, 0.0}, {7.05, 0.9, 0.68}, p);
  ASSERT_TRUE(stairs.found) << stairs.reason;
  check(stairs, p);
  for (int k = 1; k <= 4; ++k) {
    bool on = false;
    for (const auto& f : stairs.footsteps) on = on || std::abs(f.z - 0.17 * k - 0.01) < 0.025;
    EXPECT_TRUE(on) << "tread " << k;
  }
  // Too low a limit: the reason gives the measured rise (a 17 cm riser, the soles'
  // heights known to a voxel), the limit as given and what the step needed.
  std::string low_reason;
  for (const double limit : {0.15, 0.155}) {
    p.robot.max_step_m = limit;
    const mapping::Plan low = mapping::planFootsteps(map_->tree(), {5.6, 0.9, 0.0}, {7.05, 0.9, 0.68}, p);
    if (limit == 0.15) low_reason = low.reason;
    EXPECT_FALSE(low.found);
    double rise = 0, z0 = 0, z1 = 0, x = 0, y = 0, voxel = 0, needs = 0;
    char limit_text[16] = {};
    ASSERT_EQ(std::sscanf(low.reason.c_str(),
                          "the step up on the easiest way there measures %lf m, from a sole resting at z = %lf m to one at "
                          "z = %lf m (near x = %lf, y = %lf; each height known to one voxel, %lf m); a step passes when its "
                          "measured rise plus one voxel to spare is at most `max_step_m` %15[0-9.]: this one needs %lf m",
                          &rise, &z0, &z1, &x, &y, &voxel, limit_text, &needs),
              8)
        << low.reason;
    EXPECT_NEAR(rise, z1 - z0, 1e-9) << low.reason;  // the numbers add up as printed
    EXPECT_NEAR(rise, 0.17, 0.02 + 1e-6) << low.reason;  // within a voxel of the true riser
    EXPECT_DOUBLE_EQ(voxel, 0.02);
    EXPECT_EQ(std::string(limit_text), limit == 0.15 ? "0.15" : "0.155");
    EXPECT_NEAR(needs, rise + voxel, 1e-9);
    EXPECT_GT(needs, limit);
  }
  p.robot.max_step_m = 0.15;
  const mapping::Plan box = mapping::planFootsteps(map_->tree(), {4.0, 0.5, 0.0}, {4.8, 0.8, 0.5}, p);
  EXPECT_FALSE(box.found);
  const mapping::Plan ramp = mapping::planFootsteps(map_->tree(), {2.2, -0.9, 0.0}, {3.2, -0.9, 0.14}, p);
  ASSERT_TRUE(ramp.found) << ramp.reason;
  check(ramp, p);
  bool on_ramp = false;
  for (const auto& f : ramp.footsteps) on_ramp = on_ramp || (f.x > 2.75 && f.x < 3.25 && f.z > 0.04);
  EXPECT_TRUE(on_ramp);
  std::printf("[ info ] plans: stairs %zu footsteps (%zu expansions), ramp %zu footsteps; 15 cm steps: %s\n",
              stairs.footsteps.size(), stairs.expansions, ramp.footsteps.size(), low_reason.c_str());
}

TEST(CorridorMap, FusedKinectSequenceMatchesTheGroundTruth) {
  const CorridorMap m;
  {
    SCOPED_TRACE("surface scores");
    m.walkableAndUntraversableSurfacesScoreAsTheTableSays();
  }
  {
    SCOPED_TRACE("moving box");
    m.theMovingBoxLeavesNoSurfaceAtItsOldPlace();
  }
  {
    SCOPED_TRACE("footprints");
    m.footprintsOnFloorAndAcrossTheStairs();
  }
}

// The sensor's depth edges (a 9 px correlation window, mixed pixels, the projector's
// shadow) leave voxels part way up the risers and round the 10 cm pyramids of the rough
// patch (which then read less rough: the surface scores above use sharp edges). Foot-scale
// reachability and plans must stay right on such a map.
TEST(CorridorMap, FootholdsAndPlansHoldWithTheSensorsRoundedEdges) {
  const CorridorMap m({}, sim::KinectNoiseParams{}.edge_window_px);
  m.reachabilityFollowsStepsAndSlopes();
}

// `--voxel 0.02` (perception in 2 cm voxels, the map's resolution, ~3x faster): as
// many voxels on the right side of 0.5, but small surfaces and edges blur and the
// rough patch reads less rough (docs/PERCEPTION.md, "Coarser voxels", has the numbers).
TEST(CorridorMap, TwoCentimetrePerceptionVoxelsMatchTheGroundTruthToo) {
  const CorridorMap m(perception::scaledToVoxel(perception::PerceptionParams{}, 0.02));
  {
    SCOPED_TRACE("surface scores");
    SurfaceBounds coarse;
    coarse.mean_error = 0.25;
    coarse.rough_patch_mean_error = 0.2;
    coarse.large_surface_voxels = 50;
    coarse.large_surface_right_side = 0.75;
    m.walkableAndUntraversableSurfacesScoreAsTheTableSays(coarse);
  }
  {
    SCOPED_TRACE("moving box");
    m.theMovingBoxLeavesNoSurfaceAtItsOldPlace();
  }
  {
    SCOPED_TRACE("footprints");
    m.footprintsOnFloorAndAcrossTheStairs();
  }
}

}  // namespace
}  // namespace mobmap
