#pragma once
// One depth frame as every reader gives it: a frame of a sequence (7-Scenes, TUM, .pcd
// frames, a recording, OpenNI2) or a single file, which is a sequence of one frame.

#include "mobmap/perception/camera.hpp"
#include "mobmap/sources/png.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <optional>
#include <string>
#include <vector>

namespace mobmap::sources {

/// The unit depth was read in: `units_per_m` of the input's depth values (or cloud
/// coordinates) to a metre, and whether it came as a cloud (whose coordinates are
/// scaled) rather than a depth image.
struct DepthUnit {
  double units_per_m = 1000.0;
  bool cloud = false;
};

struct Frame {
  int number = 0;           ///< in its sequence, as `build --frames` numbers them
  std::string description;  ///< "frame 12 of DIR", "FILE.pcd (organized 640x480)"
  /// Either a depth image with its camera's intrinsics ...
  std::optional<perception::DepthImage> depth;
  perception::PinholeIntrinsics intrinsics;
  /// ... or a cloud in the camera frame (organized when width * height == points.size()
  /// and height > 1).
  std::vector<Eigen::Vector3f> points;
  int width = 0;
  int height = 0;
  /// Camera to world; unset for a lone file and for a stream's frame without a pose
  /// within the tolerance (not to be fused).
  std::optional<Eigen::Isometry3d> T_world_camera;
  std::optional<Eigen::Vector3f> gravity_camera;  ///< gravity (down) in the camera frame, when known
  std::optional<ImageRgb> colour;                 ///< for pictures, when the input has one (Sequence::colour)
  /// The files it was read from (depth image or cloud, pose file), which a command must
  /// not write over.
  std::vector<std::string> sources;
  /// When it was taken, in seconds (a TUM or bag stamp, a time in a file name, a
  /// sensor's clock); unset when the input does not say.
  std::optional<double> stamp_s;
  /// For the user, when loading chose something they did not ask for (empty if not).
  std::string note;
  /// The unit the depth (or the cloud's coordinates) was read in.
  DepthUnit depth_unit;
  /// An organized cloud whose points were not in its camera's frame: the camera's pose in
  /// the cloud's frame, fitted from the pixel grid (recoverCameraFrame). `points` then
  /// hold the camera-frame points; outputs go back to the cloud's frame with it.
  std::optional<Eigen::Isometry3d> T_cloud_camera;
};

}  // namespace mobmap::sources
