// The full definitions of the upstream messages.
#include "upstream_msgs.hpp"

namespace mobmap::ros1::msg {

std::string fullDefinition(const std::string& text, const std::vector<std::pair<std::string, std::string>>& uses) {
  std::string out = text;
  for (const auto& [name, definition] : uses) {
    out += "\n================================================================================\nMSG: " + name + "\n" + definition;
  }
  return out;
}

}  // namespace mobmap::ros1::msg

namespace ros::message_traits {

const char* Definition<mobmap::ros1::msg::GridMap>::value() {
  static const std::string text = mobmap::ros1::msg::fullDefinition(
      mobmap::ros1::msg::gridMapText(),
      {{"grid_map_msgs/GridMapInfo", mobmap::ros1::msg::gridMapInfoText()},
       {"std_msgs/Header", Definition<std_msgs::Header>::value()},
       {"geometry_msgs/Pose", Definition<geometry_msgs::Pose>::value()},
       {"std_msgs/Float32MultiArray", Definition<std_msgs::Float32MultiArray>::value()}});
  return text.c_str();
}

const char* Definition<mobmap::ros1::msg::Octomap>::value() {
  static const std::string text = mobmap::ros1::msg::fullDefinition(
      mobmap::ros1::msg::octomapText(), {{"std_msgs/Header", Definition<std_msgs::Header>::value()}});
  return text.c_str();
}

}  // namespace ros::message_traits
