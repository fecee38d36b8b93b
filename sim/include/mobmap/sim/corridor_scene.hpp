#pragma once
/// @file corridor_scene.hpp
/// A synthetic corridor seen by a walking, head-mounted depth camera, with exact
/// ground truth. World frame: z up (gravity (0,0,-1)), corridor along +x, metres.
/// Camera frame: OpenCV axes (x right, y down, z forward).

#include "mobmap/perception/camera.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace mobmap::sim {

/// What a ground-truth surface is.
enum class SurfaceKind { kFloor, kWall, kRamp, kRampSide, kRough, kBoxTop, kBoxSide, kStairTread, kStairRiser, kStairSide };

/// Name used in ground_truth.json ("floor", "wall", "ramp", ...).
const char* toString(SurfaceKind kind);

/// A triangle of the scene, counter-clockwise seen from the side its normal faces.
struct Triangle {
  Eigen::Vector3d a, b, c;
  int surface_id = 0;
};

/// A pyramid field z = h(x, y) >= 0 over [x0, x0 + nx*pitch] x [y0, y0 + ny*pitch]:
/// one square pyramid of height `height_m` per cell. Every facet has the same
/// gradient magnitude g = 2 height / pitch, so its true/projected area ratio is
/// exactly sqrt(1 + g^2); the field meets the floor (z = 0) along every cell edge.
struct PyramidField {
  double x0 = 0, y0 = 0;
  int nx = 0, ny = 0;
  double pitch_m = 0.1;
  double height_m = 0.0;
  [[nodiscard]] double heightAt(double x, double y) const;  ///< h(x,y), 0 outside
  [[nodiscard]] double exactAreaRatio() const;              ///< sqrt(1 + (2 h / pitch)^2)
  /// Its triangles (four per pyramid), labelled `surface_id`.
  [[nodiscard]] std::vector<Triangle> triangles(int surface_id) const;
};

/// One ground-truth surface: a planar face (one or more convex polygons in one plane)
/// or the rough pyramid field.
struct Surface {
  int id = 0;  ///< >= 1; 0 in label images means "nothing hit"
  std::string name;
  SurfaceKind kind = SurfaceKind::kFloor;
  std::vector<std::vector<Eigen::Vector3d>> polygons;  ///< world frame at frame 0
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();    ///< outward unit normal (planar faces; mean-plane normal of the rough patch)
  double slope_deg = 0.0;          ///< angle between the surface normal and gravity "up"
  double roughness = 1.0;          ///< true area / projected area
  double expected_mobility = 0.0;  ///< paper's rule table at (slope, roughness)
  bool moving = false;             ///< part of the moving obstacle
  /// A rough field's shape in words, with its parameters (ground_truth.json); empty otherwise.
  std::string description;
  double top_m = 0;  ///< a rough field's highest point above its footprint

};

/// The moving obstacle: a box translated linearly from `from` to `to` (its footprint
/// centre on the floor, world frame) between start_frame and end_frame.
struct MovingObstacle {
  Eigen::Vector3d size = Eigen::Vector3d(0.4, 0.4, 0.6);
  Eigen::Vector3d from = Eigen::Vector3d::Zero();
  Eigen::Vector3d to = Eigen::Vector3d::Zero();
  int start_frame = 0;
  int end_frame = 0;
  [[nodiscard]] Eigen::Vector3d centreAt(int frame) const;
};

/// Sensor noise model.
enum class NoiseModel { kNone, kKinect };

/// Kinect v1 noise parameters (Khoshelham & Elberink 2012; Nguyen et al. 2012).
struct KinectNoiseParams {
  double axial_sigma_at_1m_m = 1.5e-3;  ///< sigma(z) = this * z^2
  double baseline_m = 0.075;            ///< projector-camera baseline, for disparity quantisation
  double disparity_subpixel = 1.0 / 8;  ///< disparity step in pixels
  double dropout_start_deg = 70.0;      ///< incidence angle where returns start to go missing
  double dropout_full_deg = 85.0;       ///< incidence angle beyond which none return
  double max_depth_m = 10.0;            ///< farther returns are missing
  /// Depth edges as a structured-light sensor draws them. The disparity is found by
  /// correlating a window of the speckle pattern, so it is the mean over that window:
  /// exact on a plane (its disparity is affine in the pixel), rounded over a crease and
  /// smeared into a skirt of points between foreground and background at a
  /// discontinuity. Window edge in pixels (odd; Kinect v1 correlates about 9x9); 0
  /// turns the edge model (this and the mixed pixels below) off.
  int edge_window_px = 9;
  /// Mixed ("flying") pixels: on a depth discontinuity (neighbours' disparities differ by
  /// more than edge_jump_px) a pixel takes, with this probability, a random mix of the
  /// nearest and farthest disparity among its 3x3 neighbours.
  double flying_pixel_probability = 0.5;
  double edge_jump_px = 1.0;            ///< disparity jump (pixels) that makes a discontinuity
  /// The projector's shadow: the projector sits baseline_m to the camera's right (+x), so
  /// surfaces just left of a foreground edge that it cannot light return nothing.
  bool projector_shadow = true;
};

/// What the walk passes.
enum class Layout {
  /// Floor, walls, five ramps, a pyramid field, a box, stairs and a moving box.
  kCorridor,
  /// The same floor and walls with rough fields beside the path instead: square pyramids,
  /// triangular ridges along and across the path, square blocks and random stones, each
  /// with its exact area ratio (RoughYardParams).
  kRoughYard,
};

/// The rough fields of Layout::kRoughYard. Every field tiles its footprint exactly, so its
/// area ratio (true area over footprint) is exact: ridges sqrt(1 + (2 h / pitch)^2),
/// blocks 1 + 4 side h / pitch^2, stones the sum over their cells.
struct RoughYardParams {
  double ridge_pitch_m = 0.12, ridge_height_m = 0.06;  ///< area ratio sqrt(2): the rule gives 0.5
  double block_pitch_m = 0.15, block_side_m = 0.08, block_height_m = 0.06;  ///< area ratio 1.853
  /// One stone (a box) per pitch cell, its sides and height drawn uniformly from these
  /// ranges and its place in the cell at random (never touching the next cell's).
  double stone_pitch_m = 0.15, stone_min_side_m = 0.04, stone_max_side_m = 0.11;
  double stone_min_height_m = 0.02, stone_max_height_m = 0.08;
  std::uint64_t stone_seed = 3;  ///< the stones' geometry (not the noise)
};

/// Parameters of the corridor walk.
struct CorridorParams {
  int frames = 240;
  double frame_rate_hz = 30.0;
  double speed_mps = 0.75;        ///< walking pace along +x
  double camera_height_m = 1.35;  ///< mean height of the optical centre
  double pitch_down_deg = 35.0;   ///< mean pitch below the horizon
  double bob_m = 0.02;            ///< vertical head bob amplitude
  double step_frequency_hz = 1.8;
  double sway_deg = 2.0;          ///< yaw sway amplitude
  std::uint64_t seed = 1;         ///< noise seed (geometry and poses do not depend on it)
  NoiseModel noise = NoiseModel::kNone;
  KinectNoiseParams kinect;
  perception::PinholeIntrinsics intrinsics;  ///< default: Kinect v1 as in 7-Scenes
  Layout layout = Layout::kCorridor;
  RoughYardParams yard;  ///< for Layout::kRoughYard
};

/// Throws std::invalid_argument naming the field when a parameter is unusable.
void validate(const CorridorParams& params);

/// One rendered frame.
struct RenderedFrame {
  perception::DepthImage depth;        ///< metres along z, 0 = no return (noise applied if enabled)
  perception::DepthImage exact_depth;  ///< noise-free depth of the same rays
  std::vector<std::uint16_t> labels;   ///< surface id per pixel (0 = nothing), row-major
  std::vector<std::array<std::uint8_t, 3>> colour;  ///< shaded RGB per pixel
  Eigen::Isometry3d T_world_camera;
};

/// The corridor: floor, two side walls and an end wall; five ramps of 5, 15, 25,
/// 35 and 45 degrees; a rough pyramid field (area ratio 1.5); a static box; a
/// four-step staircase (17 cm risers, 30 cm treads); a box that slides out of the
/// walking path during the sequence. Immutable after construction; render() is
/// const and may run for different frames on several threads.
class CorridorScene {
 public:
  explicit CorridorScene(CorridorParams params = {});

  [[nodiscard]] const CorridorParams& params() const { return params_; }
  [[nodiscard]] const std::vector<Surface>& surfaces() const { return surfaces_; }
  [[nodiscard]] const Surface& surface(int id) const;
  [[nodiscard]] const PyramidField& roughPatch() const { return rough_; }
  [[nodiscard]] const MovingObstacle& movingObstacle() const { return moving_; }
  /// Unit gravity vector (pointing down) in the world frame.
  [[nodiscard]] Eigen::Vector3d gravityDown() const { return {0, 0, -1}; }

  /// Camera-to-world pose of a frame (0-based).
  [[nodiscard]] Eigen::Isometry3d cameraPose(int frame) const;
  /// The continuous camera path at `t_seconds` after frame 0 (any t, for
  /// ground-truth trajectories sampled at other rates than the frames).
  [[nodiscard]] Eigen::Isometry3d cameraPoseAt(double t_seconds) const;
  /// All triangles with the moving obstacle where it is at `frame`.
  [[nodiscard]] std::vector<Triangle> trianglesAt(int frame) const;
  /// Renders frame `frame`: exact ray casting, then the noise model.
  [[nodiscard]] RenderedFrame render(int frame) const;

 private:
  int addSurface(Surface s);
  void buildRoughYard(double x_begin, double x_end, double half_width);
  CorridorParams params_;
  std::vector<Surface> surfaces_;
  std::vector<Triangle> static_triangles_;
  std::vector<Triangle> moving_triangles_;  ///< at the obstacle's `from` position
  PyramidField rough_;
  MovingObstacle moving_;
};

/// Exact z-buffer ray casting of triangles: depth along z and the id of the first
/// surface hit for every pixel (u, v) on the ray pixelRay(k, u, v).
struct RayCastResult {
  perception::DepthImage depth;
  std::vector<std::uint16_t> labels;
  std::vector<float> incidence_cos;  ///< |cos| between the ray and the surface normal
};
RayCastResult castRays(const std::vector<Triangle>& triangles,
                       const perception::PinholeIntrinsics& k,
                       const Eigen::Isometry3d& T_world_camera);

/// Applies the Kinect v1 model to `depth` in place: the projector's shadow, edges smoothed
/// over the correlation window and mixed pixels (KinectNoiseParams), then dropout at
/// grazing incidence, Gaussian axial noise and disparity quantisation. Deterministic for
/// (seed, frame).
void applyKinectNoise(perception::DepthImage& depth, const std::vector<float>& incidence_cos,
                      const KinectNoiseParams& params, double fx, std::uint64_t seed, int frame);

/// Area ratio of a height field by brute force: the true area of a regular
/// triangulation with `n` x `n` cells over [x0,x1] x [y0,y1] divided by its
/// projected area. An independent check of PyramidField::exactAreaRatio().
double bruteForceAreaRatio(const PyramidField& field, int n);

}  // namespace mobmap::sim
