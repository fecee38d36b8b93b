#pragma once
// mobmap_node: maps live from a robot's depth camera and TF, and publishes the map as
// RViz, move_base and footstep planners read it (docs/ROS.md).
#include "mobmap/builder/depth_checks.hpp"
#include "mobmap/mapping/live_mapper.hpp"
#include "mobmap/mapping/map_metadata.hpp"
#include "mobmap/mapping/reachability.hpp"

#include <image_transport/image_transport.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/Header.h>
#include <std_srvs/Empty.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include <atomic>
#include <condition_variable>
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

namespace mobmap::ros1 {

/// The node's parameters (private namespace, docs/ROS.md).
struct NodeParams {
  std::string world_frame;  ///< empty: map if TF has it, else odom, else the camera's root
  std::string base_frame = "base_link";
  std::string map_frame = "mobmap_map";  ///< the map's own frame, published under world_frame
  bool compressed = false;               ///< read `depth`/compressedDepth instead of raw images
  bool use_points = false;               ///< map sensor_msgs/PointCloud2 from `points`
  bool use_imu = false;                  ///< gravity from `imu` when the world frame does not say it
  std::vector<double> gravity;           ///< down in the world frame, if given
  double resolution = 0.02;
  double max_range = 3.0;
  std::string config;                    ///< a `mobmap build --config` YAML
  int threads = 0;                       ///< perception threads; 0: the machine's cores less one, at least 1
  double tf_wait = 0.2;                  ///< seconds an image waits for its pose
  double max_pose_gap = 0.05;
  double warn_period = 10.0;             ///< the same warning at most once per this many seconds
  double cloud_rate = 1.0, occupancy_rate = 0.5, grid_map_rate = 10.0, octomap_rate = 0.5, status_rate = 1.0;
  double grid_map_size = 4.0, grid_map_resolution = 0.04;
  double clearance = 1.0;                ///< the robot's height: surfaces above it are overhead
  double occupancy_cell = 0.05;
  mapping::ReachParams reach;
  std::string save_path = "mobmap_map.ot";  ///< ~save_map writes here
  std::string save_on_exit;                 ///< non-empty: save here on shutdown
  int http_port = -1;                       ///< >= 0: serve's HTTP API on the live map (0: any free port)
  std::string http_address = "127.0.0.1";
};

/// Reads the private parameters; std::invalid_argument naming the parameter.
NodeParams readParams(const ::ros::NodeHandle& pnh);

class Node {
 public:
  Node(::ros::NodeHandle nh, ::ros::NodeHandle pnh, NodeParams params);
  ~Node();
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;
  /// Stops taking frames, fuses what was taken, saves to ~save_on_exit if set.
  void shutdown();

 private:
  struct Pending {
    perception::DepthImage depth;   // metres (a depth image)
    std::vector<Eigen::Vector3f> points;  // or a cloud
    int width = 0, height = 1;
    bool cloud = false;
    std::string frame_id;
    ::ros::Time stamp;
    ::ros::WallTime arrived;
    double units_per_m = 1000.0;
  };
  struct Gauge {  // latency samples, the last N
    std::deque<double> ms;
    void add(double v) {
      ms.push_back(v);
      if (ms.size() > 300) ms.pop_front();
    }
    [[nodiscard]] double quantile(double q) const;
  };

  void onInfo(const sensor_msgs::CameraInfoConstPtr& m);
  void onImage(const sensor_msgs::ImageConstPtr& m);
  void onCompressed(const sensor_msgs::CompressedImageConstPtr& m);
  void onPoints(const sensor_msgs::PointCloud2ConstPtr& m);
  void onImu(const sensor_msgs::ImuConstPtr& m);
  /// Counts an image, decodes it (an exception: counted unreadable, warned) and offers it.
  void takeDepth(const std_msgs::Header& header, double units_per_m,
                 const std::function<perception::DepthImage()>& decode);
  void offer(Pending&& p);
  void feed();  // the feeder thread: pose, then LiveMapper
  bool chooseWorldFrame(const std::string& camera_frame);
  std::optional<Eigen::Vector3d> gravityDown();
  /// Perception, fusion and the model as `~config` and the parameters set them, read once
  /// at start (a bad configuration stops the node there, naming the file and the key).
  static mapping::LiveMapper::Config mapperConfig(const NodeParams& p);
  void startMapper(const Eigen::Vector3d& down);
  void onFrame(const mapping::FrameReport& r);
  std::optional<Eigen::Isometry3d> lookup(const std::string& target, const std::string& source, const ::ros::Time& t,
                                          double wait_s, std::string* error);

  void publishCloud();
  void publishOccupancy();
  void publishGridMap();
  void publishOctomap();
  void publishStatus();
  void publishServed();
  bool save(const std::string& path, std::string* said);
  bool onSave(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res);
  bool onClear(std_srvs::Empty::Request&, std_srvs::Empty::Response&);
  /// The map and the stamp of the newest frame it surely holds; null before the first.
  std::shared_ptr<const mapping::MobilityMap> snapshot(::ros::Time* stamp = nullptr) const;
  std::optional<Eigen::Vector3d> baseInMap(const mapping::MobilityMap& map);
  void warn(const std::string& key, const std::string& text);

  ::ros::NodeHandle nh_, pnh_;
  NodeParams p_;
  mapping::LiveMapper::Config mapper_config_;  // all but gravity and the callback
  tf2_ros::Buffer tf_;
  tf2_ros::TransformListener tf_listener_;
  tf2_ros::StaticTransformBroadcaster static_tf_;
  image_transport::ImageTransport it_;
  image_transport::Subscriber image_sub_;
  ::ros::Subscriber info_sub_, compressed_sub_, points_sub_, imu_sub_;
  ::ros::Publisher cloud_pub_, occupancy_pub_, grid_map_pub_, octomap_pub_, status_pub_;
  ::ros::ServiceServer save_srv_, clear_srv_;
  std::vector<::ros::WallTimer> timers_;

  mutable std::mutex mutex_;  // guards what follows
  std::condition_variable wake_;
  std::optional<Pending> pending_;
  std::optional<sensor_msgs::CameraInfo> info_;
  std::string world_frame_;
  std::vector<Eigen::Vector3d> imu_down_;  // accelerometer readings' down, world frame
  std::unique_ptr<mapping::LiveMapper> mapper_;
  std::atomic<std::uint64_t> mapper_generation_{0};  // a cleared map's late frames are not counted
  std::vector<Eigen::Vector3d> trajectory_world_;  // camera positions of the frames taken
  std::uint64_t received_ = 0, replaced_ = 0, late_ = 0, unreadable_ = 0, dropped_before_ = 0, fused_before_ = 0;
  std::uint64_t no_ground_ = 0;
  Gauge latency_, arrival_, perception_, fusion_, grid_map_;
  builder::DepthCheckTally checks_;
  sources::DepthUnit unit_;
  std::map<std::string, ::ros::WallTime> warned_;
  bool stopping_ = false;
  ::ros::Time map_stamp_;        // the newest frame fused
  ::ros::Time published_[5];     // the map stamp each output last published

  std::thread feeder_;
  std::unique_ptr<app::serve::MapSource> served_;
  std::unique_ptr<app::serve::Api> api_;
  std::unique_ptr<app::serve::HttpServer> http_;
  std::thread http_thread_;
};

}  // namespace mobmap::ros1
