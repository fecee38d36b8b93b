#pragma once
// Readers of the 7-Scenes / 3DMatch directory layout and of camera files:
//   frame-NNNNNN.depth.png  16-bit, millimetres; 0 and 65535 mean "no measurement"
//   frame-NNNNNN.color.png|jpg, frame-NNNNNN.pose.txt (4x4 camera-to-world, row-major)
//   camera-intrinsics.txt (3x3 K), optional gravity-direction.txt (unit "down", world)
// mobmap's simulator adds frame-NNNNNN.labels.png (surface id per pixel) and
// ground_truth.json.

#include "mobmap/perception/camera.hpp"
#include "mobmap/sources/png.hpp"

#include <Eigen/Core>

#include <optional>
#include <string>
#include <vector>

namespace mobmap::sources {

/// Reads a camera file for images of `width` x `height`: a 3x3 camera matrix as text
/// (camera-intrinsics.txt), ROS camera_info YAML (a message dump with K, ROS 2's k, or a
/// calibration file with camera_matrix rows/cols/data) or OpenCV calibration YAML
/// ("%YAML:1.0", camera_matrix: !!opencv-matrix). Distortion coefficients are not read
/// (depth images are taken as undistorted). IoError naming the file and the problem,
/// also when a YAML file states another image size.
perception::PinholeIntrinsics readIntrinsicsFile(const std::string& path, int width, int height);
/// A camera known by its field of view is given as the intrinsics spec "fov:DEGREES".
inline constexpr const char* kFovSpecPrefix = "fov:";
/// A camera known only by its horizontal field of view: fx = fy = (width / 2) /
/// tan(fov / 2), the principal point at the image centre. util::FieldError (`intrinsics`) unless 1 < fov < 179.
perception::PinholeIntrinsics intrinsicsFromFov(double horizontal_fov_deg, int width, int height);
/// Parses "fx,fy,cx,cy" (util::FieldError naming `intrinsics` if invalid), "fov:DEGREES",
/// or reads a camera file (readIntrinsicsFile).
perception::PinholeIntrinsics parseIntrinsics(const std::string& spec, int width, int height);
/// Parses a 4x4 camera-to-world pose and checks it is rigid (mapping::checkRigid).
Eigen::Matrix4d readPoseFile(const std::string& path);
/// Parses three numbers (a direction), returned as a unit vector; IoError if missing,
/// non-finite or zero.
Eigen::Vector3d readGravityFile(const std::string& path);

/// 16-bit millimetres -> metres; 0 and 65535 become 0 ("no measurement").
perception::DepthImage readDepthPng(const std::string& path);

/// "frame-000042"
std::string frameStem(int index);

/// A directory in the 7-Scenes layout, scanned once.
class SevenScenesDirectory {
 public:
  /// Scans `dir` for frame-NNNNNN.depth.png. The intrinsics are `intrinsics_spec`
  /// (fx,fy,cx,cy or a file, as --intrinsics) when given, else camera-intrinsics.txt in
  /// `dir` and then its parent (the 3DMatch layout keeps it one level up; Microsoft's
  /// 7-Scenes download has none); image size comes from the first depth image. IoError
  /// if the directory has no frames (naming sub-folders that have them) or no
  /// intrinsics.
  explicit SevenScenesDirectory(std::string dir, const std::string& intrinsics_spec = "");

  [[nodiscard]] const std::string& dir() const { return dir_; }
  /// Frame numbers found, ascending (not necessarily contiguous).
  [[nodiscard]] const std::vector<int>& frameNumbers() const { return frames_; }
  [[nodiscard]] const perception::PinholeIntrinsics& intrinsics() const { return intrinsics_; }
  [[nodiscard]] const std::optional<Eigen::Vector3d>& gravityDown() const { return gravity_; }

  [[nodiscard]] std::string depthPath(int frame) const;
  [[nodiscard]] std::string posePath(int frame) const;
  [[nodiscard]] std::string labelsPath(int frame) const;
  /// Depth of a frame; IoError if its size differs from the intrinsics'.
  [[nodiscard]] perception::DepthImage readDepth(int frame) const;
  [[nodiscard]] Eigen::Matrix4d readPose(int frame) const;
  /// The frame's .color.png when it has the depth's size (pixel for pixel with it), else
  /// nullopt; `.color.jpg` is not read. IoError if the PNG is unreadable.
  [[nodiscard]] std::optional<ImageRgb> readColour(int frame) const;

 private:
  std::string dir_;
  std::vector<int> frames_;
  perception::PinholeIntrinsics intrinsics_;
  std::optional<Eigen::Vector3d> gravity_;
};

}  // namespace mobmap::sources
