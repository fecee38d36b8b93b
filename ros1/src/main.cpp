// mobmap_node: the ROS 1 node (docs/ROS.md). ROS's own arguments (__name:=, topic
// remappings, _param:=value) are taken by ros::init; the node has no others.
#include "node.hpp"

#include <ros/ros.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstring>

namespace {

std::atomic<bool> g_stop{false};

void onSignal(int) { g_stop.store(true); }

}  // namespace

int main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--help") == 0 || std::strcmp(argv[i], "-h") == 0) {
      std::puts(
          "mobmap_node: maps live from a depth camera and TF; publishes the mobility map\n"
          "Usage: mobmap_node [ROS remappings, e.g. depth:=/camera/depth/image_rect_raw] [_param:=value ...]\n"
          "Topics, parameters and services: docs/ROS.md. Needs a ROS master (ROS_MASTER_URI).");
      return 0;
    }
  }
  // SIGINT and SIGTERM end the node through its own shutdown, which saves ~save_on_exit.
  ros::init(argc, argv, "mobmap", ros::init_options::NoSigintHandler);
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  ros::NodeHandle nh, pnh("~");
  mobmap::live::Params params;
  try {
    params = mobmap::ros1::readParams(pnh);
  } catch (const std::exception& e) {
    ROS_FATAL("mobmap: %s", e.what());
    return 2;
  }
  int code = 0;
  try {
    mobmap::ros1::Node node(nh, pnh, params);
    ros::AsyncSpinner spinner(4);
    spinner.start();
    while (ros::ok() && !g_stop.load()) ros::WallDuration(0.05).sleep();
    ROS_INFO("mobmap: stopping");
    node.shutdown();
    spinner.stop();
  } catch (const std::exception& e) {
    ROS_FATAL("mobmap: %s", e.what());
    code = 1;
  }
  ros::shutdown();
  return code;
}
