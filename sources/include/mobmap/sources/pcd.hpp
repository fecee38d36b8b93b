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
/// cloud's own frame (perception::fitIntrinsics), else robustly in any frame, with the
/// camera's pose in it (perception::fitOrganizedCamera, which leaves out the pixels that
/// hold no measurement and the points off their rays). A fit counts with an RMS under
/// 0.5 px over its inliers, no skew, and at least kMinCameraInlierShare of the measured
/// points on their rays. nullopt when no camera fits; `best` (if given) then gets the
/// best fit found, to say how far it was.
constexpr double kMinCameraInlierShare = 0.6;
struct CloudCamera {
  perception::PinholeIntrinsics intrinsics;
  double rms_px = 0.0;
  double inlier_share = 1.0;  ///< of the measured points, on their pixels' rays
  std::optional<Eigen::Isometry3d> T_cloud_camera;  ///< unset: the cloud is in the camera's frame
};
std::optional<CloudCamera> fitCloudCamera(const std::vector<Eigen::Vector3f>& organized, int width, int height,
                                          std::optional<CloudCamera>* best = nullptr);

/// A cloud's finite points taken from its frame to its camera's (T_cloud_camera
/// inverted); the others are left as they are.
void toCameraFrame(std::vector<Eigen::Vector3f>& points, const Eigen::Isometry3d& T_cloud_camera);

/// What toCameraImage() left out.
struct StrayPoints {
  std::size_t placeholders = 0;  ///< finite points that hold no measurement (perception::unmeasuredPoints)
  std::size_t off_ray = 0;       ///< measured points farther than kCameraInlierPx from their pixel
  std::size_t measured = 0;      ///< finite points that are not placeholders
};
/// An organized cloud's points taken to `camera`'s frame, with the placeholders and the
/// points off their pixels' rays (under camera.intrinsics) set to NaN.
StrayPoints toCameraImage(std::vector<Eigen::Vector3f>& points, int width, const CloudCamera& camera);

/// For an organized cloud (height > 1) whose points are not a clean pinhole image in the
/// camera frame: fits the camera from the pixel grid (fitCloudCamera) and, when it fits,
/// moves the points into the camera frame (toCameraImage: placeholders and points off
/// their rays left out), and sets T_cloud_camera (when the frame is not the camera's)
/// and a note that says the fit and what was left out. When no camera fits, the note
/// says the frame cannot be recovered and the cloud is scored as it is.
void recoverCameraFrame(Frame& f, const std::string& path);

}  // namespace mobmap::sources
