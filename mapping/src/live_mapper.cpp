#include "mobmap/mapping/live_mapper.hpp"

#include "mobmap/mapping/gravity.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <exception>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <vector>

namespace mobmap::mapping {
namespace {

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

// A map buffer and the number of snapshots of it still held. Shared with the snapshots'
// deleters, so a snapshot outlives the mapper.
struct MapBuffer {
  std::unique_ptr<MobilityMap> map;
  std::atomic<int> leases{0};
};

// A frame waiting for perception: one of the three kinds.
struct LiveMapper::Pending {
  std::optional<DepthFrame> depth;
  std::optional<CloudFrame> cloud;
  std::optional<PerceivedFrame> perceived;
};

// A frame after perception, kept until both buffers have it.
struct Perceived {
  std::uint64_t index = 0;
  Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();
  double stamp_s = 0.0;
  std::optional<perception::DepthImage> depth;  // for clearing free space
  perception::PinholeIntrinsics intrinsics;
  perception::FrameResult result;
  std::string error;
  double perception_ms = 0.0;
};

struct LiveMapper::Impl {
  Config config;
  perception::FramePipeline pipeline;
  Eigen::Matrix3d R_map_world;

  mutable std::mutex mutex;              // guards everything below up to the threads
  std::condition_variable changed;       // any of it changed
  std::deque<Pending> waiting;           // pushed, not yet taken for perception
  std::map<std::uint64_t, std::shared_ptr<Perceived>> perceived;  // by index, awaiting fusion
  std::uint64_t next_index = 0;          // given to the next frame taken for perception
  std::uint64_t next_to_fuse = 0;
  std::uint64_t in_perception = 0;
  std::uint64_t finish_requests = 0;     // finish() calls
  std::uint64_t finishes_done = 0;       // of them, answered: all fused, the front finalized
  bool finalized = true;                 // the published buffer is finalized (an empty map is)
  bool stopping = false;
  bool cancelled = false;
  std::exception_ptr callback_error;     // the first exception a callback threw
  Stats stats;

  mutable std::mutex publish_mutex;      // guards `front`
  std::shared_ptr<MapBuffer> front;      // what snapshot() hands out

  // Fusion thread only.
  std::shared_ptr<MapBuffer> back;
  std::vector<std::shared_ptr<Perceived>> missed;  // fused into `front`, not yet into `back`
  bool origin_set = false;
  bool rebuild_back = false;  // `back` has another origin than `front`: copy, do not catch up

  std::vector<std::thread> workers;
  std::thread fuser;

  Impl(Config c, std::unique_ptr<MobilityOcTree> tree, const std::optional<Eigen::Matrix3d>& R,
       const std::optional<Eigen::Vector3d>& origin)
      : config(std::move(c)), pipeline(config.perception, config.model) {
    perception::validate(config.perception);
    if (tree) config.map.resolution_m = tree->getResolution();
    validate(config.map);
    if (config.perception_threads < 1 || config.perception_threads > kMaxPerceptionThreads) {
      throw std::invalid_argument("LiveMapper: perception_threads must be in [1, " + std::to_string(kMaxPerceptionThreads) +
                                  "], got " + std::to_string(config.perception_threads));
    }
    if (config.queue_capacity < 1) throw std::invalid_argument("LiveMapper: queue_capacity must be >= 1");
    const Eigen::Vector3d& g = config.gravity_down_world;
    if (!g.allFinite() || g.norm() < 1e-9) throw std::invalid_argument("LiveMapper: gravity_down_world must be finite and not zero");
    R_map_world = R ? *R : gravityAlignment(g);
    if (origin) config.origin_world = origin;
    origin_set = config.origin_world.has_value();
    const Eigen::Vector3d o = config.origin_world.value_or(Eigen::Vector3d::Zero());
    auto first = std::make_shared<MapBuffer>();
    auto second = std::make_shared<MapBuffer>();
    if (tree && !config.serve_snapshots) {  // one buffer: the second is never used
      first->map = std::make_unique<MobilityMap>(std::move(tree), config.map, R_map_world, o);
      second->map = std::make_unique<MobilityMap>(config.map, R_map_world, o);
    } else if (tree) {
      first->map = std::make_unique<MobilityMap>(tree->clone(), config.map, R_map_world, o);
      second->map = std::make_unique<MobilityMap>(std::move(tree), config.map, R_map_world, o);
    } else {
      first->map = std::make_unique<MobilityMap>(config.map, R_map_world, o);
      second->map = std::make_unique<MobilityMap>(config.map, R_map_world, o);
    }
    // Rough ground on the fine surface is scored with the perception's model.
    const auto model = std::make_shared<const gp::MobilityModel>(config.model);
    first->map->setMobilityModel(model);
    second->map->setMobilityModel(model);
    front = std::move(first);
    back = std::move(second);
    try {
      for (int t = 0; t < config.perception_threads; ++t) workers.emplace_back([this] { perceive(); });
      fuser = std::thread([this] { fuse(); });
    } catch (const std::system_error& e) {  // the system would not give this process more threads
      stopThreads();
      throw std::runtime_error("LiveMapper: cannot start " + std::to_string(config.perception_threads) +
                               " perception threads and a fusion thread: " + e.what());
    }
  }

  ~Impl() { stopThreads(); }

  void stopThreads() {
    {
      const std::lock_guard<std::mutex> lock(mutex);
      stopping = true;
      cancelled = true;
      waiting.clear();
    }
    changed.notify_all();
    for (auto& t : workers) t.join();
    if (fuser.joinable()) fuser.join();
  }

  void perceive() {
    for (;;) {
      Pending frame;
      std::uint64_t index = 0;
      {
        std::unique_lock<std::mutex> lock(mutex);
        changed.wait(lock, [this] { return stopping || !waiting.empty(); });
        if (stopping) return;
        frame = std::move(waiting.front());
        waiting.pop_front();
        index = next_index++;
        ++in_perception;
      }
      changed.notify_all();  // room in the queue
      auto p = std::make_shared<Perceived>();
      p->index = index;
      const auto t0 = std::chrono::steady_clock::now();
      try {
        const Eigen::Isometry3d& T = frame.depth ? frame.depth->T_world_camera
                                     : frame.cloud ? frame.cloud->T_world_camera
                                                   : frame.perceived->T_world_camera;
        const Eigen::Vector3f g_camera = (T.linear().transpose() * config.gravity_down_world.normalized()).cast<float>();
        p->T_world_camera = T;
        if (frame.depth) {
          p->result = pipeline.process(frame.depth->depth, frame.depth->intrinsics, g_camera);
          p->stamp_s = frame.depth->stamp_s;
          p->intrinsics = frame.depth->intrinsics;
          p->depth = std::move(frame.depth->depth);
        } else if (frame.cloud) {
          const CloudFrame& c = *frame.cloud;
          p->result = c.height > 1 ? pipeline.processOrganized(c.points, c.width, c.height, g_camera)
                                   : pipeline.process(c.points, g_camera);
          p->stamp_s = c.stamp_s;
        } else {
          p->result = std::move(frame.perceived->result);
          p->stamp_s = frame.perceived->stamp_s;
          p->intrinsics = frame.perceived->intrinsics;
          p->depth = std::move(frame.perceived->depth);
        }
      } catch (const std::exception& e) {
        p->error = e.what();
      }
      p->perception_ms = msSince(t0);
      {
        const std::lock_guard<std::mutex> lock(mutex);
        perceived.emplace(index, std::move(p));
        --in_perception;
      }
      changed.notify_all();
    }
  }

  // Makes `back` a buffer fusion may write that holds every frame fused so far.
  void prepareBack() {
    if (!rebuild_back && back->leases.load(std::memory_order_acquire) == 0) {
      for (const auto& m : missed) integrateInto(*back->map, *m);
    } else {
      // A reader still holds it: start from a copy of the current map instead.
      std::shared_ptr<MapBuffer> current;
      {
        const std::lock_guard<std::mutex> lock(publish_mutex);
        current = front;
      }
      auto fresh = std::make_shared<MapBuffer>();
      fresh->map = std::make_unique<MobilityMap>(*current->map);
      back = std::move(fresh);
      if (!rebuild_back) {
        const std::lock_guard<std::mutex> lock(mutex);
        ++stats.snapshot_copies;
      }
      rebuild_back = false;
    }
    missed.clear();
  }

  // The map with every frame fused so far, finalized, becomes what snapshot() gives.
  void finalizeAndPublish() {
    if (!config.serve_snapshots) {
      front->map->finalize();
      const std::lock_guard<std::mutex> lock(mutex);
      finalized = true;
      return;
    }
    prepareBack();
    back->map->finalize();
    publish(true);
  }

  bool frontFinalized() {
    const std::lock_guard<std::mutex> lock(mutex);
    return finalized;
  }

  IntegrationReport integrateInto(MobilityMap& map, const Perceived& p) {
    const bool clear = config.clear_free_space && p.depth.has_value();
    return map.integrate(p.result, p.T_world_camera, clear ? &*p.depth : nullptr, clear ? &p.intrinsics : nullptr);
  }

  void publish(bool now_finalized) {
    {
      const std::lock_guard<std::mutex> lock(publish_mutex);
      std::swap(front, back);
    }
    const std::lock_guard<std::mutex> lock(mutex);
    finalized = now_finalized;
  }

  bool idle() const { return waiting.empty() && in_perception == 0 && perceived.empty(); }

  void fuse() {
    for (;;) {
      std::shared_ptr<Perceived> p;
      {
        std::unique_lock<std::mutex> lock(mutex);
        changed.wait(lock, [this] {
          return stopping || (cancelled && !perceived.empty()) || perceived.count(next_to_fuse) > 0 ||
                 (finish_requests > finishes_done && idle());
        });
        if (stopping) return;
        if (cancelled && !perceived.empty()) {
          perceived.clear();
          continue;
        }
        const auto it = perceived.find(next_to_fuse);
        if (it != perceived.end()) {
          p = std::move(it->second);
          perceived.erase(it);
          ++next_to_fuse;
        }
      }
      if (!p) {  // finish(): every frame is fused; publish the map finalized
        if (!frontFinalized()) finalizeAndPublish();
        {
          const std::lock_guard<std::mutex> lock(mutex);
          finishes_done = finish_requests;
        }
        changed.notify_all();
        continue;
      }
      FrameReport report;
      report.index = p->index;
      report.stamp_s = p->stamp_s;
      report.perception_ms = p->perception_ms;
      report.error = p->error;
      if (p->error.empty()) {
        const auto t0 = std::chrono::steady_clock::now();
        MobilityMap& target = config.serve_snapshots ? *back->map : *front->map;
        if (!origin_set) {
          // The first frame's camera, rounded, as `mobmap build`. Nothing is fused yet;
          // the buffer readers see keeps its origin and is replaced after this frame.
          target.setOriginWorld(defaultMapOrigin(p->T_world_camera.translation()));
          origin_set = true;
          rebuild_back = true;
        } else if (config.serve_snapshots) {
          prepareBack();
        }
        MobilityMap& into = config.serve_snapshots ? *back->map : *front->map;
        report.integration = integrateInto(into, *p);
        report.stages = p->result.stages;
        report.frames_integrated = into.framesIntegrated();
        report.fused = true;
        report.points = p->result.points.size();
        report.ground_found = p->result.ground_plane.has_value();
        if (report.ground_found) report.ground_distance_m = (*p->result.ground_plane)(3);
        report.range = p->result.range;
        if (config.serve_snapshots) {
          publish(false);
          missed.push_back(p);
        } else {
          const std::lock_guard<std::mutex> lock(mutex);
          finalized = false;
        }
        report.fusion_ms = msSince(t0);
      }
      {
        const std::lock_guard<std::mutex> lock(mutex);
        ++(report.fused ? stats.fused : stats.failed);
      }
      try {
        if (config.on_frame) config.on_frame(report);
        if (report.fused && config.finalize_after && config.finalize_after(report)) {
          finalizeAndPublish();
          std::shared_ptr<MapBuffer> finalized_front;
          {
            const std::lock_guard<std::mutex> lock(publish_mutex);
            finalized_front = front;
          }
          if (config.on_finalized) config.on_finalized(*finalized_front->map, report);
        }
      } catch (...) {  // a callback threw: the run stops, finish() rethrows it
        const std::lock_guard<std::mutex> lock(mutex);
        if (!callback_error) callback_error = std::current_exception();
        cancelled = true;
        waiting.clear();
      }
      changed.notify_all();
    }
  }
};

LiveMapper::LiveMapper(Config config) : impl_(std::make_unique<Impl>(std::move(config), nullptr, std::nullopt, std::nullopt)) {}

LiveMapper::LiveMapper(Config config, std::unique_ptr<MobilityOcTree> tree, const Eigen::Matrix3d& R_map_world,
                       const Eigen::Vector3d& origin_world)
    : impl_(std::make_unique<Impl>(std::move(config), std::move(tree), R_map_world, origin_world)) {}

LiveMapper::~LiveMapper() = default;

namespace {

void checkPose(const Eigen::Isometry3d& T) {
  if (auto problem = checkRigid(T.matrix())) {
    throw std::invalid_argument("LiveMapper::push: T_world_camera is not a rigid transform: " + *problem);
  }
}

}  // namespace

void LiveMapper::enqueue(Pending&& frame) {
  Impl& m = *impl_;
  {
    std::unique_lock<std::mutex> lock(m.mutex);
    if (m.cancelled) throw std::logic_error("LiveMapper::push after cancel()");
    if (m.config.when_busy == WhenBusy::kBlock) {
      m.changed.wait(lock, [&] { return m.cancelled || m.waiting.size() < m.config.queue_capacity; });
      if (m.cancelled) throw std::logic_error("LiveMapper::push after cancel()");
    } else if (m.waiting.size() >= m.config.queue_capacity) {
      m.waiting.pop_front();
      ++m.stats.dropped;
    }
    m.waiting.push_back(std::move(frame));
    ++m.stats.pushed;
  }
  m.changed.notify_all();
}

void LiveMapper::push(DepthFrame frame) {
  const auto& k = frame.intrinsics;
  if (frame.depth.width != k.width || frame.depth.height != k.height ||
      frame.depth.depth_m.size() != static_cast<std::size_t>(frame.depth.width) * static_cast<std::size_t>(frame.depth.height)) {
    throw std::invalid_argument("LiveMapper::push: the depth image is " + std::to_string(frame.depth.width) + "x" +
                                std::to_string(frame.depth.height) + " but the intrinsics are for " +
                                std::to_string(k.width) + "x" + std::to_string(k.height));
  }
  checkPose(frame.T_world_camera);
  Pending p;
  p.depth = std::move(frame);
  enqueue(std::move(p));
}

void LiveMapper::push(CloudFrame frame) {
  if (frame.height > 1 && frame.points.size() != static_cast<std::size_t>(frame.width) * static_cast<std::size_t>(frame.height)) {
    throw std::invalid_argument("LiveMapper::push: an organized cloud of " + std::to_string(frame.width) + "x" +
                                std::to_string(frame.height) + " has " + std::to_string(frame.points.size()) + " points");
  }
  checkPose(frame.T_world_camera);
  Pending p;
  p.cloud = std::move(frame);
  enqueue(std::move(p));
}

void LiveMapper::push(PerceivedFrame frame) {
  checkPose(frame.T_world_camera);
  Pending p;
  p.perceived = std::move(frame);
  enqueue(std::move(p));
}

std::shared_ptr<const MobilityMap> LiveMapper::snapshot() const {
  std::shared_ptr<MapBuffer> buffer;
  {
    const std::lock_guard<std::mutex> lock(impl_->publish_mutex);
    buffer = impl_->front;
    buffer->leases.fetch_add(1, std::memory_order_relaxed);
  }
  const MobilityMap* map = buffer->map.get();
  return std::shared_ptr<const MobilityMap>(
      map, [buffer = std::move(buffer)](const MobilityMap*) { buffer->leases.fetch_sub(1, std::memory_order_release); });
}

void LiveMapper::finish() {
  Impl& m = *impl_;
  std::unique_lock<std::mutex> lock(m.mutex);
  const std::uint64_t request = ++m.finish_requests;
  m.changed.notify_all();
  m.changed.wait(lock, [&] { return m.finishes_done >= request; });
  if (m.callback_error) std::rethrow_exception(m.callback_error);
}

void LiveMapper::cancel() {
  Impl& m = *impl_;
  {
    const std::lock_guard<std::mutex> lock(m.mutex);
    m.cancelled = true;
    m.waiting.clear();
  }
  m.changed.notify_all();
}

LiveMapper::Stats LiveMapper::stats() const {
  const std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->stats;
}

const Eigen::Matrix3d& LiveMapper::rotationMapWorld() const { return impl_->R_map_world; }

}  // namespace mobmap::mapping
