#pragma once
// A robot's recording: a ROS 2 bag (a folder with metadata.yaml, a .db3 file or an
// .mcap file), its depth images with their camera's intrinsics, and each image's camera
// pose in a world frame, composed through the recording's TF tree at the image's stamp.
//
// Opening reads the recording once, keeping the TF tree, the camera_info and IMU
// readings and, for each image, only where it lies and its stamp; load() decodes one
// image when it is needed, so memory does not grow with the length of the recording.

#include "mobmap/perception/camera.hpp"
#include "mobmap/sources/tf_tree.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace mobmap::sources {

struct RecordingOptions {
  std::string depth_topic;        ///< empty: the recording's only depth image topic
  std::string camera_info_topic;  ///< empty: the camera_info in the depth topic's namespace
  std::string world_frame;        ///< empty: "map" when the tree has it, else "odom", else the camera's root
  /// The sensor_msgs/Imu topic gravity is estimated from; empty: none when the world
  /// frame is map or odom (z up, REP 105), else the recording's only Imu topic.
  std::string imu_topic;
  /// Intrinsics given instead of a camera_info topic (none is needed then), from the
  /// size of the depth images.
  std::function<perception::PinholeIntrinsics(int width, int height)> intrinsics;
  /// Camera poses from elsewhere (`--poses`: a trajectory matched by stamp) instead of
  /// the TF tree: an image's pose is what this gives for its stamp (nullopt: skipped).
  /// The world frame is then the trajectory's (worldFrame() is empty) and gravity is not
  /// known from the recording.
  std::function<std::optional<Eigen::Isometry3d>(std::int64_t stamp_ns)> poses;
  /// An image whose transforms on the way to the world frame have no samples around its
  /// stamp within this many seconds of each other is skipped.
  double max_pose_gap_s = 0.05;
  /// To describe a recording (`mobmap info`): a recording whose topics or frames cannot be
  /// chosen still opens, with problem() saying why; its frames are then empty.
  bool describe_only = false;
};

struct TopicSummary {
  std::string name;
  std::string type;  ///< "sensor_msgs/Image"
  std::size_t count = 0;
  double rate_hz = 0.0;  ///< messages per second between the first and the last; 0 for fewer than two
};

/// One depth image, decoded.
struct RecordingFrame {
  int number = 0;
  std::int64_t stamp_ns = 0;
  std::string frame_id;
  perception::DepthImage depth;  ///< metres; 0 where invalid; undistorted when the camera_info has distortion
  std::optional<Eigen::Isometry3d> T_world_camera;
};

/// True for what open() reads: a .mcap, .db3, .bag or .bag.active file, a folder with
/// metadata.yaml, or one with .db3 / .mcap files and no metadata.yaml (a crashed recorder's).
bool isRecording(const std::string& path);

class Recording {
 public:
  /// Opens and indexes `path`, and decodes its first depth image. IoError naming the
  /// file and what is wrong: not a recording, no depth topic or several (the candidates
  /// listed), a depth encoding that is not depth, a big-endian image, rows that do not
  /// match the width, an image whose size differs from its camera_info, a world or camera frame missing from the
  /// TF tree (its frames listed), a TF cycle or a frame with two parents.
  /// A recording whose bytes end early or fail a check is read up to that point; fault()
  /// says where.
  static std::unique_ptr<Recording> open(const std::string& path, const RecordingOptions& options = {});
  virtual ~Recording() = default;

  [[nodiscard]] virtual const std::string& path() const = 0;
  [[nodiscard]] virtual std::string format() const = 0;  ///< "ROS 2 bag (MCAP)", "ROS 2 bag (sqlite3)"
  [[nodiscard]] virtual const std::vector<TopicSummary>& topics() const = 0;
  [[nodiscard]] virtual const TfTree& tf() const = 0;
  [[nodiscard]] virtual const std::string& depthTopic() const = 0;
  [[nodiscard]] virtual const std::string& cameraInfoTopic() const = 0;  ///< empty when intrinsics were given
  [[nodiscard]] virtual const std::string& worldFrame() const = 0;  ///< empty with RecordingOptions::poses
  [[nodiscard]] virtual const std::string& cameraFrame() const = 0;  ///< the first depth image's frame_id
  [[nodiscard]] virtual const perception::PinholeIntrinsics& intrinsics() const = 0;
  /// The depth images' values per metre as stored: 1000 for 16UC1, 1 for 32FC1.
  [[nodiscard]] virtual double depthUnitsPerMetre() const = 0;
  /// How the camera_info's distortion was handled ("plumb_bob distortion undone"), or "".
  [[nodiscard]] virtual const std::string& distortionNote() const = 0;
  /// Gravity (down) in the world frame: from the IMU's accelerometer while the robot was
  /// still, taken to the world frame through the TF tree (when an Imu topic is chosen),
  /// else from the world frame when it says it (REP 105: map and odom are z up).
  [[nodiscard]] virtual std::optional<Eigen::Vector3d> gravityDown() const = 0;
  [[nodiscard]] virtual std::string gravitySource() const = 0;
  /// Depth images on the depth topic, numbered 0.. in stamp order.
  [[nodiscard]] virtual int imageCount() const = 0;
  /// Numbers of the images with a pose, ascending.
  [[nodiscard]] virtual const std::vector<int>& frames() const = 0;
  [[nodiscard]] virtual std::optional<Eigen::Isometry3d> pose(int n) const = 0;
  [[nodiscard]] virtual std::int64_t stamp(int n) const = 0;
  /// Image `n`, decoded; may run on several threads at once. IoError naming the file and
  /// the image when it cannot be decoded.
  [[nodiscard]] virtual RecordingFrame load(int n) const = 0;
  /// Images left out and why ("12 depth images without a pose ..."), or "".
  [[nodiscard]] virtual std::string skipped() const = 0;
  /// Where the recording's bytes ended early or failed a check, or "".
  [[nodiscard]] virtual const std::string& fault() const = 0;
  /// What a crashed recorder left and how it was read, or "": a ROS 2 bag folder without
  /// metadata.yaml, messages recovered from a .db3's write-ahead log, a ROS 1 bag
  /// without its index (a `.bag.active`) read chunk by chunk.
  [[nodiscard]] virtual std::string recovered() const = 0;
  /// With RecordingOptions::describe_only: why no frames could be chosen, or "".
  [[nodiscard]] virtual const std::string& problem() const = 0;
  [[nodiscard]] virtual std::vector<std::string> files() const = 0;
  /// Bytes held by the index, the TF tree and the readings kept.
  [[nodiscard]] virtual std::size_t memoryBytes() const = 0;
};

}  // namespace mobmap::sources
