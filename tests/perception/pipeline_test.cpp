// The whole pipeline on the synthetic corridor, with exact ground truth, and its parameters.
#include "perception_support.hpp"

namespace mobmap::perception {
namespace {

// --- End to end on the corridor ------------------------------------------------

struct Truth {
  std::map<int, int> points_of_surface;             // ground-truth id -> labelled pixels with a point
  std::map<int, std::map<int, int>> segment_votes;  // ground-truth id -> segment -> points
};

// Assigns each reduced point the majority ground-truth label of its pixels.
Truth overlap(const sim::CorridorScene& scene, const sim::RenderedFrame& r, const FrameResult& res) {
  std::vector<std::map<int, int>> votes(res.points.size());
  for (std::size_t px = 0; px < res.point_of_pixel.size(); ++px) {
    const int p = res.point_of_pixel[px];
    if (p >= 0 && r.labels[px] > 0) ++votes[static_cast<std::size_t>(p)][r.labels[px]];
  }
  Truth t;
  for (std::size_t p = 0; p < votes.size(); ++p) {
    if (votes[p].empty()) continue;
    const int id = std::max_element(votes[p].begin(), votes[p].end(),
                                    [](const auto& a, const auto& b) { return a.second < b.second; })->first;
    ++t.points_of_surface[id];
    if (res.segment_of_point[p] >= 0) ++t.segment_votes[id][res.segment_of_point[p]];
  }
  (void)scene;
  return t;
}

class CorridorFrames : public ::testing::TestWithParam<sim::NoiseModel> {};

TEST_P(CorridorFrames, RampSlopesFloorRoughnessAndGround) {
  sim::CorridorParams params;
  params.noise = GetParam();
  params.kinect.edge_window_px = 0;  // per-frame accuracy on sharp edges (edges: CorridorMap.FootholdsAndPlans...)
  const sim::CorridorScene scene(params);
  const FramePipeline pipeline;
  std::map<int, std::vector<double>> slope_errors;  // ramp id -> errors
  std::vector<double> floor_roughness;
  for (int frame : {0, 30, 60, 90, 120}) {
    const auto r = scene.render(frame);
    const Eigen::Vector3f g_cam = (r.T_world_camera.linear().transpose() * scene.gravityDown()).cast<float>();
    const FrameResult res = pipeline.process(r.depth, params.intrinsics, g_cam);
    ASSERT_TRUE(res.ground_plane) << "frame " << frame;
    // The ground is the floor: its distance is the camera height.
    EXPECT_NEAR((*res.ground_plane)(3), r.T_world_camera.translation().z(), 0.03) << "frame " << frame;
    const Truth t = overlap(scene, r, res);
    for (const auto& [id, segs] : t.segment_votes) {
      const auto& s = scene.surface(id);
      const auto best = std::max_element(segs.begin(), segs.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
      const Segment& seg = res.segments[static_cast<std::size_t>(best->first)];
      if (s.kind == sim::SurfaceKind::kRamp && best->second >= 500) {
        slope_errors[id].push_back(std::abs(seg.slope_deg - s.slope_deg));
      }
      if (s.kind == sim::SurfaceKind::kFloor && seg.is_ground) {
        // Floor within 2 m of the camera (the spec's range for the noisy bound).
        floor_roughness.push_back(seg.roughness);
      }
    }
  }
  ASSERT_GE(slope_errors.size(), 4u);
  for (const auto& [id, errors] : slope_errors) {
    std::vector<double> e = errors;
    std::sort(e.begin(), e.end());
    const double median = e[e.size() / 2];
    if (GetParam() == sim::NoiseModel::kNone) {
      EXPECT_LE(e.back(), 0.3) << scene.surface(id).name;
    } else {
      EXPECT_LE(median, 1.5) << scene.surface(id).name;
    }
  }
  ASSERT_FALSE(floor_roughness.empty());
  for (double r : floor_roughness) {
    if (GetParam() == sim::NoiseModel::kNone) {
      EXPECT_NEAR(r, 1.0, 0.01);
    } else {
      EXPECT_LE(r, 1.05);
    }
  }
}

TEST_P(CorridorFrames, SurfacesAreCoveredByOneSegmentEach) {
  sim::CorridorParams params;
  params.noise = GetParam();
  params.kinect.edge_window_px = 0;  // per-frame accuracy on sharp edges (edges: CorridorMap.FootholdsAndPlans...)
  const sim::CorridorScene scene(params);
  const FramePipeline pipeline;
  // Per surface over several frames: points seen, points in its best segment, and the
  // labelled points of that segment (purity: the share of them that are this surface).
  std::map<int, std::pair<int, int>> cover;
  std::map<int, int> best_segment_size;
  for (int frame : {0, 45, 90, 135}) {
    const auto r = scene.render(frame);
    const Eigen::Vector3f g = (r.T_world_camera.linear().transpose() * scene.gravityDown()).cast<float>();
    const FrameResult res = pipeline.process(r.depth, params.intrinsics, g);
    const Truth t = overlap(scene, r, res);
    std::map<int, int> segment_size;  // labelled points per segment
    for (const auto& [id, votes] : t.segment_votes) {
      for (const auto& [seg, v] : votes) segment_size[seg] += v;
    }
    for (const auto& [id, n] : t.points_of_surface) {
      if (n < 500) continue;  // the spec's visibility threshold
      int best = 0, best_seg = -1;
      const auto it = t.segment_votes.find(id);
      if (it != t.segment_votes.end()) {
        for (const auto& [seg, votes] : it->second) {
          if (votes > best) best = votes, best_seg = seg;
        }
      }
      cover[id].first += n;
      cover[id].second += best;
      if (best_seg >= 0) best_segment_size[id] += segment_size[best_seg];
    }
  }
  // Every surface is covered >= 90 % by one segment except a known gap under noise,
  // printed and recorded in docs/PERCEPTION.md: the first riser (far, 15 cm tall) breaks up.
  const bool noisy = GetParam() != sim::NoiseModel::kNone;
  const std::set<std::string> gaps = noisy ? std::set<std::string>{"stair riser 1"} : std::set<std::string>{};
  int asserted = 0;
  for (const auto& [id, c] : cover) {
    const double frac = static_cast<double>(c.second) / c.first;
    const double purity = static_cast<double>(c.second) / std::max(1, best_segment_size[id]);
    const std::string& name = scene.surface(id).name;
    std::printf("[ info ] %-22s %6d points, %5.1f %% in one segment, purity %5.1f %%%s\n", name.c_str(), c.first,
                100 * frac, 100 * purity, gaps.count(name) ? " (known gap)" : "");
    if (!gaps.count(name)) {
      EXPECT_GE(frac, 0.9) << name;
      EXPECT_GE(purity, 0.9) << name;
      ++asserted;
    }
  }
  EXPECT_GE(asserted, 10);  // of 13 surfaces with >= 500 points
}

INSTANTIATE_TEST_SUITE_P(NoiseOffAndOn, CorridorFrames,
                         ::testing::Values(sim::NoiseModel::kNone, sim::NoiseModel::kKinect),
                         [](const auto& param_info) { return param_info.param == sim::NoiseModel::kNone ? "Exact" : "Kinect"; });

TEST(FramePipeline, OnePipelineServesSeveralThreadsWithIdenticalResults) {
  // `mobmap build` runs two frames through one const pipeline at once.
  sim::CorridorParams params;
  params.noise = sim::NoiseModel::kKinect;
  const sim::CorridorScene scene(params);
  const FramePipeline pipeline;
  const int frames[] = {10, 40, 70};
  std::vector<FrameResult> alone;
  for (int f : frames) alone.push_back(pipeline.process(scene.render(f).depth, params.intrinsics));
  std::vector<std::vector<FrameResult>> together(2);
  std::vector<std::thread> threads;
  for (std::size_t t = 0; t < together.size(); ++t) {
    threads.emplace_back([&, t] {
      for (int f : frames) together[t].push_back(pipeline.process(scene.render(f).depth, params.intrinsics));
    });
  }
  for (auto& th : threads) th.join();
  for (const auto& run : together) {
    ASSERT_EQ(run.size(), alone.size());
    for (std::size_t i = 0; i < run.size(); ++i) {
      EXPECT_EQ(run[i].points, alone[i].points);
      ASSERT_EQ(run[i].segments.size(), alone[i].segments.size());
      EXPECT_GT(run[i].segments.size(), 3u);
      for (std::size_t s = 0; s < run[i].segments.size(); ++s) {
        EXPECT_EQ(run[i].segments[s].points, alone[i].segments[s].points);
        EXPECT_EQ(run[i].segments[s].mobility, alone[i].segments[s].mobility);
      }
    }
  }
}

TEST(FramePipeline, PerGroundConeResultsAreThoseOfAPipelineWithThatCone) {
  // `mobmap build` checks gravity against the floor in a 10-degree cone and perceives the
  // same frames for the run with its own cone, sharing the stages before the ground.
  sim::CorridorParams params;
  params.noise = sim::NoiseModel::kKinect;
  const sim::CorridorScene scene(params);
  PerceptionParams narrow;
  narrow.ground_max_tilt_deg = 10.0;
  const FramePipeline shared(narrow);
  int grounds_differ = 0;
  for (const int f : {10, 60, 150}) {
    const auto r = scene.render(f);
    const Eigen::Vector3f down = (r.T_world_camera.linear().transpose() * scene.gravityDown()).cast<float>();
    // A gravity hint 15 degrees off: the 10- and 40-degree cones then find different grounds.
    const Eigen::Vector3f tilted = Eigen::AngleAxisf(0.26f, Eigen::Vector3f::UnitX()) * down;
    for (const Eigen::Vector3f& g : {down, tilted}) {
      const std::vector<double> cones = {10.0, 20.0, 40.0};
      const std::vector<FrameResult> both = shared.processPerGroundCone(r.depth, params.intrinsics, g, cones);
      ASSERT_EQ(both.size(), cones.size());
      for (std::size_t c = 0; c < cones.size(); ++c) {
        PerceptionParams own;
        own.ground_max_tilt_deg = cones[c];
        const FrameResult alone = FramePipeline(own).process(r.depth, params.intrinsics, g);
        const FrameResult& got = both[c];
        SCOPED_TRACE("frame " + std::to_string(f) + " cone " + std::to_string(cones[c]));
        EXPECT_EQ(got.points, alone.points);
        EXPECT_EQ(got.normals, alone.normals);
        EXPECT_EQ(got.segment_of_point, alone.segment_of_point);
        EXPECT_EQ(got.point_of_pixel, alone.point_of_pixel);
        ASSERT_EQ(got.ground_plane.has_value(), alone.ground_plane.has_value());
        if (got.ground_plane) {
          EXPECT_EQ(*got.ground_plane, *alone.ground_plane);
        }
        ASSERT_EQ(got.segments.size(), alone.segments.size());
        for (std::size_t s = 0; s < got.segments.size(); ++s) {
          EXPECT_EQ(got.segments[s].points, alone.segments[s].points);
          EXPECT_EQ(got.segments[s].mobility, alone.segments[s].mobility);
          EXPECT_EQ(got.segments[s].roughness, alone.segments[s].roughness);
        }
        EXPECT_EQ(got.range.median_range_m, alone.range.median_range_m);
        EXPECT_EQ(got.range.lowest.has_value(), alone.range.lowest.has_value());
        EXPECT_EQ(got.stages.size(), alone.stages.size());
      }
      grounds_differ += both[0].segment_of_point != both[2].segment_of_point;
    }
  }
  EXPECT_GT(grounds_differ, 0);  // the cones did make a difference somewhere
  EXPECT_THROW((void)shared.processPerGroundCone(scene.render(0).depth, params.intrinsics, std::nullopt, {}), std::invalid_argument);
  EXPECT_THROW((void)shared.processPerGroundCone(scene.render(0).depth, params.intrinsics, std::nullopt, {95.0}),
               std::invalid_argument);
}

TEST(FramePipeline, FloorIsChosenAsGroundEvenWhenAWallHasMorePoints) {
  // Camera 1.3 m above a floor, looking at a wall 2.2 m ahead that fills most of the view.
  std::vector<sim::Triangle> tris = {
      {{-3, -1, 0}, {3, -1, 0}, {3, 2.2, 0}, 1}, {{-3, -1, 0}, {3, 2.2, 0}, {-3, 2.2, 0}, 1},  // floor z = 0
      {{-3, 2.2, 0}, {3, 2.2, 0}, {3, 2.2, 3}, 2}, {{-3, 2.2, 0}, {3, 2.2, 3}, {-3, 2.2, 3}, 2}};  // wall y = 2.2
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  Eigen::Matrix3d rot;
  const double pitch = 20 * kDeg;  // looking along +y, slightly down
  const Eigen::Vector3d fwd(0, std::cos(pitch), -std::sin(pitch)), right(1, 0, 0);
  rot.col(0) = right;
  rot.col(1) = fwd.cross(right);
  rot.col(2) = fwd;
  T.linear() = rot;
  T.translation() = Eigen::Vector3d(0, 0, 1.3);
  const PinholeIntrinsics k;
  const auto rc = sim::castRays(tris, k, T);
  int floor_px = 0, wall_px = 0;
  for (auto l : rc.labels) {
    floor_px += l == 1;
    wall_px += l == 2;
  }
  ASSERT_GT(wall_px, 2 * floor_px);
  ASSERT_GT(floor_px, 20000);
  const FramePipeline pipeline;
  const Eigen::Vector3f g_cam = (rot.transpose() * Eigen::Vector3d(0, 0, -1)).cast<float>();
  const FrameResult with_gravity = pipeline.process(rc.depth, k, g_cam);
  ASSERT_TRUE(with_gravity.ground_plane);
  EXPECT_NEAR((*with_gravity.ground_plane)(3), 1.3, 0.02);
  EXPECT_GT(with_gravity.ground_plane->head<3>().dot(-g_cam), 0.99f);
  EXPECT_EQ(with_gravity.reference, SlopeReference::kGravity);
}

// A camera 1.3 m above the floor (z = 0) of a room, looking along +y and pitched down
// by `pitch_deg` (negative: up); its pose and the frame it sees.
struct PitchedView {
  Eigen::Matrix3d rot;
  sim::RayCastResult rc;
  int pixels(int label) const { return static_cast<int>(std::count(rc.labels.begin(), rc.labels.end(), label)); }
};
PitchedView pitchedView(const std::vector<sim::Triangle>& tris, double pitch_deg) {
  PitchedView v;
  const double pitch = pitch_deg * kDeg;
  const Eigen::Vector3d fwd(0, std::cos(pitch), -std::sin(pitch)), right(1, 0, 0);
  v.rot.col(0) = right;
  v.rot.col(1) = fwd.cross(right);
  v.rot.col(2) = fwd;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = v.rot;
  T.translation() = Eigen::Vector3d(0, 0, 1.3);
  v.rc = sim::castRays(tris, PinholeIntrinsics{}, T);
  return v;
}

// Without gravity the paper's largest plane is the wall here; the upright prior takes
// the floor below the camera, and stays out of the way when the largest plane is a floor
// seen steeply (beyond the prior's cone). With gravity, a larger ceiling is never the
// ground: the ground is below the camera.
TEST(FramePipeline, UprightPriorTakesTheFloorOverALargerWallAndGravityNeverTakesACeiling) {
  const std::vector<sim::Triangle> room = {
      {{-3, -1, 0}, {3, -1, 0}, {3, 2.2, 0}, 1}, {{-3, -1, 0}, {3, 2.2, 0}, {-3, 2.2, 0}, 1},        // floor z = 0
      {{-3, 2.2, 0}, {3, 2.2, 0}, {3, 2.2, 3}, 2}, {{-3, 2.2, 0}, {3, 2.2, 3}, {-3, 2.2, 3}, 2},    // wall y = 2.2
      {{-4, -1, 1.8}, {4, 6, 1.8}, {4, -1, 1.8}, 3}, {{-4, -1, 1.8}, {-4, 6, 1.8}, {4, 6, 1.8}, 3},   // ceiling z = 1.8
      {{-4, -1, 0}, {4, -1, 0}, {4, 6, 0}, 1}, {{-4, -1, 0}, {4, 6, 0}, {-4, 6, 0}, 1}};             // a longer floor
  const PinholeIntrinsics k;
  const PitchedView level = pitchedView({room[0], room[1], room[2], room[3]}, 20.0);
  ASSERT_GT(level.pixels(2), 2 * level.pixels(1));
  const FramePipeline pipeline;
  const FrameResult prior = pipeline.process(level.rc.depth, k);
  ASSERT_TRUE(prior.ground_plane);
  EXPECT_EQ(prior.ground_rule, GroundRule::kUprightPrior);
  EXPECT_NEAR((*prior.ground_plane)(3), 1.3, 0.02);
  EXPECT_EQ(prior.reference, SlopeReference::kGround);
  EXPECT_LT(prior.segments.front().slope_deg, 0.5);
  PerceptionParams paper;
  paper.ground_upright_prior_deg = 0;
  const FrameResult largest = FramePipeline(paper).process(level.rc.depth, k);
  ASSERT_TRUE(largest.ground_plane);
  EXPECT_EQ(largest.ground_rule, GroundRule::kLargestPlane);
  // The wall: its normal is the camera's forward axis pitched up by 20 degrees.
  EXPECT_NEAR(std::abs((*largest.ground_plane)(2)), std::cos(20 * kDeg), 0.01);
  // Looking down at 55 degrees: the floor is the largest plane, outside the 45-degree
  // cone; the prior's search finds nothing but an edge fit, and the floor stays.
  const PitchedView steep = pitchedView({room[0], room[1]}, 55.0);
  const FrameResult down = pipeline.process(steep.rc.depth, k);
  ASSERT_TRUE(down.ground_plane);
  EXPECT_EQ(down.ground_rule, GroundRule::kLargestPlane);
  EXPECT_NEAR((*down.ground_plane)(3), 1.3, 0.02);
  // Level, in a long room with a ceiling 0.5 m overhead that fills more of the view
  // (the floor starts 3.1 m ahead, where the lowest rays meet it).
  const PitchedView up = pitchedView({room[4], room[5], room[6], room[7]}, 0.0);
  ASSERT_GT(up.pixels(3), 3 * up.pixels(1) / 2);
  const Eigen::Vector3f g_cam = (up.rot.transpose() * Eigen::Vector3d(0, 0, -1)).cast<float>();
  PerceptionParams loose;
  loose.max_range_m = 4.0;  // ceiling from 1.2 m, floor from 3.1 m: the ceiling has more voxels
  loose.ground_max_tilt_deg = 45;  // a ceiling passes the tilt test as well as the floor does
  const FrameResult with_gravity = FramePipeline(loose).process(up.rc.depth, k, g_cam);
  ASSERT_TRUE(with_gravity.ground_plane);
  EXPECT_EQ(with_gravity.ground_rule, GroundRule::kGravity);

  EXPECT_NEAR((*with_gravity.ground_plane)(3), 1.3, 0.02);
  EXPECT_GT(with_gravity.ground_plane->head<3>().dot(-g_cam), 0.99f);
}

TEST(FramePipeline, EmptyAllInvalidAndNanFramesGiveNoSegmentsAndNoNan) {
  const FramePipeline pipeline;
  const PinholeIntrinsics k;
  const FrameResult empty = pipeline.process(DepthImage(k.width, k.height), k);
  EXPECT_TRUE(empty.segments.empty());
  EXPECT_FALSE(empty.ground_plane);
  DepthImage nan_frame(k.width, k.height);
  std::fill(nan_frame.depth_m.begin(), nan_frame.depth_m.end(), std::numeric_limits<float>::quiet_NaN());
  EXPECT_TRUE(pipeline.process(nan_frame, k).segments.empty());
  std::vector<Eigen::Vector3f> cloud = {{NAN, 0, 1}, {0, 0, 1}};
  EXPECT_TRUE(pipeline.process(cloud).segments.empty());
  EXPECT_THROW((void)pipeline.process(DepthImage(10, 10), k), std::invalid_argument);
  EXPECT_THROW((void)pipeline.process(DepthImage(k.width, k.height), k, Eigen::Vector3f::Zero()), std::invalid_argument);
}

TEST(FramePipeline, ASinglePlaneIsOneGroundSegmentWithFiniteFeatures) {
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 100; ++i) {
    for (int j = 0; j < 100; ++j) pts.emplace_back(-0.5f + i * 0.01f, 1.0f, 1.0f + j * 0.01f);
  }
  const FrameResult r = FramePipeline().process(pts, Eigen::Vector3f(0, 1, 0));
  ASSERT_EQ(r.segments.size(), 1u);
  EXPECT_TRUE(r.segments[0].is_ground);
  EXPECT_NEAR(r.segments[0].slope_deg, 0.0, 0.1);
  EXPECT_NEAR(r.segments[0].roughness, 1.0, 0.01);
  EXPECT_GT(r.segments[0].mobility, 0.95);
  // Gravity is a direction: 1e30 long (its squared norm overflows a float) is the same.
  const FrameResult huge = FramePipeline().process(pts, Eigen::Vector3f(0, 1e30f, 0));
  ASSERT_EQ(huge.segments.size(), 1u);
  EXPECT_TRUE(huge.segments[0].is_ground);
  EXPECT_EQ(huge.segments[0].slope_deg, r.segments[0].slope_deg);
}

TEST(PerceptionParams, RejectsAbsurdValuesNamingTheField) {
  PerceptionParams p;
  p.voxel_size_m = 0;
  try {
    FramePipeline{p};
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("voxel_size_m"), std::string::npos);
  }
  p = {};
  p.max_range_m = 0.1;
  EXPECT_THROW(FramePipeline{p}, std::invalid_argument);
  p = {};
  p.ground_probability = 1.0;
  EXPECT_THROW(FramePipeline{p}, std::invalid_argument);
}

TEST(PerceptionParams, ScaledToCoarserVoxelsKeepTheirPhysicalSizes) {
  const PerceptionParams d;
  const PerceptionParams c = scaledToVoxel(d, 0.02);
  EXPECT_NO_THROW(validate(c));
  EXPECT_EQ(c.voxel_size_m, 0.02);
  // Counts of points on an area: a quarter (rounded).
  EXPECT_EQ(c.min_segment_points, 13);     // 50 / 4
  EXPECT_EQ(c.ground_min_points, 125);     // 500 / 4
  EXPECT_EQ(c.rough_fragment_max_points, 38);
  EXPECT_EQ(c.rough_min_points, 25);
  EXPECT_EQ(c.rough_smoothing_k, 7);       // 31 points on the same disc: 31 / 4 - 1
  // Spacing-tied distances double; neighbour counts and physical sizes stay.
  EXPECT_DOUBLE_EQ(c.neighbour_distance_m, 2 * d.neighbour_distance_m);
  EXPECT_DOUBLE_EQ(c.max_triangle_edge_m, 2 * d.max_triangle_edge_m);
  EXPECT_EQ(c.normal_k, d.normal_k);
  EXPECT_EQ(c.outlier_k, d.outlier_k);
  EXPECT_EQ(c.ground_distance_m, d.ground_distance_m);
  EXPECT_EQ(c.rough_min_width_m, d.rough_min_width_m);
  EXPECT_EQ(c.adopt_max_distance_m, d.adopt_max_distance_m);
  // The same voxel size changes nothing.
  const PerceptionParams same = scaledToVoxel(d, 0.01);
  EXPECT_EQ(same.min_segment_points, d.min_segment_points);
  EXPECT_EQ(same.ground_min_points, d.ground_min_points);
  EXPECT_EQ(same.rough_fragment_max_points, d.rough_fragment_max_points);
  EXPECT_EQ(same.rough_min_points, d.rough_min_points);
  EXPECT_EQ(same.rough_smoothing_k, d.rough_smoothing_k);
  EXPECT_DOUBLE_EQ(same.neighbour_distance_m, d.neighbour_distance_m);
  EXPECT_DOUBLE_EQ(same.max_triangle_edge_m, d.max_triangle_edge_m);
  // Rough joining switched off stays off.
  PerceptionParams off;
  off.rough_fragment_max_points = 0;
  EXPECT_EQ(scaledToVoxel(off, 0.02).rough_fragment_max_points, 0);
  // Much finer voxels: counts grow, and the result still validates.
  EXPECT_NO_THROW(validate(scaledToVoxel(d, 0.001)));
  EXPECT_EQ(scaledToVoxel(d, 0.001).min_segment_points, 5000);
  EXPECT_THROW((void)scaledToVoxel(d, 0.0), std::invalid_argument);
  EXPECT_THROW((void)scaledToVoxel(d, std::nan("")), std::invalid_argument);
}

}  // namespace
}  // namespace mobmap::perception
