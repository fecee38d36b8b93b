#pragma once
// The live core's outputs as ROS 1 messages.
#include "upstream_msgs.hpp"

#include "core.hpp"

#include <nav_msgs/OccupancyGrid.h>
#include <ros/time.h>
#include <sensor_msgs/PointCloud2.h>

#include <string>

namespace mobmap::ros1 {

/// x, y, z, mobility, variance (float32) per surface voxel, in `world_frame`.
sensor_msgs::PointCloud2 mobilityCloud(const mapping::MobilityMap& map, const std::string& world_frame, const ros::Time& stamp);

nav_msgs::OccupancyGrid occupancyGrid(const live::Occupancy& o, const std::string& world_frame, const ros::Time& stamp);

msg::GridMap gridMap(const live::GridMapData& d, const std::string& world_frame, const ros::Time& stamp);

/// The map's occupancy as octomap_msgs/Octomap (binary, id "OcTree") in `map_frame`.
msg::Octomap octomapMessage(const mapping::MobilityMap& map, const std::string& map_frame, const ros::Time& stamp);

}  // namespace mobmap::ros1
