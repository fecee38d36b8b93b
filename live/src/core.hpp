#pragma once
// The live nodes' core, the same on every transport (mobmap_node on ROS 1, mobmap_ros2
// over DDS): decoded messages in, LiveMapper in the middle (the newest frame kept, drops
// counted), map snapshots, layers, status, saving and serve's HTTP API out. A front end
// turns its transport's messages into sources::ros's structs and the core's outputs into
// its messages; the core never blocks a front end's receive thread for long.
#include "params.hpp"

#include "ros_messages.hpp"

#include "mobmap/builder/depth_checks.hpp"
#include "mobmap/mapping/layers.hpp"
#include "mobmap/mapping/live_mapper.hpp"

#include <Eigen/Geometry>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace mobmap::app::serve {
class Api;
class HttpServer;
class MapSource;
}  // namespace mobmap::app::serve

namespace mobmap::live {

/// The front end's TF: what it has heard on /tf and /tf_static. Calls come from the
/// core's threads; an implementation locks what it shares with its receive thread.
class Transforms {
 public:
  virtual ~Transforms() = default;
  [[nodiscard]] virtual bool has(const std::string& frame) = 0;
  /// The frame's root: the last frame up its chain of parents (the frame itself when it
  /// has none); nullopt when TF has not named it.
  [[nodiscard]] virtual std::optional<std::string> root(const std::string& frame) = 0;
  /// `source`'s pose in `target` at `stamp_ns`, without waiting; nullopt and `error`
  /// when TF cannot say it (yet).
  [[nodiscard]] virtual std::optional<Eigen::Isometry3d> lookup(const std::string& target, const std::string& source,
                                                                std::int64_t stamp_ns, std::string* error) = 0;
};

enum class Level { kDebug, kInfo, kWarn, kError };

struct Hooks {
  /// The transport's clock (simulated time when a recording drives it), ns since the epoch.
  std::function<std::int64_t()> now_ns;
  std::function<void(Level, const std::string&)> log;
  /// The node cannot go on (mapping could not start): the front end stops.
  std::function<void()> fatal;
};

/// The map's surface voxels: x, y, z (world frame), mobility, variance per point (NaN
/// where a voxel was never scored), float32, one point per voxel.
std::vector<float> mobilityCloudValues(const mapping::MobilityMap& map);

/// A pose in the world frame (position, quaternion x y z w).
struct WorldPose {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
};
/// A point of the map's frame as a pose in the world frame (the map's axes).
WorldPose poseInWorld(const mapping::MobilityMap& map, const Eigen::Vector3d& p_map);

/// nav_msgs/OccupancyGrid's content: rows from the origin along +y, free 0, occupied 100, unknown -1.
struct Occupancy {
  double cell_m = 0;
  int cols = 0, rows = 0;
  WorldPose origin;
  std::vector<std::int8_t> data;
};
Occupancy occupancy(const mapping::MobilityMap& map, const mapping::LevelLayers& layers);

/// grid_map_msgs/GridMap's content: layers elevation (world z), mobility, step (m), slope
/// (deg), variance (m^2), each in grid_map's storage order (column-major, index (0, 0) at
/// the corner of largest x and y), centred on the window's centre.
struct GridMapData {
  double resolution = 0, length_x = 0, length_y = 0;
  WorldPose pose;
  int cols = 0, rows = 0;  ///< along x, along y
  std::vector<std::string> layers;
  std::vector<std::vector<float>> data;
};
GridMapData gridMapData(const mapping::MobilityMap& map, const mapping::LevelLayers& layers);

/// The octree as octomap_msgs/Octomap's binary data.
std::string octomapBinary(const mapping::MobilityMap& map);

class Core {
 public:
  enum Output { kCloud, kOccupancy, kGridMap, kOctomap, kServed, kOutputs };

  /// `input` names what the node maps from (a topic), for the saved map's metadata.
  /// std::invalid_argument (naming the file and key) when `p.config` is wrong.
  Core(Params p, Transforms& tf, Hooks hooks, std::string input);
  ~Core();
  Core(const Core&) = delete;
  Core& operator=(const Core&) = delete;

  [[nodiscard]] const Params& params() const { return p_; }

  // Inputs, from the front end's receive threads.
  void cameraInfo(const sources::ros::CameraInfo& m);
  /// Counts a depth image, decodes it (an exception: counted unreadable, warned) and
  /// offers it to the feeder, which keeps only the newest waiting frame.
  void depth(const sources::ros::Header& header, double units_per_m, const std::function<perception::DepthImage()>& decode);
  void image(const sources::ros::Image& m, const std::string& topic);
  void compressedImage(const sources::ros::CompressedImage& m, const std::string& topic);
  void points(const sources::ros::PointCloud2& m, const std::string& topic);
  void imu(const sources::ros::Imu& m);
  /// A sample that could not be decoded (counted as received and unreadable).
  void unreadable(const std::string& key, const std::string& why);
  /// A warning at most once per warn_period for each key.
  void warn(const std::string& key, const std::string& text);
  void log(Level level, const std::string& text) const {
    if (hooks_.log) hooks_.log(level, text);
  }

  // Outputs, from the front end's publishing thread.
  struct Snapshot {
    std::shared_ptr<const mapping::MobilityMap> map;
    std::int64_t stamp_ns = 0;  ///< the newest frame the map surely holds
  };
  /// Null before the first frame is fused.
  [[nodiscard]] std::optional<Snapshot> snapshot() const;
  /// A snapshot newer than the one `output` last took (marks it taken), else nullopt.
  [[nodiscard]] std::optional<Snapshot> newSnapshot(Output output);
  /// Whether `output` has not yet published the map of `stamp_ns`; markPublished says it has.
  [[nodiscard]] bool isNew(Output output, std::int64_t stamp_ns) const;
  void markPublished(Output output, std::int64_t stamp_ns);
  [[nodiscard]] std::string worldFrame() const;
  /// The robot's level's layers with reachability from the base (OccupancyGrid).
  [[nodiscard]] std::optional<mapping::LevelLayers> occupancyLayers(const mapping::MobilityMap& map, std::int64_t stamp_ns);
  /// The window of grid_map_size around the base, terrain up to the clearance (GridMap).
  [[nodiscard]] std::optional<mapping::LevelLayers> gridMapLayers(const mapping::MobilityMap& map, std::int64_t stamp_ns);
  /// The map frame's pose in the world frame.
  [[nodiscard]] static WorldPose mapFrame(const mapping::MobilityMap& map);
  /// The status as JSON (docs/ROS.md); `extra` fields of the front end's are added.
  [[nodiscard]] std::string status(const std::map<std::string, double>& extra = {}) const;
  /// Whether the status should also go to the log this time (every ten seconds).
  [[nodiscard]] bool logStatusNow();
  /// Hands the newest map to serve's HTTP API, when it runs.
  void publishServed();
  /// The bound HTTP port, or -1.
  [[nodiscard]] int httpPort() const { return http_port_; }

  /// Saves the four files `build` writes, together; `said` says what happened.
  bool save(const std::string& path, std::string* said);
  /// Forgets the map; frames not yet fused are dropped.
  void clear();
  /// Stops taking frames, fuses what was taken, saves to save_on_exit if set.
  void shutdown();

 private:
  struct Pending {
    perception::DepthImage depth;
    std::vector<Eigen::Vector3f> points;
    int width = 0, height = 1;
    bool cloud = false;
    std::string frame_id;
    std::int64_t stamp_ns = 0;
    std::chrono::steady_clock::time_point arrived;
    double units_per_m = 1000.0;
  };
  struct Gauge {
    std::deque<double> ms;
    void add(double v) {
      ms.push_back(v);
      if (ms.size() > 300) ms.pop_front();
    }
    [[nodiscard]] double quantile(double q) const;
  };

  void offer(Pending&& p);
  void feed();
  /// The world frame, once: map, else odom, else (after kRootAfterFrames frames that
  /// found neither) the camera's root. False while there is none yet.
  bool chooseWorldFrame(const std::string& camera_frame);
  static constexpr int kRootAfterFrames = 10;
  int frames_without_world_ = 0;  // the feeder's
  std::optional<Eigen::Vector3d> gravityDown();
  static mapping::LiveMapper::Config mapperConfig(const Params& p);
  void startMapper(const Eigen::Vector3d& down);
  void onFrame(const mapping::FrameReport& r);
  void remember(double stamp_s, std::int64_t stamp_ns);  // under mutex_
  std::optional<Eigen::Isometry3d> lookup(const std::string& target, const std::string& source, std::int64_t stamp_ns,
                                          double wait_s, std::string* error);
  std::optional<Eigen::Vector3d> baseInMap(const mapping::MobilityMap& map, std::int64_t stamp_ns);

  Params p_;
  Transforms& tf_;
  Hooks hooks_;
  std::string input_;
  mapping::LiveMapper::Config mapper_config_;  // all but gravity and the callback

  mutable std::mutex mutex_;  // guards what follows
  std::condition_variable wake_;
  std::optional<Pending> pending_;
  std::optional<sources::ros::CameraInfo> info_;
  std::string world_frame_;
  std::vector<Eigen::Vector3d> imu_down_;
  std::unique_ptr<mapping::LiveMapper> mapper_;
  std::atomic<std::uint64_t> mapper_generation_{0};
  std::vector<Eigen::Vector3d> trajectory_world_;
  std::uint64_t received_ = 0, replaced_ = 0, late_ = 0, unreadable_ = 0, dropped_before_ = 0, fused_before_ = 0;
  std::uint64_t no_ground_ = 0;
  Gauge latency_, arrival_, perception_, fusion_, grid_map_;
  builder::DepthCheckTally checks_;
  sources::DepthUnit unit_;
  std::map<std::string, std::chrono::steady_clock::time_point> warned_;
  bool stopping_ = false;   // no more frames are taken
  bool shut_down_ = false;
  std::int64_t map_stamp_ns_ = 0;
  std::deque<std::pair<double, std::int64_t>> stamps_;  // the frames in flight: seconds -> exact ns
  std::int64_t published_[kOutputs] = {};
  int status_ticks_ = 0;

  std::thread feeder_;
  std::unique_ptr<app::serve::MapSource> served_;
  std::unique_ptr<app::serve::Api> api_;
  std::unique_ptr<app::serve::HttpServer> http_;
  std::thread http_thread_;
  int http_port_ = -1;
};

}  // namespace mobmap::live
