// The live core's outputs as ROS 1 messages.
#include "outputs.hpp"

#include <cstring>

namespace mobmap::ros1 {
namespace {

geometry_msgs::Pose pose(const live::WorldPose& w) {
  geometry_msgs::Pose p;
  p.position.x = w.position.x();
  p.position.y = w.position.y();
  p.position.z = w.position.z();
  p.orientation.x = w.orientation.x();
  p.orientation.y = w.orientation.y();
  p.orientation.z = w.orientation.z();
  p.orientation.w = w.orientation.w();
  return p;
}

}  // namespace

sensor_msgs::PointCloud2 mobilityCloud(const mapping::MobilityMap& map, const std::string& world_frame, const ros::Time& stamp) {
  sensor_msgs::PointCloud2 c;
  c.header.frame_id = world_frame;
  c.header.stamp = stamp;
  for (const char* name : {"x", "y", "z", "mobility", "variance"}) {
    sensor_msgs::PointField f;
    f.name = name;
    f.offset = static_cast<std::uint32_t>(4 * c.fields.size());
    f.datatype = sensor_msgs::PointField::FLOAT32;
    f.count = 1;
    c.fields.push_back(f);
  }
  c.point_step = 20;
  c.is_bigendian = false;
  c.is_dense = false;
  c.height = 1;
  const std::vector<float> values = live::mobilityCloudValues(map);
  c.width = static_cast<std::uint32_t>(values.size() / 5);
  c.row_step = c.point_step * c.width;
  c.data.resize(values.size() * sizeof(float));
  if (!values.empty()) std::memcpy(c.data.data(), values.data(), c.data.size());
  return c;
}

nav_msgs::OccupancyGrid occupancyGrid(const live::Occupancy& o, const std::string& world_frame, const ros::Time& stamp) {
  nav_msgs::OccupancyGrid g;
  g.header.frame_id = world_frame;
  g.header.stamp = stamp;
  g.info.map_load_time = stamp;
  g.info.resolution = static_cast<float>(o.cell_m);
  g.info.width = static_cast<std::uint32_t>(o.cols);
  g.info.height = static_cast<std::uint32_t>(o.rows);
  g.info.origin = pose(o.origin);
  g.data = o.data;
  return g;
}

msg::GridMap gridMap(const live::GridMapData& d, const std::string& world_frame, const ros::Time& stamp) {
  msg::GridMap g;
  g.info.header.frame_id = world_frame;
  g.info.header.stamp = stamp;
  g.info.resolution = d.resolution;
  g.info.length_x = d.length_x;
  g.info.length_y = d.length_y;
  g.info.pose = pose(d.pose);
  const auto nx = static_cast<std::uint32_t>(d.cols), ny = static_cast<std::uint32_t>(d.rows);
  for (std::size_t k = 0; k < d.layers.size(); ++k) {
    std_msgs::Float32MultiArray a;
    a.layout.dim.resize(2);
    a.layout.dim[0].label = "column_index";
    a.layout.dim[0].size = ny;
    a.layout.dim[0].stride = nx * ny;
    a.layout.dim[1].label = "row_index";
    a.layout.dim[1].size = nx;
    a.layout.dim[1].stride = nx;
    a.data = d.data[k];
    g.layers.push_back(d.layers[k]);
    g.data.push_back(std::move(a));
  }
  g.basic_layers = {"elevation"};
  return g;
}

msg::Octomap octomapMessage(const mapping::MobilityMap& map, const std::string& map_frame, const ros::Time& stamp) {
  msg::Octomap m;
  m.header.frame_id = map_frame;
  m.header.stamp = stamp;
  m.binary = true;
  m.id = "OcTree";
  m.resolution = map.tree().getResolution();
  const std::string bytes = live::octomapBinary(map);
  m.data.resize(bytes.size());
  if (!bytes.empty()) std::memcpy(m.data.data(), bytes.data(), bytes.size());
  return m;
}

}  // namespace mobmap::ros1
