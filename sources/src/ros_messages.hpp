#pragma once
// The few ROS messages a recording's depth, camera, TF and IMU come in, decoded from
// their two wire formats: ROS 2's CDR (a 4-byte encapsulation header, then fields
// aligned to their size from the end of that header, little- or big-endian) and ROS 1's
// serialisation (little-endian, packed, strings without a terminating NUL, a `seq` in
// every header). Every read is bounds-checked: a message that ends early or claims more
// elements than it holds throws MessageError, never reads past its bytes.

#include <array>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace mobmap::sources::ros {

enum class Wire { kCdr, kRos1 };

class MessageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Header {
  std::int64_t stamp_ns = 0;
  std::string frame_id;
};

/// sensor_msgs/Image; `data` points into the message's bytes.
struct Image {
  Header header;
  std::uint32_t height = 0, width = 0;
  std::string encoding;
  bool big_endian = false;
  std::uint32_t step = 0;
  const std::uint8_t* data = nullptr;
  std::size_t data_size = 0;
};

/// sensor_msgs/CompressedImage; `data` points into the message's bytes.
struct CompressedImage {
  Header header;
  std::string format;
  const std::uint8_t* data = nullptr;
  std::size_t data_size = 0;
};

/// sensor_msgs/CameraInfo (the fields mobmap uses).
struct CameraInfo {
  Header header;
  std::uint32_t height = 0, width = 0;
  std::string distortion_model;
  std::vector<double> d;
  std::array<double, 9> k{};
};

/// geometry_msgs/TransformStamped.
struct Transform {
  Header header;  ///< frame_id: the parent
  std::string child_frame_id;
  std::array<double, 3> translation{};
  std::array<double, 4> rotation_xyzw{};
};

/// sensor_msgs/Imu (the fields mobmap uses).
struct Imu {
  Header header;
  std::array<double, 3> linear_acceleration{};
};

/// sensor_msgs/PointField.
struct PointField {
  std::string name;
  std::uint32_t offset = 0;
  std::uint8_t datatype = 0;  ///< 7: FLOAT32
  std::uint32_t count = 0;
};

/// sensor_msgs/PointCloud2; `data` points into the message's bytes.
struct PointCloud2 {
  Header header;
  std::uint32_t height = 0, width = 0;
  std::vector<PointField> fields;
  bool big_endian = false;
  std::uint32_t point_step = 0, row_step = 0;
  const std::uint8_t* data = nullptr;
  std::size_t data_size = 0;
  bool dense = false;
};

/// Only the header: what indexing a depth image needs, without its pixels.
Header decodeHeader(const std::uint8_t* data, std::size_t size, Wire wire);
Image decodeImage(const std::uint8_t* data, std::size_t size, Wire wire);
/// rosgraph_msgs/Clock: the time in ns.
std::int64_t decodeClock(const std::uint8_t* data, std::size_t size, Wire wire);
CompressedImage decodeCompressedImage(const std::uint8_t* data, std::size_t size, Wire wire);
CameraInfo decodeCameraInfo(const std::uint8_t* data, std::size_t size, Wire wire);
/// tf2_msgs/TFMessage: at most `max_transforms` (MessageError past that).
std::vector<Transform> decodeTfMessage(const std::uint8_t* data, std::size_t size, Wire wire,
                                       std::size_t max_transforms = 100000);
Imu decodeImu(const std::uint8_t* data, std::size_t size, Wire wire);
/// At most `max_fields` fields (MessageError past that).
PointCloud2 decodePointCloud2(const std::uint8_t* data, std::size_t size, Wire wire, std::size_t max_fields = 64);
/// The cloud's x, y, z, row by row: MessageError unless they are little-endian FLOAT32
/// fields within each point and the points and rows within the data.
std::vector<std::array<float, 3>> cloudXyz(const PointCloud2& cloud);

}  // namespace mobmap::sources::ros
