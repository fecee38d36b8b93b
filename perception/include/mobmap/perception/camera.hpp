#pragma once
/// @file camera.hpp
/// Pinhole camera model and depth images (camera frame, OpenCV axes: x right,
/// y down, z forward; metres).

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <vector>

namespace mobmap::perception {

/// Intrinsics of a pinhole depth camera. Pixel (u, v) with integer indices looks
/// along the ray ((u - cx) / fx, (v - cy) / fy, 1): the convention of 7-Scenes,
/// TUM RGB-D and PCL's organized clouds.
struct PinholeIntrinsics {
  int width = 640;
  int height = 480;
  double fx = 585.0;  ///< focal length in pixels
  double fy = 585.0;
  double cx = 320.0;  ///< principal point in pixels
  double cy = 240.0;

  bool operator==(const PinholeIntrinsics& o) const {
    return width == o.width && height == o.height && fx == o.fx && fy == o.fy && cx == o.cx &&
           cy == o.cy;
  }
};

/// Throws std::invalid_argument naming the field unless the size is positive (at most
/// 16384 per side) and the focal lengths are finite and > 0, the principal point finite.
void validate(const PinholeIntrinsics& intrinsics);

/// A depth image: metres along the optical axis (z, not range), row-major,
/// 0 where there is no measurement.
struct DepthImage {
  int width = 0;
  int height = 0;
  std::vector<float> depth_m;

  DepthImage() = default;
  DepthImage(int w, int h) : width(w), height(h), depth_m(static_cast<std::size_t>(w) * h, 0.f) {}
  [[nodiscard]] float at(int u, int v) const { return depth_m[static_cast<std::size_t>(v) * width + u]; }
  float& at(int u, int v) { return depth_m[static_cast<std::size_t>(v) * width + u]; }
};

/// A 16-bit depth value in millimetres (depth PNGs, 16UC1 images, OpenNI2) in metres;
/// 0 and 65535 mean no measurement and give 0.
inline float metresFromMillimetres(std::uint16_t mm) {
  return (mm == 0 || mm == 65535) ? 0.f : static_cast<float>(mm) * 1e-3f;
}

/// The camera-frame point seen at pixel (u, v) at depth z (metres).
inline Eigen::Vector3d backProject(const PinholeIntrinsics& k, double u, double v, double z) {
  return {(u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z};
}

/// Unit-free ray direction (z = 1) through pixel (u, v).
inline Eigen::Vector3d pixelRay(const PinholeIntrinsics& k, double u, double v) {
  return {(u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0};
}

/// Pixel coordinates of a camera-frame point (paper eq. 13), or nullopt when it is
/// behind the camera (z <= 0). The result may lie outside the image.
inline std::optional<Eigen::Vector2d> project(const PinholeIntrinsics& k, const Eigen::Vector3d& p) {
  if (!(p.z() > 0.0)) return std::nullopt;
  return Eigen::Vector2d(k.fx * p.x() / p.z() + k.cx, k.fy * p.y() / p.z() + k.cy);
}

/// Back-projects every valid pixel (depth > 0 and finite) into camera-frame points.
std::vector<Eigen::Vector3d> depthToPoints(const DepthImage& depth, const PinholeIntrinsics& k);

/// Pinhole intrinsics fitted to an organized cloud (row-major, width x height, NaN
/// or non-positive z where there is no point): least squares of u = fx x/z + cx and
/// v = fy y/z + cy over the valid pixels. `rms_px` gets the RMS reprojection residual.
/// nullopt with fewer than 100 valid points or a degenerate fit (focal length not > 0).
std::optional<PinholeIntrinsics> fitIntrinsics(const std::vector<Eigen::Vector3f>& organized, int width, int height,
                                               double* rms_px = nullptr);

/// Pixels of an organized cloud that hold no measurement, by the rules drivers store
/// them: a non-finite point, the origin, or a value repeated at another pixel (two
/// pixels' rays meet only at the camera, so a repeated point is a placeholder).
std::vector<bool> unmeasuredPoints(const std::vector<Eigen::Vector3f>& organized);

/// A point lies on its pixel's ray when the fitted camera projects it within this many
/// pixels of that pixel.
constexpr double kCameraInlierPx = 1.0;

/// The camera behind an organized cloud whose points may be in another frame than the
/// camera's (a driver's or a robot's): each valid pixel's point lies on that pixel's ray,
/// so the pixel grid gives the camera's intrinsics and its pose in the cloud's frame.
struct OrganizedCameraFit {
  PinholeIntrinsics intrinsics;
  /// Camera to cloud: a point p in the camera frame is T_cloud_camera * p in the cloud's.
  Eigen::Isometry3d T_cloud_camera = Eigen::Isometry3d::Identity();
  double rms_px = 0.0;      ///< RMS reprojection residual over the inliers
  double skew = 0.0;        ///< K(0, 1) / fx of the fitted camera (0 for a pinhole)
  std::size_t points = 0;   ///< measured points used (a grid sample of at most ~20000)
  /// The share of those points on their pixels' rays (within kCameraInlierPx).
  double inlier_share = 1.0;
  std::size_t unmeasured = 0;  ///< pixels left out as unmeasuredPoints() says
};

/// Fits a projective camera u ~ P [q; 1] to the measured points q of an organized cloud
/// (row-major, width x height; unmeasuredPoints() are left out) by the normalised
/// direct linear transform, robustly: when some points are off their pixels' rays, by
/// RANSAC over 8-point samples with a refit on the inliers. Splits P into intrinsics and
/// pose (RQ decomposition, the camera looking at its points). nullopt with fewer than 100
/// measured points or a degenerate system (the points on one plane through the camera,
/// for example). The caller judges inlier_share, rms_px and skew: a cloud that is not a
/// pinhole image has few inliers.
std::optional<OrganizedCameraFit> fitOrganizedCamera(const std::vector<Eigen::Vector3f>& organized, int width, int height);

}  // namespace mobmap::perception
