#include "mobmap/sources/pcd.hpp"

#include "pcd_adapter.hpp"

#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/png.hpp"
#include "mobmap/util/plugin.hpp"

#include "mobmap/perception/camera.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

namespace mobmap::sources {
namespace {

// The PCL half of the reader, opened when the first .pcd is read.
const PcdAdapter& adapter(const std::string& path) {
  static const PcdAdapter* const loaded = [&] {
    try {
      return &util::pluginTable<PcdAdapter>("pcd", "mobmap_pcd_adapter", kPcdAdapterVersion);
    } catch (const std::runtime_error& e) {
      throw IoError(path, std::string("cannot be read: ") + e.what());
    }
  }();
  return *loaded;
}

}  // namespace

void checkPcdComplete(const std::string& path) { adapter(path).check(path); }

Frame loadPcd(const std::string& path, bool recover_camera) {
  Frame f = adapter(path).load(path);
  if (recover_camera) recoverCameraFrame(f, path);
  return f;
}

std::optional<CloudCamera> fitCloudCamera(const std::vector<Eigen::Vector3f>& organized, int width, int height,
                                          std::optional<CloudCamera>* best) {
  constexpr double kMaxRmsPx = 0.5, kMaxSkew = 0.01;
  if (best) best->reset();
  double rms = 0;
  if (const auto k = perception::fitIntrinsics(organized, width, height, &rms); k && rms < kMaxRmsPx) {
    return CloudCamera{*k, rms, 1.0, {}};
  }
  const auto fit = perception::fitOrganizedCamera(organized, width, height);
  if (!fit) return std::nullopt;
  CloudCamera camera{fit->intrinsics, fit->rms_px, fit->inlier_share, fit->T_cloud_camera};
  if (best) *best = camera;
  if (!(fit->rms_px < kMaxRmsPx) || !(std::abs(fit->skew) < kMaxSkew) || !(fit->inlier_share >= kMinCameraInlierShare)) {
    return std::nullopt;
  }
  // The camera's own frame, found by the robust fit (placeholders kept fitIntrinsics off).
  const Eigen::Isometry3d& T = *camera.T_cloud_camera;
  if (Eigen::AngleAxisd(T.linear()).angle() < 1e-6 && T.translation().norm() < 1e-5) camera.T_cloud_camera.reset();
  return camera;
}

void toCameraFrame(std::vector<Eigen::Vector3f>& points, const Eigen::Isometry3d& T_cloud_camera) {
  const Eigen::Isometry3f T_camera_cloud = T_cloud_camera.inverse().cast<float>();
  for (Eigen::Vector3f& p : points) {
    if (p.allFinite()) p = T_camera_cloud * p;
  }
}

StrayPoints toCameraImage(std::vector<Eigen::Vector3f>& points, int width, const CloudCamera& camera) {
  const std::vector<bool> unmeasured = perception::unmeasuredPoints(points);  // before the points move
  if (camera.T_cloud_camera) toCameraFrame(points, *camera.T_cloud_camera);
  StrayPoints out;
  const Eigen::Vector3f none = Eigen::Vector3f::Constant(std::nanf(""));
  for (std::size_t i = 0; i < points.size(); ++i) {
    Eigen::Vector3f& p = points[i];
    if (!p.allFinite()) continue;
    if (unmeasured[i]) {
      ++out.placeholders;
      p = none;
      continue;
    }
    ++out.measured;
    const auto uv = perception::project(camera.intrinsics, p.cast<double>());
    const Eigen::Vector2d pixel(static_cast<double>(i % static_cast<std::size_t>(width)),
                                static_cast<double>(i / static_cast<std::size_t>(width)));
    if (!uv || (*uv - pixel).norm() > perception::kCameraInlierPx) {
      ++out.off_ray;
      p = none;
    }
  }
  return out;
}

void recoverCameraFrame(Frame& f, const std::string& path) {
  if (f.height <= 1 || f.depth) return;
  std::optional<CloudCamera> best;
  const auto camera = fitCloudCamera(f.points, f.width, f.height, &best);
  char text[700];
  if (!camera) {
    std::size_t valid = 0;
    for (const Eigen::Vector3f& p : f.points) valid += p.allFinite();
    if (valid < 100) return;  // too few points to tell
    char fit[160] = "none";
    if (best) {
      std::snprintf(fit, sizeof fit, "%.0f %% of the points on their rays, RMS %.3f px", 100.0 * best->inlier_share,
                    best->rms_px);
    }
    std::snprintf(text, sizeof text,
                  "%s: an organized cloud whose points do not lie on their pixels' rays for any pinhole camera "
                  "(best fit: %s; %.0f %% are needed): its frame cannot be recovered, so it is scored as it is, with "
                  "the image's up axis taken as up (`gravity` in the cloud's frame says otherwise)",
                  path.c_str(), fit, 100.0 * kMinCameraInlierShare);
    f.note = text;
    return;
  }
  const StrayPoints stray = toCameraImage(f.points, f.width, *camera);
  std::string note;
  if (camera->T_cloud_camera) {
    const Eigen::Isometry3d& T = *camera->T_cloud_camera;
    f.T_cloud_camera = T;
    std::snprintf(text, sizeof text,
                  "%s: its points are not in its camera's frame; the camera, fitted from the pixel grid (fx %.1f fy %.1f "
                  "cx %.1f cy %.1f, RMS %.3f px, %.1f %% of the points on their rays), is turned %.1f degrees and moved "
                  "%.3f m from the cloud's frame: scored in the camera's frame, reported in the cloud's",
                  path.c_str(), camera->intrinsics.fx, camera->intrinsics.fy, camera->intrinsics.cx, camera->intrinsics.cy,
                  camera->rms_px, 100.0 * camera->inlier_share, Eigen::AngleAxisd(T.linear()).angle() * 180.0 / M_PI,
                  T.translation().norm());
    note = text;
  }
  if (stray.placeholders > 0 || stray.off_ray > 0) {
    std::snprintf(text, sizeof text,
                  "%s%s: %zu pixels hold a placeholder, not a measurement (the origin or a point repeated at other "
                  "pixels), and %zu of its %zu measured points lie off their pixels' rays: both left out",
                  note.empty() ? "" : "; ", note.empty() ? path.c_str() : "also", stray.placeholders, stray.off_ray,
                  stray.measured);
    note += text;
  }
  f.note = note;
}

}  // namespace mobmap::sources
