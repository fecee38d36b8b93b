#pragma once
// Messages of packages Debian does not ship, defined here field for field as upstream
// defines them for ROS 1, so that their MD5 sums are upstream's and upstream subscribers
// (grid_map_rviz_plugin, octomap_rviz_plugins, elevation_mapping's consumers) take them:
//   grid_map_msgs/GridMap, grid_map_msgs/GridMapInfo (ANYbotics/grid_map, ROS 1 branch)
//   octomap_msgs/Octomap (OctoMap/octomap_msgs)
// The full definitions name their dependencies as ROS's generators write them; the
// dependencies' own texts come from Debian's headers of those messages.
#include <geometry_msgs/Pose.h>
#include <ros/message_traits.h>
#include <ros/serialization.h>
#include <std_msgs/Float32MultiArray.h>
#include <std_msgs/Header.h>

#include <boost/shared_ptr.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace mobmap::ros1::msg {

struct GridMapInfo {
  std_msgs::Header header;
  double resolution = 0;
  double length_x = 0;
  double length_y = 0;
  geometry_msgs::Pose pose;
};

struct GridMap {
  GridMapInfo info;
  std::vector<std::string> layers;
  std::vector<std::string> basic_layers;
  std::vector<std_msgs::Float32MultiArray> data;
  std::uint16_t outer_start_index = 0;
  std::uint16_t inner_start_index = 0;
  using Ptr = boost::shared_ptr<GridMap>;
  using ConstPtr = boost::shared_ptr<const GridMap>;
};

struct Octomap {
  std_msgs::Header header;
  bool binary = true;
  std::string id;
  double resolution = 0;
  std::vector<std::int8_t> data;
  using Ptr = boost::shared_ptr<Octomap>;
  using ConstPtr = boost::shared_ptr<const Octomap>;
};

/// The message texts (comments left out: they do not enter the MD5 sum).
inline const char* gridMapText() {
  return "GridMapInfo info\n"
         "string[] layers\n"
         "string[] basic_layers\n"
         "std_msgs/Float32MultiArray[] data\n"
         "uint16 outer_start_index\n"
         "uint16 inner_start_index\n";
}
inline const char* gridMapInfoText() {
  return "Header header\n"
         "float64 resolution\n"
         "float64 length_x\n"
         "float64 length_y\n"
         "geometry_msgs/Pose pose\n";
}
inline const char* octomapText() {
  return "Header header\n"
         "bool binary\n"
         "string id\n"
         "float64 resolution\n"
         "int8[] data\n";
}

/// A full definition as ROS's generators write it: the message, then each type it uses.
std::string fullDefinition(const std::string& text, const std::vector<std::pair<std::string, std::string>>& uses);

}  // namespace mobmap::ros1::msg

namespace ros {
namespace message_traits {

template <>
struct IsMessage<mobmap::ros1::msg::GridMap> : TrueType {};
template <>
struct DataType<mobmap::ros1::msg::GridMap> {
  static const char* value() { return "grid_map_msgs/GridMap"; }
  static const char* value(const mobmap::ros1::msg::GridMap&) { return value(); }
};
template <>
struct MD5Sum<mobmap::ros1::msg::GridMap> {
  static const char* value() { return "95681e052b1f73bf87b7eb984382b401"; }
  static const char* value(const mobmap::ros1::msg::GridMap&) { return value(); }
  static const uint64_t static_value1 = 0x95681e052b1f73bfULL;
  static const uint64_t static_value2 = 0x87b7eb984382b401ULL;
};
template <>
struct Definition<mobmap::ros1::msg::GridMap> {
  static const char* value();
  static const char* value(const mobmap::ros1::msg::GridMap&) { return value(); }
};

template <>
struct IsMessage<mobmap::ros1::msg::Octomap> : TrueType {};
template <>
struct HasHeader<mobmap::ros1::msg::Octomap> : TrueType {};
template <>
struct DataType<mobmap::ros1::msg::Octomap> {
  static const char* value() { return "octomap_msgs/Octomap"; }
  static const char* value(const mobmap::ros1::msg::Octomap&) { return value(); }
};
template <>
struct MD5Sum<mobmap::ros1::msg::Octomap> {
  static const char* value() { return "9a45536b45c5e409cd49f04bb2d9999f"; }
  static const char* value(const mobmap::ros1::msg::Octomap&) { return value(); }
  static const uint64_t static_value1 = 0x9a45536b45c5e409ULL;
  static const uint64_t static_value2 = 0xcd49f04bb2d9999fULL;
};
template <>
struct Definition<mobmap::ros1::msg::Octomap> {
  static const char* value();
  static const char* value(const mobmap::ros1::msg::Octomap&) { return value(); }
};

}  // namespace message_traits

namespace serialization {

template <>
struct Serializer<mobmap::ros1::msg::GridMapInfo> {
  template <typename Stream, typename T>
  inline static void allInOne(Stream& stream, T m) {
    stream.next(m.header);
    stream.next(m.resolution);
    stream.next(m.length_x);
    stream.next(m.length_y);
    stream.next(m.pose);
  }
  ROS_DECLARE_ALLINONE_SERIALIZER
};

template <>
struct Serializer<mobmap::ros1::msg::GridMap> {
  template <typename Stream, typename T>
  inline static void allInOne(Stream& stream, T m) {
    stream.next(m.info);
    stream.next(m.layers);
    stream.next(m.basic_layers);
    stream.next(m.data);
    stream.next(m.outer_start_index);
    stream.next(m.inner_start_index);
  }
  ROS_DECLARE_ALLINONE_SERIALIZER
};

template <>
struct Serializer<mobmap::ros1::msg::Octomap> {
  template <typename Stream, typename T>
  inline static void allInOne(Stream& stream, T m) {
    stream.next(m.header);
    stream.next(m.binary);
    stream.next(m.id);
    stream.next(m.resolution);
    stream.next(m.data);
  }
  ROS_DECLARE_ALLINONE_SERIALIZER
};

}  // namespace serialization
}  // namespace ros
