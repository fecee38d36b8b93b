#pragma once
// Depth from a ROS image message: sensor_msgs/Image in 16UC1 (millimetres) or 32FC1
// (metres), and sensor_msgs/CompressedImage in image_transport's compressedDepth form (a
// 12-byte header, then a PNG of the 16-bit depth or, for 32FC1, of quantised inverse
// depth). Everything else is refused by name.

#include "ros_messages.hpp"

#include "mobmap/perception/camera.hpp"

#include <string>

namespace mobmap::sources {

/// Whether images in `encoding` are depth (16UC1, 32FC1; "mono16" and colour are not).
bool isDepthEncoding(const std::string& encoding);
/// The encoding of a compressedDepth image ("16UC1" of "16UC1; compressedDepth png"),
/// or "" when the format is not compressedDepth.
std::string compressedDepthEncoding(const std::string& format);

/// IoError(`what`, reason) when the image is not depth mobmap reads: another encoding, big
/// endian, rows shorter than the width or data that does not hold its rows.
perception::DepthImage depthFromImage(const ros::Image& m, const std::string& what);
perception::DepthImage depthFromCompressed(const ros::CompressedImage& m, const std::string& what);

}  // namespace mobmap::sources
