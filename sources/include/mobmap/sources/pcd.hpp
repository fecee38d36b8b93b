#pragma once
// PCD files (PCL's reader, checked against hostile headers first), and the pinhole
// camera behind an organized cloud, fitted from its pixel grid.

#include "mobmap/sources/frame.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <optional>
#include <string>
#include <vector>

namespace mobmap::sources {

/// Reads a PCD file (x y z, optional rgb/rgba) with PCL. IoError naming the file if it
/// is missing, unreadable, has no x/y/z fields or fewer points than declared. With
/// `recover_camera`, an organized cloud goes through recoverCameraFrame().
Frame loadPcd(const std::string& path, bool recover_camera = true);
/// Checks cheaply (header only, no point parsed) that a .pcd can be loaded: a readable
/// header with x, y and z, and for binary and binary_compressed data at least the bytes
/// the header declares. ASCII data is not checked (counting its lines means reading it).
/// IoError naming the file if not.
void checkPcdComplete(const std::string& path);

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
void recoverCameraFrame(Frame& f, const std::string& path);

}  // namespace mobmap::sources
