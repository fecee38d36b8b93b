#pragma once
// What every recording container (an MCAP file, a ROS 2 .db3, a ROS 1 .bag) gives the
// recording reader: its topics, one pass over its messages in the order they are
// stored, and a stored message read again by the reference that pass gave.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "ros_messages.hpp"

namespace mobmap::sources {

/// Where a message lies in its container, to read it again (meaning is the container's).
struct MessageRef {
  std::uint32_t file = 0;
  std::uint64_t a = 0, b = 0, c = 0;
};

struct ContainerTopic {
  std::string name;
  std::string type;      ///< "sensor_msgs/Image" (ROS 2's "/msg/" dropped)
  std::string encoding;  ///< "cdr", "ros1", or what the container says when neither
};

struct RawMessage {
  int topic = 0;  ///< index into topics()
  std::int64_t log_time_ns = 0;
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
  MessageRef ref;
};

/// The stored bytes end early or fail their check: the pass stops there.
struct ContainerFault {
  std::string what;  ///< "cut short at byte 123456", "chunk at byte N fails its CRC"
};

class Container {
 public:
  virtual ~Container() = default;
  /// Every message in stored order; topics() may grow during the pass (an MCAP channel
  /// is declared before its first message). Returns the fault that ended the pass early,
  /// if any. IoError when the file is not of the format at all.
  virtual std::optional<ContainerFault> scan(const std::function<void(const RawMessage&)>& visit) = 0;
  [[nodiscard]] virtual const std::vector<ContainerTopic>& topics() const = 0;
  /// The message at `ref` again; may run on several threads at once.
  [[nodiscard]] virtual std::vector<std::uint8_t> read(const MessageRef& ref) const = 0;
  /// The files it reads (for commands that must not write over them).
  [[nodiscard]] virtual std::vector<std::string> files() const = 0;
  /// How what a crashed writer left was read (a log merged, an index rebuilt), or "".
  [[nodiscard]] virtual std::string recovered() const { return {}; }
};

/// "sensor_msgs/msg/Image" -> "sensor_msgs/Image".
std::string normaliseType(const std::string& type);
/// The wire of a container topic's encoding; false when mobmap does not decode it.
bool wireOf(const std::string& encoding, ros::Wire* wire);

std::unique_ptr<Container> openMcap(const std::string& path);
std::unique_ptr<Container> openDb3(const std::string& path);
/// A ROS 1 bag (format 2.0), read record by record without its index (ros1_scan.cpp): a
/// bag without one (a `.bag.active` left by a killed `rosbag record`, or one cut short)
/// reads as far as it goes, and recovered() says so.
std::unique_ptr<Container> openRos1Bag(const std::string& path);
/// True for NAME.bag.active (what `rosbag record` writes until it closes the bag).
bool isActiveRos1Bag(const std::string& path);
/// A ROS 2 bag folder: its files in metadata.yaml's order (every .db3 / .mcap in it
/// when metadata.yaml does not list them, or when there is no metadata.yaml: a recorder
/// killed before writing it, whose folder is read as `ros2 bag reindex` would, and
/// recovered() says so). IoError for a file outside the folder.
std::unique_ptr<Container> openBagFolder(const std::string& dir);
/// True for a folder holding a .db3 or .mcap file (what a killed ROS 2 recorder leaves).
bool isBagFolderWithoutMetadata(const std::string& dir);

}  // namespace mobmap::sources
