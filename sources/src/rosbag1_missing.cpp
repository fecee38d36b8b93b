// This build has no ROS 1 libraries (librosbag-storage-dev): .bag files are refused
// with the reason.

#include "container.hpp"

#include "mobmap/sources/io_error.hpp"

namespace mobmap::sources {

std::unique_ptr<Container> openRos1Bag(const std::string& path) {
  throw IoError(path, "this mobmap was built without ROS 1 bag support (install librosbag-storage-dev and catkin, "
                      "as scripts/setup.sh does, and build again)");
}

}  // namespace mobmap::sources
