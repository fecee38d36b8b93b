#pragma once
// What the node publishes, made from a map snapshot: plain functions of the map, so the
// tests can check them without a ROS master.
#include "upstream_msgs.hpp"

#include "mobmap/mapping/layers.hpp"
#include "mobmap/mapping/mobility_map.hpp"

#include <nav_msgs/OccupancyGrid.h>
#include <ros/time.h>
#include <sensor_msgs/PointCloud2.h>

#include <string>

namespace mobmap::ros1 {

/// The map's surface voxels as x, y, z (world frame), mobility and its variance (float32;
/// NaN where a voxel was never scored), one point per voxel, in `world_frame`.
sensor_msgs::PointCloud2 mobilityCloud(const mapping::MobilityMap& map, const std::string& world_frame, const ros::Time& stamp);

/// A level's traversable layer as nav_msgs/OccupancyGrid: free 0, occupied 100, unknown -1;
/// the grid's origin is its lower-left corner at the level's height, posed in the world frame.
nav_msgs::OccupancyGrid occupancyGrid(const mapping::MobilityMap& map, const mapping::LevelLayers& layers,
                                      const std::string& world_frame, const ros::Time& stamp);

/// Layers as grid_map_msgs/GridMap: elevation (world z), mobility, step (m), slope (deg) and
/// variance (of the elevation, m^2), grid_map's storage order (column-major, index (0, 0)
/// at the corner of largest x and y), centred on the window's centre, in `world_frame`.
msg::GridMap gridMap(const mapping::MobilityMap& map, const mapping::LevelLayers& layers, const std::string& world_frame,
                     const ros::Time& stamp);

/// The map's occupancy as octomap_msgs/Octomap (binary, id "OcTree") in `map_frame`.
msg::Octomap octomapMessage(const mapping::MobilityMap& map, const std::string& map_frame, const ros::Time& stamp);

}  // namespace mobmap::ros1
