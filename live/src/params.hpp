#pragma once
// The live nodes' parameters (mobmap_node on ROS 1, mobmap_ros2 over DDS): one set, one
// meaning, one check (docs/ROS.md).
#include "mobmap/mapping/reachability.hpp"

#include <string>
#include <vector>

namespace mobmap::live {

struct Params {
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
  std::string save_path = "mobmap_map.ot";  ///< save_map writes here
  std::string save_on_exit;                 ///< non-empty: save here on shutdown
  int http_port = -1;                       ///< >= 0: serve's HTTP API on the live map (0: any free port)
  std::string http_address = "127.0.0.1";
};

/// Every parameter's name, in the order docs/ROS.md lists them.
const std::vector<std::string>& paramNames();

/// Sets the parameter `name` from its text (a number, true/false, a string, a list
/// `[a, b, c]`). std::invalid_argument naming `prefix + name` when the name is unknown
/// or the text is not of its type.
void setParam(Params& p, const std::string& name, const std::string& text, const std::string& prefix = "");

/// Checks ranges and the robot limits; std::invalid_argument naming `prefix + name`.
void validate(Params& p, const std::string& prefix = "");

}  // namespace mobmap::live
