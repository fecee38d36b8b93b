// LiveMapper while a planner asks: frames per second with no reader and with one, and
// the latency of snapshots, point queries and footprint queries taken during fusion.
// Prints medians, 99th percentiles and the ratio of the two runs. Release builds only.
//
//   live_mapper_bench [SEVEN_SCENES_DIR] [FRAMES]
//
// Without a directory it renders the synthetic corridor (Kinect noise). Depth images are
// read before the clock starts. The reader is a planner at 100 Hz: every 10 ms it takes
// a snapshot and asks 100 points and 10 soles around the newest camera position.
#include "io/dataset.hpp"

#include "mobmap/mapping/gravity.hpp"
#include "mobmap/mapping/live_mapper.hpp"
#include "mobmap/sim/corridor_scene.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

using namespace mobmap;
using Clock = std::chrono::steady_clock;

namespace {

double us(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double, std::micro>(b - a).count(); }

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(p * static_cast<double>(v.size())))];
}

struct Run {
  double seconds = 0;
  std::vector<double> snapshot_us, point_us, foot_us;
  std::uint64_t copies = 0;
};

Run run(const std::vector<mapping::DepthFrame>& frames, const Eigen::Vector3d& g_world, bool with_reader) {
  mapping::LiveMapper::Config config;
  config.gravity_down_world = g_world;
  std::mutex where_mutex;
  Eigen::Vector3d where = Eigen::Vector3d::Zero();  // the newest camera, map frame
  mapping::LiveMapper* self = nullptr;
  config.on_frame = [&](const mapping::FrameReport& r) {
    const std::lock_guard<std::mutex> lock(where_mutex);
    where = self->snapshot()->worldToMap(frames[r.index].T_world_camera.translation());
  };
  mapping::LiveMapper mapper(config);
  self = &mapper;
  Run out;
  std::atomic<bool> done{false};
  std::thread reader;
  if (with_reader) {
    reader = std::thread([&] {
      std::mt19937 rng(7);
      std::uniform_real_distribution<double> around(-2.0, 2.0), yaw(-3.14, 3.14);
      while (!done.load()) {
        const auto t0 = Clock::now();
        const auto snap = mapper.snapshot();
        out.snapshot_us.push_back(us(t0, Clock::now()));
        Eigen::Vector3d c;
        {
          const std::lock_guard<std::mutex> lock(where_mutex);
          c = where;
        }
        for (int i = 0; i < 100; ++i) {
          const Eigen::Vector3d p = c + Eigen::Vector3d(around(rng), around(rng), -1.3 + 0.5 * around(rng));
          const auto a = Clock::now();
          (void)snap->query(p);
          out.point_us.push_back(us(a, Clock::now()));
        }
        for (int i = 0; i < 10; ++i) {
          const auto a = Clock::now();
          (void)snap->footprint({c.x() + around(rng), c.y() + around(rng), c.z() - 1.3, yaw(rng), 0.25, 0.12});
          out.foot_us.push_back(us(a, Clock::now()));
        }
        std::this_thread::sleep_until(t0 + std::chrono::milliseconds(10));
      }
    });
  }
  const auto start = Clock::now();
  for (const auto& f : frames) mapper.push(f);
  mapper.finish();
  out.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  done.store(true);
  if (reader.joinable()) reader.join();
  out.copies = mapper.stats().snapshot_copies;
  return out;
}

}  // namespace

int main(int argc, char** argv) {
#ifndef NDEBUG
  std::fprintf(stderr, "warning: this is not a Release build; the numbers mean little\n");
#endif
  const std::string dir = argc > 1 ? argv[1] : "";
  const int n_frames = argc > 2 ? std::atoi(argv[2]) : 120;
  std::vector<mapping::DepthFrame> frames;
  Eigen::Vector3d g_world(0, 0, -1);
  if (!dir.empty()) {
    const app::SevenScenesDirectory d(dir);
    const auto& nums = d.frameNumbers();
    Eigen::Vector3d camera_y = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < nums.size() && static_cast<int>(frames.size()) < n_frames; ++i) {
      mapping::DepthFrame f;
      f.depth = d.readDepth(nums[i]);
      f.intrinsics = d.intrinsics();
      f.T_world_camera.matrix() = d.readPose(nums[i]);
      f.T_world_camera.linear() = mapping::nearestRotation(f.T_world_camera.linear());
      camera_y += f.T_world_camera.linear().col(1);
      frames.push_back(std::move(f));
    }
    // As `mobmap build` falls back to without a floor: the cameras' mean +y axis.
    g_world = d.gravityDown() ? *d.gravityDown() : Eigen::Vector3d(camera_y.normalized());
  } else {
    sim::CorridorParams p;
    p.noise = sim::NoiseModel::kKinect;
    const sim::CorridorScene scene(p);
    for (int i = 0; i < n_frames; ++i) {
      const auto r = scene.render(i * 2 % p.frames);
      frames.push_back({r.depth, p.intrinsics, r.T_world_camera, i / 15.0});
    }
  }
  std::printf("%zu frames of %s, 2 perception threads, 2 cores\n", frames.size(), dir.empty() ? "the corridor" : dir.c_str());
  // Alternate: without, with, without, with; medians of the frame rates.
  std::vector<double> alone_fps, read_fps;
  Run last;
  for (int round = 0; round < 2; ++round) {
    alone_fps.push_back(frames.size() / run(frames, g_world, false).seconds);
    last = run(frames, g_world, true);
    read_fps.push_back(frames.size() / last.seconds);
  }
  const double a = percentile(alone_fps, 0.5), b = percentile(read_fps, 0.5);
  std::printf("frames/s: %.1f without a reader, %.1f with one (%.0f %%)\n", a, b, 100.0 * b / a);
  std::printf("during fusion (last run with the reader, %zu snapshots, %llu copies of a held buffer):\n",
              last.snapshot_us.size(), static_cast<unsigned long long>(last.copies));
  std::printf("  snapshot      p50 %7.1f us  p99 %7.1f us\n", percentile(last.snapshot_us, 0.5), percentile(last.snapshot_us, 0.99));
  std::printf("  point query   p50 %7.1f us  p99 %7.1f us\n", percentile(last.point_us, 0.5), percentile(last.point_us, 0.99));
  std::printf("  footprint     p50 %7.1f us  p99 %7.1f us\n", percentile(last.foot_us, 0.5), percentile(last.foot_us, 0.99));
  return 0;
}
