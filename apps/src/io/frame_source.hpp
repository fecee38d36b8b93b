#pragma once
// Loading one frame for `mobmap analyze`: a PCD file, a 16-bit depth PNG with
// intrinsics, or one frame of a 7-Scenes layout or TUM RGB-D directory.

#include "io/depth_checks.hpp"
#include "io/png_io.hpp"

#include "mobmap/perception/camera.hpp"
#include "mobmap/perception/pipeline.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <optional>
#include <string>
#include <vector>

namespace mobmap::app {

class Sequence;

struct LoadedFrame {
  std::string description;  ///< "frame 12 of DIR", "FILE.pcd (organized 640x480)"
  /// Either a depth image with intrinsics ...
  std::optional<perception::DepthImage> depth;
  perception::PinholeIntrinsics intrinsics;
  /// ... or a cloud (organized when width * height == points.size() and height > 1).
  std::vector<Eigen::Vector3f> points;
  int width = 0;
  int height = 0;
  std::optional<ImageRgb> colour;                 ///< for overlays, when the input has one
  std::optional<Eigen::Vector3f> gravity_camera;  ///< gravity (down) in the camera frame
  std::optional<Eigen::Matrix4d> T_world_camera;
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

/// The pinhole camera behind an organized cloud, fitted from its pixel grid: in the
/// cloud's own frame (perception::fitIntrinsics), else in another frame with the
/// camera's pose in it (perception::fitOrganizedCamera). A fit counts with an RMS under
/// 0.5 px (and no skew). nullopt when neither fits; `best_rms_px` (if given) then gets
/// the RMS of the pose fit, NaN when none could be made.
struct CloudCamera {
  perception::PinholeIntrinsics intrinsics;
  double rms_px = 0.0;
  std::optional<Eigen::Isometry3d> T_cloud_camera;  ///< unset: the cloud is in the camera's frame
};
std::optional<CloudCamera> fitCloudCamera(const std::vector<Eigen::Vector3f>& organized, int width, int height,
                                          double* best_rms_px = nullptr);

/// A cloud's finite points taken from its frame to its camera's (T_cloud_camera
/// inverted); the others are left as they are.
void toCameraFrame(std::vector<Eigen::Vector3f>& points, const Eigen::Isometry3d& T_cloud_camera);

/// For an organized cloud (height > 1) whose points are not a pinhole image in the
/// camera frame: fits the camera from the pixel grid (perception::fitOrganizedCamera)
/// and, when it fits (RMS under 0.5 px, no skew), moves the points into the camera frame
/// and sets T_cloud_camera and a note. When no camera fits, the note says the frame
/// cannot be recovered and the cloud is scored as it is. A cloud already in its
/// camera's frame is left alone.
void recoverCameraFrame(LoadedFrame& f, const std::string& path);

/// The frame's results taken to the frame of the input's points: the cloud's when
/// T_cloud_camera is set (points, normals, segment centroids and normals, ground
/// plane); unchanged otherwise. Slopes, roughness and mobility do not change.
void toInputFrame(perception::FrameResult& r, const LoadedFrame& f);

/// Reads `f`'s depth (or cloud coordinates) at `units_per_m` instead of the unit it was
/// read in (`--depth-scale`). UsageError unless positive and finite.
void rescaleDepth(LoadedFrame& f, double units_per_m);

/// Reads a PCD file (x y z, optional rgb/rgba) with PCL. IoError naming the file if it
/// is missing, unreadable, has no x/y/z fields or fewer points than declared. With
/// `recover_camera`, an organized cloud goes through recoverCameraFrame().
LoadedFrame loadPcd(const std::string& path, bool recover_camera = true);
/// Checks cheaply (header only, no point parsed) that a .pcd can be loaded: a readable
/// header with x, y and z, and for binary and binary_compressed data at least the bytes
/// the header declares. ASCII data is not checked (counting its lines means reading it).
/// IoError naming the file if not.
void checkPcdComplete(const std::string& path);


/// Runs `pipeline` on a loaded frame: its depth image, else its cloud (organized when
/// it has more than one row).
perception::FrameResult perceiveFrame(const perception::FramePipeline& pipeline, const LoadedFrame& f,
                                      const std::optional<Eigen::Vector3f>& gravity_down_camera);

/// For a frame perceived without gravity, a note for the user on how its ground was
/// chosen, or empty: when the largest plane leaned away from the image's up axis and a
/// floor within `upright_prior_deg` of it was taken instead (the camera assumed
/// upright), and when the ground is the largest plane and more than 45 degrees from
/// that axis: "may be a wall" when a surface within 30 degrees of that axis (the floor of
/// an upright camera) is in view too; nothing when none is and surfaces parallel to the
/// plane lie at other heights (levels seen from above: treads, a floor); else that it is
/// a floor seen from above or a wall. `analyze` and `build` both take `--gravity`.
std::string groundChoiceNote(const perception::FrameResult& r, double upright_prior_deg);

/// Parses "X,Y,Z" (non-zero, finite), a direction: returned as a unit vector. Throws
/// UsageError.
Eigen::Vector3f parseVector3(const std::string& spec, const std::string& what);

/// Frame `frame` of `seq` (opened from `input`, which errors name): its depth, pose,
/// intrinsics and colour image. IoError naming the frames there are if `seq` has no
/// frame with that number.
LoadedFrame loadSequenceFrame(const Sequence& seq, const std::string& input, int frame);

/// Loads INPUT as `mobmap analyze` describes it. `frame` picks the frame of a
/// directory (-1: the first one), numbered as `build` numbers them. `intrinsics_spec`
/// is required for a PNG unless a camera-intrinsics.txt lies beside it (then `note`
/// says it was used).
LoadedFrame loadSingleFrame(const std::string& input, int frame, const std::string& intrinsics_spec);

}  // namespace mobmap::app
