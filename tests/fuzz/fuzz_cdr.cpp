// libFuzzer target: arbitrary bytes as each ROS message mobmap decodes, in both wire
// formats (CDR, ROS 1). Each decodes or throws MessageError; what it decodes stays
// inside the bytes it was given, and an image's depth decodes or is refused with IoError.
#include "depth_decode.hpp"
#include "ros_messages.hpp"

#include "mobmap/sources/io_error.hpp"

#include <cstdint>
#include <cstdlib>

namespace {

void inside(const std::uint8_t* p, std::size_t n, const std::uint8_t* data, std::size_t size) {
  if (n > 0 && (p < data || p + n > data + size)) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace ros = mobmap::sources::ros;
  for (const ros::Wire wire : {ros::Wire::kCdr, ros::Wire::kRos1}) {
    try {
      (void)ros::decodeHeader(data, size, wire);
    } catch (const ros::MessageError&) {
    }
    try {
      const ros::Image m = ros::decodeImage(data, size, wire);
      inside(m.data, m.data_size, data, size);
      try {
        const auto d = mobmap::sources::depthFromImage(m, "image");
        if (d.depth_m.size() != static_cast<std::size_t>(d.width) * d.height) std::abort();
      } catch (const mobmap::sources::IoError&) {
      }
    } catch (const ros::MessageError&) {
    }
    try {
      const ros::CompressedImage m = ros::decodeCompressedImage(data, size, wire);
      inside(m.data, m.data_size, data, size);
      try {
        (void)mobmap::sources::depthFromCompressed(m, "image");
      } catch (const mobmap::sources::IoError&) {
      }
    } catch (const ros::MessageError&) {
    }
    try {
      const ros::CameraInfo m = ros::decodeCameraInfo(data, size, wire);
      if (m.d.size() > size) std::abort();
    } catch (const ros::MessageError&) {
    }
    try {
      if (ros::decodeTfMessage(data, size, wire).size() > size) std::abort();
    } catch (const ros::MessageError&) {
    }
    try {
      (void)ros::decodeImu(data, size, wire);
    } catch (const ros::MessageError&) {
    }
    try {
      const ros::PointCloud2 m = ros::decodePointCloud2(data, size, wire);
      inside(m.data, m.data_size, data, size);
      if (ros::cloudXyz(m).size() > size) std::abort();
    } catch (const ros::MessageError&) {
    }
  }
  return 0;
}
