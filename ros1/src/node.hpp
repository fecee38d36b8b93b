#pragma once
// mobmap_node: maps live from a robot's depth camera and TF, and publishes the map as
// RViz, move_base and footstep planners read it (docs/ROS.md). The ROS 1 front of the
// live core (live/src/core.hpp), which mobmap_ros2 shares.
#include "core.hpp"

#include <image_transport/image_transport.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_srvs/Empty.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include <memory>
#include <string>
#include <vector>

namespace mobmap::ros1 {

/// Reads the private parameters; std::invalid_argument naming the parameter.
live::Params readParams(const ::ros::NodeHandle& pnh);

class Node : public live::Transforms {
 public:
  Node(::ros::NodeHandle nh, ::ros::NodeHandle pnh, live::Params params);
  ~Node() override;
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;
  /// Stops taking frames, fuses what was taken, saves to ~save_on_exit if set.
  void shutdown();

  // live::Transforms over tf2's buffer.
  bool has(const std::string& frame) override;
  std::optional<std::string> root(const std::string& frame) override;
  std::optional<Eigen::Isometry3d> lookup(const std::string& target, const std::string& source, std::int64_t stamp_ns,
                                          std::string* error) override;

 private:
  void onInfo(const sensor_msgs::CameraInfoConstPtr& m);
  void onImage(const sensor_msgs::ImageConstPtr& m);
  void onCompressed(const sensor_msgs::CompressedImageConstPtr& m);
  void onPoints(const sensor_msgs::PointCloud2ConstPtr& m);
  void onImu(const sensor_msgs::ImuConstPtr& m);

  void publishCloud();
  void publishOccupancy();
  void publishGridMap();
  void publishOctomap();
  void publishStatus();
  bool onSave(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res);
  bool onClear(std_srvs::Empty::Request&, std_srvs::Empty::Response&);

  ::ros::NodeHandle nh_, pnh_;
  tf2_ros::Buffer tf_;
  tf2_ros::TransformListener tf_listener_;
  tf2_ros::StaticTransformBroadcaster static_tf_;
  image_transport::ImageTransport it_;
  image_transport::Subscriber image_sub_;
  ::ros::Subscriber info_sub_, compressed_sub_, points_sub_, imu_sub_;
  ::ros::Publisher cloud_pub_, occupancy_pub_, grid_map_pub_, octomap_pub_, status_pub_;
  ::ros::ServiceServer save_srv_, clear_srv_;
  std::vector<::ros::WallTimer> timers_;
  std::unique_ptr<live::Core> core_;
};

}  // namespace mobmap::ros1
