#pragma once
/// @file live_mapper.hpp
/// Mapping while the map is queried: frames go in from any thread, perception runs on
/// worker threads, fusion runs in push order on a thread of its own, and readers take
/// snapshots of the map that never change under them.

#include "mobmap/gp/mobility_model.hpp"
#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/perception/camera.hpp"
#include "mobmap/perception/pipeline.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

namespace mobmap::mapping {

/// One depth frame and where the camera was.
struct DepthFrame {
  perception::DepthImage depth;  ///< metres, 0 or NaN = no measurement
  perception::PinholeIntrinsics intrinsics;
  Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();
  double stamp_s = 0.0;
};

/// A point cloud frame (a .pcd): organized (row-major, width x height, non-finite =
/// no measurement) when height > 1. Free space is not cleared for clouds.
struct CloudFrame {
  std::vector<Eigen::Vector3f> points;  ///< camera frame, metres
  int width = 0;
  int height = 1;
  Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();
  double stamp_s = 0.0;
};

/// A frame perceived already (FramePipeline), fused as it is. With its depth image and
/// intrinsics, free space is cleared as for a DepthFrame.
struct PerceivedFrame {
  perception::FrameResult result;
  std::optional<perception::DepthImage> depth;
  perception::PinholeIntrinsics intrinsics;
  Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();
  double stamp_s = 0.0;
};

/// What became of one frame, in push order (LiveMapper::Config::on_frame).
struct FrameReport {
  std::uint64_t index = 0;  ///< among the frames taken for perception, from 0
  double stamp_s = 0.0;
  bool fused = false;       ///< false: perception failed (error says why)
  std::string error;
  IntegrationReport integration;
  std::size_t points = 0;        ///< after perception's reduction
  bool ground_found = false;
  /// The ground plane's distance below the camera when ground_found.
  double ground_distance_m = 0.0;
  /// Where the frame's points lay and what the range limits took (RangeReport).
  perception::RangeReport range;
  int frames_integrated = 0;     ///< in the map after this frame
  double perception_ms = 0.0;
  double fusion_ms = 0.0;        ///< both map buffers (see LiveMapper)
  std::vector<perception::StageTiming> stages;  ///< perception's, in pipeline order
};

/// Fuses a stream of depth frames into a MobilityMap and serves snapshots of it.
///
/// Snapshots: the map is kept twice. Fusion writes one buffer while readers use the
/// other; after each frame the two swap, and the buffer readers no longer see catches up
/// on the frame it missed before it takes the next one. A snapshot is a shared pointer
/// to the published buffer (taking one copies a pointer), and the buffer is not written
/// while any snapshot of it is held: if a reader still holds it when fusion needs it,
/// fusion works on a copy of the current map instead (Stats::snapshot_copies counts
/// them). Each frame is therefore fused twice; fusion stays small beside perception.
///
/// Threading: push(), snapshot(), stats(), finish() and cancel() may be called from any
/// thread. The map of a snapshot may be queried from several threads at once. Callbacks
/// run on the fusion thread; they may call snapshot(), stats() and cancel(), not push()
/// or finish().
class LiveMapper {
 public:
  /// What push() does when `queue_capacity` frames already wait for perception.
  enum class WhenBusy {
    kBlock,       ///< wait until one is taken (back-pressure; nothing is lost)
    kKeepNewest,  ///< drop the oldest waiting frame (a live sensor); Stats::dropped counts them
  };

  static constexpr int kMaxPerceptionThreads = 256;

  struct Config {
    /// `mobmap build`'s defaults: 2 cm voxels, points up to 3 m.
    MapParams map = [] {
      MapParams m;
      m.max_range_m = 3.0;
      return m;
    }();
    perception::PerceptionParams perception;
    gp::MobilityModel model = gp::MobilityModel();
    /// Gravity (pointing down) in the world frame of the poses.
    Eigen::Vector3d gravity_down_world = Eigen::Vector3d(0, 0, -1);
    /// The map origin in the world frame; unset: the first frame's camera position
    /// rounded to 100 m (as `mobmap build`). At most kMaxWorldCoordinateM from the world origin.
    std::optional<Eigen::Vector3d> origin_world;
    /// Frames perceived at once, 1 to kMaxPerceptionThreads (each thread holds a frame's
    /// working memory); one thread more fuses.
    int perception_threads = 2;
    std::size_t queue_capacity = 2;
    WhenBusy when_busy = WhenBusy::kBlock;
    /// Clear voxels each frame sees through (MobilityMap::integrate with the depth image).
    bool clear_free_space = true;
    /// false: one map buffer, each frame fused once (a batch job such as `mobmap build`
    /// that queries nothing while it runs). snapshot() may then be called only from the
    /// callbacks and after finish(), and its map changes as fusion goes on.
    bool serve_snapshots = true;
    /// Called on the fusion thread after each frame, in push order.
    std::function<void(const FrameReport&)> on_frame;
    /// Asked on the fusion thread after on_frame for each fused frame: true finalizes the
    /// map (MobilityMap::finalize), publishes it and hands it to on_finalized before the
    /// next frame (a checkpoint to save). Fusion then goes on in the finalized map.
    std::function<bool(const FrameReport&)> finalize_after;
    std::function<void(const MobilityMap&, const FrameReport&)> on_finalized;
  };

  struct Stats {
    std::uint64_t pushed = 0;
    std::uint64_t dropped = 0;  ///< WhenBusy::kKeepNewest
    std::uint64_t fused = 0;
    std::uint64_t failed = 0;   ///< perception threw (FrameReport::error)
    std::uint64_t snapshot_copies = 0;
  };

  /// std::invalid_argument if a parameter is unusable (MapParams, PerceptionParams,
  /// gravity zero or not finite, no perception thread, no queue).
  explicit LiveMapper(Config config);
  /// Continues a map: `tree` (e.g. loadMobilityMap()) in the frame `R_map_world` /
  /// `origin_world` it was built in; config.map.resolution_m is taken from the tree.
  LiveMapper(Config config, std::unique_ptr<MobilityOcTree> tree, const Eigen::Matrix3d& R_map_world,
             const Eigen::Vector3d& origin_world);
  /// Cancels (frames not yet fused are dropped) and joins the threads. Snapshots stay valid.
  ~LiveMapper();
  LiveMapper(const LiveMapper&) = delete;
  LiveMapper& operator=(const LiveMapper&) = delete;

  /// Queues a frame. std::invalid_argument (at once, from the caller's thread) if its
  /// image and intrinsics do not match or its pose is not rigid; std::logic_error after
  /// cancel(). With WhenBusy::kBlock it waits while the queue is full.
  void push(DepthFrame frame);
  /// The same for a point cloud (std::invalid_argument if width x height is not its size
  /// for an organized cloud) and for a frame perceived already.
  void push(CloudFrame frame);
  void push(PerceivedFrame frame);
  /// The map after the last frame fused (an empty map before the first). Never null.
  [[nodiscard]] std::shared_ptr<const MobilityMap> snapshot() const;
  /// Returns when every frame pushed so far is fused (or failed); the snapshot then is
  /// finalized (MobilityMap::finalize: inner nodes, pruning), ready to save: the same
  /// map, byte for byte, as fusing the frames one by one into a MobilityMap and calling
  /// finalize(). Frames may be pushed afterwards (not after cancel()). If a callback
  /// threw, the run stopped there (as cancel()) and finish() rethrows that exception.
  void finish();
  /// Drops the frames not yet fused and stops taking new ones; a frame being fused
  /// completes. finish() afterwards finalizes the map of the frames fused (Ctrl-C).
  void cancel();
  [[nodiscard]] Stats stats() const;
  /// The rotation and origin of the map frame (MobilityMap::worldToMap).
  [[nodiscard]] const Eigen::Matrix3d& rotationMapWorld() const;

 private:
  struct Impl;
  struct Pending;
  void enqueue(Pending&& frame);
  std::unique_ptr<Impl> impl_;
};

}  // namespace mobmap::mapping
