// This build has no ROS 1 libraries (librosbag-storage-dev): every .bag is read by
// scanning its records (ros1_scan.cpp), indexed or not.

#include "container.hpp"

namespace mobmap::sources {

std::unique_ptr<Container> openRos1Bag(const std::string& path) { return openRos1Unindexed(path); }

}  // namespace mobmap::sources
