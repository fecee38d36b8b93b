// Map snapshots as ROS messages.
#include "outputs.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

namespace mobmap::ros1 {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

geometry_msgs::Pose poseInWorld(const mapping::MobilityMap& map, const Eigen::Vector3d& p_map) {
  const Eigen::Vector3d p = map.mapToWorld(p_map);
  const Eigen::Quaterniond q(map.rotationMapWorld().transpose());
  geometry_msgs::Pose pose;
  pose.position.x = p.x();
  pose.position.y = p.y();
  pose.position.z = p.z();
  pose.orientation.x = q.x();
  pose.orientation.y = q.y();
  pose.orientation.z = q.z();
  pose.orientation.w = q.w();
  return pose;
}

void addField(sensor_msgs::PointCloud2& c, const std::string& name) {
  sensor_msgs::PointField f;
  f.name = name;
  f.offset = static_cast<std::uint32_t>(4 * c.fields.size());
  f.datatype = sensor_msgs::PointField::FLOAT32;
  f.count = 1;
  c.fields.push_back(f);
}

}  // namespace

sensor_msgs::PointCloud2 mobilityCloud(const mapping::MobilityMap& map, const std::string& world_frame, const ros::Time& stamp) {
  sensor_msgs::PointCloud2 c;
  c.header.frame_id = world_frame;
  c.header.stamp = stamp;
  for (const char* name : {"x", "y", "z", "mobility", "variance"}) addField(c, name);
  c.point_step = 20;
  c.is_bigendian = false;
  c.is_dense = false;
  c.height = 1;
  const mapping::MobilityOcTree& tree = map.tree();
  const double res = tree.getResolution();
  std::vector<float> values;
  const auto add = [&](const Eigen::Vector3d& centre_map, const mapping::MobilityOcTreeNode& node) {
    const Eigen::Vector3d p = map.mapToWorld(centre_map);
    values.push_back(static_cast<float>(p.x()));
    values.push_back(static_cast<float>(p.y()));
    values.push_back(static_cast<float>(p.z()));
    values.push_back(node.hasMobility() ? static_cast<float>(node.mobility()) : kNaN);
    values.push_back(node.hasMobility() ? static_cast<float>(node.variance()) : kNaN);
  };
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) {
    if (!tree.isNodeOccupied(*it)) continue;
    const double size = it.getSize();
    const Eigen::Vector3d centre(it.getX(), it.getY(), it.getZ());
    if (size <= res * 1.5) {
      add(centre, *it);
      continue;
    }
    // A pruned block: each of its voxels.
    const int n = static_cast<int>(std::lround(size / res));
    const Eigen::Vector3d corner = centre - Eigen::Vector3d::Constant(size / 2 - res / 2);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j)
        for (int k = 0; k < n; ++k) add(corner + res * Eigen::Vector3d(i, j, k), *it);
  }
  c.width = static_cast<std::uint32_t>(values.size() / 5);
  c.row_step = c.point_step * c.width;
  c.data.resize(values.size() * sizeof(float));
  if (!values.empty()) std::memcpy(c.data.data(), values.data(), c.data.size());
  return c;
}

nav_msgs::OccupancyGrid occupancyGrid(const mapping::MobilityMap& map, const mapping::LevelLayers& l,
                                      const std::string& world_frame, const ros::Time& stamp) {
  nav_msgs::OccupancyGrid g;
  g.header.frame_id = world_frame;
  g.header.stamp = stamp;
  g.info.map_load_time = stamp;
  g.info.resolution = static_cast<float>(l.cell_m);
  g.info.width = static_cast<std::uint32_t>(l.cols);
  g.info.height = static_cast<std::uint32_t>(l.rows);
  g.info.origin = poseInWorld(map, Eigen::Vector3d(l.x_min, l.y_min, l.level.z_m));
  g.data.assign(static_cast<std::size_t>(l.cols) * static_cast<std::size_t>(l.rows), -1);
  if (l.traversable.empty()) return g;
  // OccupancyGrid rows run from the origin along +y; the layers' row 0 is the highest y.
  for (int r = 0; r < l.rows; ++r) {
    for (int col = 0; col < l.cols; ++col) {
      const mapping::Traversable t = l.traversable[l.index(l.rows - 1 - r, col)];
      g.data[static_cast<std::size_t>(r) * l.cols + col] =
          t == mapping::Traversable::kFree ? 0 : t == mapping::Traversable::kOccupied ? 100 : -1;
    }
  }
  return g;
}

msg::GridMap gridMap(const mapping::MobilityMap& map, const mapping::LevelLayers& l, const std::string& world_frame,
                     const ros::Time& stamp) {
  msg::GridMap g;
  g.info.header.frame_id = world_frame;
  g.info.header.stamp = stamp;
  g.info.resolution = l.cell_m;
  g.info.length_x = l.cols * l.cell_m;
  g.info.length_y = l.rows * l.cell_m;
  g.info.pose = poseInWorld(map, Eigen::Vector3d(l.x_min + 0.5 * l.cols * l.cell_m, l.y_min + 0.5 * l.rows * l.cell_m, 0.0));
  // Elevation along the world's z (the map's z is gravity's up; the world's is too when
  // the world frame is map or odom).
  const double z0 = map.mapToWorld(Eigen::Vector3d::Zero()).z();
  const std::size_t nx = static_cast<std::size_t>(l.cols), ny = static_cast<std::size_t>(l.rows);
  const auto layer = [&](const std::string& name, const std::vector<float>& values, double offset) {
    std_msgs::Float32MultiArray a;
    a.layout.dim.resize(2);
    a.layout.dim[0].label = "column_index";
    a.layout.dim[0].size = static_cast<std::uint32_t>(ny);
    a.layout.dim[0].stride = static_cast<std::uint32_t>(nx * ny);
    a.layout.dim[1].label = "row_index";
    a.layout.dim[1].size = static_cast<std::uint32_t>(nx);
    a.layout.dim[1].stride = static_cast<std::uint32_t>(nx);
    a.data.resize(nx * ny);
    // grid_map index (i, j): i along -x from the largest x, j along -y from the largest y;
    // column-major (i fastest). The layers' (row 0 = largest y, col 0 = smallest x).
    for (std::size_t j = 0; j < ny; ++j)
      for (std::size_t i = 0; i < nx; ++i) {
        const float v = values[l.index(static_cast<int>(j), static_cast<int>(nx - 1 - i))];
        a.data[j * nx + i] = std::isnan(v) ? v : static_cast<float>(v + offset);
      }
    g.layers.push_back(name);
    g.data.push_back(std::move(a));
  };
  layer("elevation", l.elevation, z0);
  layer("mobility", l.mobility, 0.0);
  layer("step", l.step, 0.0);
  layer("slope", l.slope_deg, 0.0);
  layer("variance", l.elevation_variance, 0.0);
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
  std::stringstream s;
  map.tree().writeBinaryData(s);
  const std::string bytes = s.str();
  m.data.resize(bytes.size());
  if (!bytes.empty()) std::memcpy(m.data.data(), bytes.data(), bytes.size());
  return m;
}

}  // namespace mobmap::ros1
