#pragma once
/// @file pipeline.hpp
/// The per-frame pipeline of Genesio et al.: reduction, denoising, normals, RGB-N
/// colours, ground removal, colour region growing, per-segment slope, roughness and
/// mobility. One frame, camera frame (OpenCV axes), metres; no poses.

#include "mobmap/gp/mobility_model.hpp"
#include "mobmap/perception/camera.hpp"
#include "mobmap/perception/frame_result.hpp"
#include "mobmap/perception/ground.hpp"  // imageUpTiltDeg, for the ground the pipeline chose
#include "mobmap/perception/params.hpp"
#include "mobmap/perception/triangulator.hpp"

#include <Eigen/Core>

#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace mobmap::perception {


/// Runs the pipeline. Immutable after construction: process() may run on several
/// threads at once (each call uses its own buffers). Each thread that calls it keeps
/// its two neighbour graphs from call to call (~40 MB for a VGA frame at 1 cm, freed
/// when the thread ends), so later frames neither allocate nor clear them.
class FramePipeline {
 public:
  explicit FramePipeline(PerceptionParams params = {}, gp::MobilityModel model = gp::MobilityModel());

  /// A depth image (metres, 0 = invalid) with its intrinsics; gravity (pointing down)
  /// in the camera frame if known. Throws std::invalid_argument if the image and
  /// intrinsics sizes differ or gravity is zero/non-finite. An empty or all-invalid
  /// frame gives a result with no segments, not an error.
  [[nodiscard]] FrameResult process(const DepthImage& depth, const PinholeIntrinsics& intrinsics,
                                    const std::optional<Eigen::Vector3f>& gravity_down_camera = std::nullopt) const;

  /// process() once per ground cone: result i is what process() gives for a pipeline
  /// whose params are this one's with ground_max_tilt_deg = ground_cones_deg[i], at the
  /// cost of one reduction, denoising and normals (the stages before the ground, which
  /// do not depend on the cone) and the later stages once per cone. For a check of
  /// gravity against the floor in a narrow cone that also perceives the frame as the run
  /// will. std::invalid_argument as process(), or for a cone outside [0, 90] or none.
  [[nodiscard]] std::vector<FrameResult> processPerGroundCone(const DepthImage& depth, const PinholeIntrinsics& intrinsics,
                                                              const std::optional<Eigen::Vector3f>& gravity_down_camera,
                                                              const std::vector<double>& ground_cones_deg) const;

  /// An organized cloud (row-major, width x height, non-finite = invalid pixel), such
  /// as a Kinect PCD; FrameResult::point_of_pixel is filled.
  [[nodiscard]] FrameResult processOrganized(const std::vector<Eigen::Vector3f>& points, int width, int height,
                                             const std::optional<Eigen::Vector3f>& gravity_down_camera = std::nullopt) const;

  /// An unorganized cloud (non-finite points are skipped).
  [[nodiscard]] FrameResult process(const std::vector<Eigen::Vector3f>& points,
                                    const std::optional<Eigen::Vector3f>& gravity_down_camera = std::nullopt) const;

  [[nodiscard]] const PerceptionParams& params() const { return params_; }
  [[nodiscard]] const gp::MobilityModel& model() const { return model_; }

 private:
  // raw: the frame's finite points within the range limits (pixel_of_raw: their pixels,
  // empty for an unorganized cloud, in an image of `pixels`); `valid`: its finite
  // points before the crop; `started`: when making them began (the reduction's clock).
  // `cones`: the ground cones to finish the frame for (processPerGroundCone); empty:
  // this pipeline's own, one result.
  std::vector<FrameResult> run(std::vector<Eigen::Vector3f> raw, std::vector<int> pixel_of_raw, std::size_t pixels,
                               std::size_t valid, std::chrono::steady_clock::time_point started,
                               const std::optional<Eigen::Vector3f>& gravity_down_camera,
                               const std::vector<double>& cones = {}) const;
  PerceptionParams params_;
  gp::MobilityModel model_;
};

}  // namespace mobmap::perception
