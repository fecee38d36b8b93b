#pragma once
// One depth frame as every reader gives it: a frame of a sequence (7-Scenes, TUM, .pcd
// frames, OpenNI2) or a single file, which is a sequence of one frame.

#include "io/depth_checks.hpp"
#include "io/png_io.hpp"

#include "mobmap/perception/camera.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <optional>
#include <string>
#include <vector>

namespace mobmap::app {

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
  /// For the user, when loading chose something they did not ask for (empty if not).
  std::string note;
  /// The unit the depth (or the cloud's coordinates) was read in.
  DepthUnit depth_unit;
  /// An organized cloud whose points were not in its camera's frame: the camera's pose in
  /// the cloud's frame, fitted from the pixel grid (recoverCameraFrame). `points` then
  /// hold the camera-frame points; outputs go back to the cloud's frame with it.
  std::optional<Eigen::Isometry3d> T_cloud_camera;
};

}  // namespace mobmap::app
