// mobmap_ros2: the live node on ROS 2, over Cyclone DDS (docs/ROS.md).
#include "node.hpp"

#include <atomic>
#include <csignal>
#include <cstdio>
#include <exception>

namespace {

std::atomic<bool> g_stop{false};

void onSignal(int) { g_stop.store(true); }

const char* kHelp =
    "mobmap_ros2: maps live from a depth camera and TF on ROS 2 (DDS); publishes the mobility map\n"
    "Usage: mobmap_ros2 [--ros-args [-r from:=to] [-r __node:=NAME] [-r __ns:=/NS] [-p name:=value]\n"
    "                   [--params-file FILE] [--log-level debug|info|warn|error]]\n"
    "Reads /camera/depth/image_rect_raw (-r depth:=...), the camera_info beside it, /tf, /tf_static;\n"
    "publishes ~/mobility_cloud, ~/occupancy, ~/elevation_map, ~/octomap_binary, ~/status; services\n"
    "~/save_map, ~/clear_map. ROS_DOMAIN_ID picks the domain; CYCLONEDDS_URI configures DDS.\n"
    "Topics, QoS, parameters: docs/ROS.md.\n";

}  // namespace

int main(int argc, char** argv) {
  mobmap::ros2::Args args;
  try {
    args = mobmap::ros2::parseArgs(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mobmap_ros2: %s\n", e.what());
    return 2;
  }
  if (args.help) {
    std::fputs(kHelp, stdout);
    return 0;
  }
  // SIGINT and SIGTERM end the node through its own shutdown, which saves save_on_exit.
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  try {
    mobmap::ros2::Node node(args);
    if (!node.run(g_stop)) return 1;
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "mobmap_ros2: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mobmap_ros2: %s\n", e.what());
    return 1;
  }
  return 0;
}
