// LiveMapper: fusing frames while readers query snapshots of the map.
#include "mobmap/mapping/gravity.hpp"
#include "mobmap/mapping/live_mapper.hpp"
#include "mobmap/sim/corridor_scene.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <sstream>
#include <thread>
#include <vector>

namespace mobmap::mapping {
namespace {

// Every 4th frame of the noisy corridor's first 64.
struct Corridor {
  Corridor() : scene(params()) {
    for (int f = 0; f < 64; f += 4) frames.push_back(scene.render(f));
  }
  static sim::CorridorParams params() {
    sim::CorridorParams p;
    p.noise = sim::NoiseModel::kKinect;
    return p;
  }
  DepthFrame frame(std::size_t i) const {
    return {frames[i].depth, scene.params().intrinsics, frames[i].T_world_camera, 0.1 * static_cast<double>(i)};
  }
  sim::CorridorScene scene;
  std::vector<sim::RenderedFrame> frames;
};

const Corridor& corridor() {
  static const Corridor c;
  return c;
}

// The frames fused one by one into a MobilityMap, as `mobmap build` did before LiveMapper.
std::string sequentialMapBytes(const LiveMapper::Config& config, const Eigen::Vector3d& origin) {
  const Corridor& c = corridor();
  const perception::FramePipeline pipeline(config.perception, config.model);
  MobilityMap map(config.map, gravityAlignment(config.gravity_down_world), origin);
  for (std::size_t i = 0; i < c.frames.size(); ++i) {
    const DepthFrame f = c.frame(i);
    const Eigen::Vector3f g = (f.T_world_camera.linear().transpose() * config.gravity_down_world).cast<float>();
    const perception::FrameResult r = pipeline.process(f.depth, f.intrinsics, g);
    map.integrate(r, f.T_world_camera, &f.depth, &f.intrinsics);
  }
  map.finalize();
  std::ostringstream out;
  map.tree().write(out);
  return out.str();
}

std::string bytesOf(const MobilityMap& map) {
  std::ostringstream out;
  map.tree().write(out);
  return out.str();
}

// What a planner asks: points over the corridor's floor, ramps and stairs, and soles.
struct Answers {
  std::vector<int> states;
  std::vector<double> mobility;
  std::vector<double> sole_min;
  bool operator==(const Answers& o) const { return states == o.states && mobility == o.mobility && sole_min == o.sole_min; }
};

Answers ask(const MobilityMap& map) {
  Answers a;
  for (double x = 0.0; x <= 4.0; x += 0.1) {
    for (double y = -1.0; y <= 1.0; y += 0.25) {
      const PointQuery q = map.query({x, y, 0.01});
      a.states.push_back(static_cast<int>(q.state));
      a.mobility.push_back(q.has_mobility ? q.mobility : -1.0);
    }
    a.sole_min.push_back(map.footprint({x, 0.0, 0.05, 0.0, 0.25, 0.12}).min_mobility);
  }
  return a;
}

TEST(LiveMapper, SnapshotsNeverChangeUnderAReaderAndTheFinalMapIsTheSequentialOne) {
  const Corridor& c = corridor();
  LiveMapper::Config config;
  config.gravity_down_world = c.scene.gravityDown();
  std::vector<std::uint64_t> reported;
  std::vector<int> integrated;
  config.on_frame = [&](const FrameReport& r) {  // the fusion thread, in order
    reported.push_back(r.index);
    integrated.push_back(r.frames_integrated);
  };
  LiveMapper mapper(config);
  std::atomic<bool> done{false};
  int checks = 0, went_back = 0, changed = 0;
  std::thread reader([&] {
    int last = 0;
    while (!done.load()) {
      const std::shared_ptr<const MobilityMap> s = mapper.snapshot();
      const int frames = s->framesIntegrated();
      went_back += frames < last;
      last = frames;
      const Answers before = ask(*s);
      // Hold it until fusion has moved on (or ended), then ask again.
      while (!done.load() && mapper.snapshot()->framesIntegrated() == frames) std::this_thread::yield();
      changed += !(ask(*s) == before);
      ++checks;
    }
  });
  for (std::size_t i = 0; i < c.frames.size(); ++i) mapper.push(c.frame(i));
  mapper.finish();
  done.store(true);
  reader.join();
  EXPECT_GT(checks, 0);
  EXPECT_EQ(went_back, 0);
  EXPECT_EQ(changed, 0);
  const auto final_map = mapper.snapshot();
  EXPECT_EQ(final_map->framesIntegrated(), static_cast<int>(c.frames.size()));
  const LiveMapper::Stats stats = mapper.stats();
  EXPECT_EQ(stats.pushed, c.frames.size());
  EXPECT_EQ(stats.fused, c.frames.size());
  EXPECT_EQ(stats.dropped, 0u);
  ASSERT_EQ(reported.size(), c.frames.size());
  for (std::size_t i = 0; i < reported.size(); ++i) {
    EXPECT_EQ(reported[i], i);
    EXPECT_EQ(integrated[i], static_cast<int>(i) + 1);
  }
  // The origin is the first camera position rounded to 100 m, as `mobmap build` takes it.
  const Eigen::Vector3d t = c.frames[0].T_world_camera.translation();
  const Eigen::Vector3d origin(std::round(t.x() / 100) * 100, std::round(t.y() / 100) * 100, std::round(t.z() / 100) * 100);
  EXPECT_EQ(final_map->originWorld(), origin);
  const std::string live = bytesOf(*final_map), sequential = sequentialMapBytes(config, origin);
  EXPECT_GT(live.size(), 100000u);
  EXPECT_TRUE(live == sequential) << live.size() << " bytes against " << sequential.size();
}

// One buffer (a batch job): each frame fused once, the same map.
TEST(LiveMapper, WithoutSnapshotsDuringTheRunTheMapIsTheSameWithHalfTheFusion) {
  const Corridor& c = corridor();
  LiveMapper::Config config;
  config.gravity_down_world = c.scene.gravityDown();
  config.serve_snapshots = false;
  LiveMapper mapper(config);
  for (std::size_t i = 0; i < c.frames.size(); ++i) mapper.push(c.frame(i));
  mapper.finish();
  const auto map = mapper.snapshot();
  EXPECT_EQ(map->framesIntegrated(), static_cast<int>(c.frames.size()));
  EXPECT_EQ(mapper.stats().snapshot_copies, 0u);
  EXPECT_TRUE(bytesOf(*map) == sequentialMapBytes(config, map->originWorld()));
}

// A copy of a map is the same map, and fusing into it leaves the original alone (OctoMap's
// own copy constructor loses the nodes' mobility).
TEST(LiveMapper, ACopiedMapIsTheSameMapAndIndependent) {
  const Corridor& c = corridor();
  LiveMapper::Config config;
  const perception::FramePipeline pipeline(config.perception, config.model);
  MobilityMap map(config.map);
  const auto fuse = [&](MobilityMap& m, std::size_t i) {
    const DepthFrame f = c.frame(i);
    const Eigen::Vector3f g = (f.T_world_camera.linear().transpose() * c.scene.gravityDown()).cast<float>();
    m.integrate(pipeline.process(f.depth, f.intrinsics, g), f.T_world_camera, &f.depth, &f.intrinsics);
  };
  fuse(map, 0);
  const MobilityMap copy(map);
  EXPECT_TRUE(bytesOf(copy) == bytesOf(map));
  EXPECT_TRUE(ask(copy) == ask(map));
  MobilityMap both(copy), reference(map);
  fuse(both, 1);
  fuse(reference, 1);
  EXPECT_TRUE(bytesOf(both) == bytesOf(reference));  // the copy fuses as the original would
  EXPECT_TRUE(bytesOf(copy) == bytesOf(map));        // and the original did not move
  both.finalize();
  reference.finalize();
  EXPECT_TRUE(bytesOf(both) == bytesOf(reference));
}

TEST(LiveMapper, AHeldSnapshotIsCopiedAroundNotWrittenAndStaysAsItWas) {
  const Corridor& c = corridor();
  LiveMapper::Config config;
  config.gravity_down_world = c.scene.gravityDown();
  config.origin_world = Eigen::Vector3d(0, 0, 0);
  LiveMapper mapper(config);
  const auto empty = mapper.snapshot();  // held throughout
  const Answers none = ask(*empty);
  for (std::size_t i = 0; i < 3; ++i) mapper.push(c.frame(i));
  mapper.finish();
  const auto three = mapper.snapshot();
  EXPECT_EQ(three->framesIntegrated(), 3);
  // The buffer the empty snapshot points to was needed for the second frame: it was
  // left alone and the map copied instead.
  EXPECT_GE(mapper.stats().snapshot_copies, 1u);
  EXPECT_EQ(empty->framesIntegrated(), 0);
  EXPECT_EQ(empty->tree().size(), 0u);
  EXPECT_TRUE(ask(*empty) == none);
  EXPECT_FALSE(ask(*three) == none);
  // Frames pushed after finish() go on from there; a snapshot survives its mapper.
  std::shared_ptr<const MobilityMap> last;
  {
    LiveMapper again(config);
    for (std::size_t i = 0; i < 2; ++i) again.push(c.frame(i));
    again.finish();
    again.push(c.frame(2));
    again.finish();
    last = again.snapshot();
  }
  EXPECT_EQ(last->framesIntegrated(), 3);
  EXPECT_TRUE(ask(*last) == ask(*three));
}

TEST(LiveMapper, KeepNewestDropsWaitingFramesAndCountsThem) {
  const Corridor& c = corridor();
  LiveMapper::Config config;
  config.gravity_down_world = c.scene.gravityDown();
  config.when_busy = LiveMapper::WhenBusy::kKeepNewest;
  config.queue_capacity = 1;
  config.perception_threads = 1;
  LiveMapper mapper(config);
  for (std::size_t i = 0; i < c.frames.size(); ++i) mapper.push(c.frame(i));  // never waits
  mapper.finish();
  const LiveMapper::Stats s = mapper.stats();
  EXPECT_EQ(s.pushed, c.frames.size());
  EXPECT_EQ(s.fused + s.dropped, s.pushed);
  EXPECT_GE(s.fused, 1u);
  EXPECT_EQ(mapper.snapshot()->framesIntegrated(), static_cast<int>(s.fused));
}

TEST(LiveMapper, ACallbackThatThrowsStopsTheRunAndFinishRethrows) {
  const Corridor& c = corridor();
  LiveMapper::Config config;
  config.gravity_down_world = c.scene.gravityDown();
  config.on_frame = [](const FrameReport& r) {
    if (r.index == 1) throw std::runtime_error("disk full");
  };
  LiveMapper mapper(config);
  try {
    for (std::size_t i = 0; i < 6; ++i) mapper.push(c.frame(i));
  } catch (const std::logic_error&) {  // pushing after the run stopped
  }
  EXPECT_THROW(mapper.finish(), std::runtime_error);
  // Fusion stopped with the frame whose callback threw: frames 0 and 1, finalized.
  EXPECT_EQ(mapper.snapshot()->framesIntegrated(), 2);
}

TEST(LiveMapper, BadFramesAndParametersAreRefusedAtOnce) {
  const Corridor& c = corridor();
  LiveMapper::Config config;
  LiveMapper mapper(config);
  DepthFrame wrong = c.frame(0);
  wrong.intrinsics.width = 320;
  EXPECT_THROW(mapper.push(wrong), std::invalid_argument);
  DepthFrame scaled = c.frame(0);
  scaled.T_world_camera.linear() *= 2.0;
  EXPECT_THROW(mapper.push(scaled), std::invalid_argument);
  mapper.cancel();
  EXPECT_THROW(mapper.push(c.frame(0)), std::logic_error);
  mapper.finish();  // after cancel(): finalizes the frames fused, none here
  EXPECT_EQ(mapper.stats().fused, 0u);
  LiveMapper::Config bad;
  bad.gravity_down_world = Eigen::Vector3d::Zero();
  EXPECT_THROW(LiveMapper{bad}, std::invalid_argument);
  bad = LiveMapper::Config();
  bad.map.resolution_m = -1;
  EXPECT_THROW(LiveMapper{bad}, std::invalid_argument);
  bad = LiveMapper::Config();
  bad.perception_threads = 0;
  EXPECT_THROW(LiveMapper{bad}, std::invalid_argument);
}

}  // namespace
}  // namespace mobmap::mapping
