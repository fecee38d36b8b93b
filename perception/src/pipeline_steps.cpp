// FramePipeline's steps 3, 5, 6 and 7 (pipeline_steps.hpp).

#include "pipeline_steps.hpp"

#include "mobmap/perception/stages.hpp"

#include <algorithm>
#include <cmath>

namespace mobmap::perception::steps {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;
// Passes of ground absorption into rough regions: each fills a valley of the floor's
// RANSAC band about one point deeper from both sides; 6 fill the ~4 cm bands the
// corridor's pyramid field leaves (3 left 363 of its 6,015 points at frame 0 in the
// ground). A straight boundary with the floor does not move: the floor points along
// it have fewer than half their neighbours in the rough region.
constexpr int kAbsorbPasses = 6;
// A plane found within this many degrees of the upright prior's cone edge is taken for
// a leaning surface fitted at the edge (see ground_upright_prior_deg), not a floor.
constexpr double kUprightEdgeDeg = 5.0;

}  // namespace

std::vector<Eigen::Vector3f> estimateNormalsAndSmooth(FrameResult& out, const KnnGraph& graph,
                                                      const PerceptionParams& p) {
  const std::size_t n = out.points.size();
  std::vector<Eigen::Vector3f> smoothed;
  // The first pass starts its eigenvectors from the direction to the camera (only
  // surfaces seen edge-on are near orthogonal to it; points whose iteration does not
  // converge go to the closed-form solver): that pass 10.3 -> 5.3 ms per real frame.
  std::vector<Eigen::Vector3f> towards_camera(n);
  for (std::size_t i = 0; i < n; ++i) towards_camera[i] = -out.points[i].normalized();
  estimateNormals(out.points, graph, Eigen::Vector3f::Zero(), out.normals, out.curvature,
                  p.roughness_smoothing ? &smoothed : nullptr, &towards_camera);
  // Each later pass starts from the previous pass's normals (the planes move little
  // between passes).
  std::vector<Eigen::Vector3f> previous_normals = out.normals;
  for (int pass = 1; p.roughness_smoothing && pass < p.roughness_smoothing_passes; ++pass) {
    std::vector<Eigen::Vector3f> n_tmp, next;
    std::vector<float> c_tmp;
    estimateNormals(smoothed, graph, Eigen::Vector3f::Zero(), n_tmp, c_tmp, &next, &previous_normals);
    smoothed.swap(next);
    previous_normals.swap(n_tmp);
  }
  return smoothed;
}

std::vector<int> findGround(FrameResult& out, const std::optional<Eigen::Vector3f>& up, const PerceptionParams& p,
                            std::mt19937& rng) {
  const std::size_t n = out.points.size();
  std::vector<int> all(n);
  for (std::size_t i = 0; i < n; ++i) all[i] = static_cast<int>(i);
  std::vector<int> ground_points;
  {
    RansacOptions o;
    o.distance_m = p.ground_distance_m;
    o.probability = p.ground_probability;
    o.max_iterations = p.ground_max_iterations;
    o.required_normal = up;
    o.max_tilt_deg = p.ground_max_tilt_deg;
    o.origin_on_normal_side = true;  // a floor below the camera, not a ceiling above it
    o.point_normals = &out.normals;
    o.normal_tolerance_deg = p.ground_normal_tolerance_deg;
    // With a required direction, only points whose own normal is within the tilt plus
    // the inlier normal tolerance of it can be inliers of a qualifying plane: sampling
    // among them alone finds the same planes, where a floor that is a few percent of
    // the view (walls and people fill the rest) would otherwise rarely be drawn.
    const auto facing = [&](const Eigen::Vector3f& dir, double max_tilt_deg) {
      const double reach = std::min(90.0, max_tilt_deg + p.ground_normal_tolerance_deg);
      const float cos_reach = static_cast<float>(std::cos(reach / kRadToDeg));
      std::vector<int> c;
      for (std::size_t i = 0; i < n; ++i) {
        if (std::abs(out.normals[i].dot(dir)) >= cos_reach - 1e-6f) c.push_back(static_cast<int>(i));
      }
      return c;
    };
    auto fit = ransacPlane(out.points, up ? facing(*up, p.ground_max_tilt_deg) : all, o, rng);
    const auto large_enough = [&](const std::optional<PlaneFit>& f) {
      return f && static_cast<int>(f->inliers.size()) >= p.ground_min_points;
    };
    out.ground_rule = up ? GroundRule::kGravity : GroundRule::kLargestPlane;
    if (!up && p.ground_upright_prior_deg > 0 && (!large_enough(fit) || imageUpTiltDeg(fit->plane) > p.ground_upright_prior_deg)) {
      // The largest plane leans away from the image's up axis (a wall, when the camera
      // is held upright). Look for a floor within the prior's cone; one fitted at the
      // cone's edge is the same leaning surface, not a floor.
      RansacOptions upright = o;
      upright.required_normal = Eigen::Vector3f(0, -1, 0);
      upright.max_tilt_deg = p.ground_upright_prior_deg;
      auto floor = ransacPlane(out.points, facing(*upright.required_normal, upright.max_tilt_deg), upright, rng);
      if (large_enough(floor) && imageUpTiltDeg(floor->plane) <= p.ground_upright_prior_deg - kUprightEdgeDeg) {
        fit = std::move(floor);
        out.ground_rule = GroundRule::kUprightPrior;
      }
    }
    if (large_enough(fit)) {
      Eigen::Vector4f plane = fit->plane;
      if (plane(3) < 0) plane = -plane;  // normal towards the camera at the origin
      out.ground_plane = plane;
      ground_points = std::move(fit->inliers);
    } else {
      out.ground_rule = GroundRule::kNone;
    }
  }
  return ground_points;
}

std::size_t segment(FrameResult& out, const KnnGraph& graph, std::vector<int> ground_points,
                    const std::optional<Eigen::Vector3f>& up, const PerceptionParams& p) {
  const std::size_t n = out.points.size();
  out.segment_of_point.assign(n, -1);
  std::vector<bool> eligible(n, true);
  for (int i : ground_points) eligible[static_cast<std::size_t>(i)] = false;
  int regions = 0;
  std::vector<bool> region_rough;
  std::optional<Eigen::Vector3f> level = up;
  if (!level && out.ground_plane) level = out.ground_plane->head<3>();
  // With rough joining on, every region is kept (min size 1) so that the small ones
  // can be judged as fragments; mergeFragments applies the size limit afterwards.
  const bool join_rough = p.rough_fragment_max_points > 0;
  std::vector<int> labels =
      growRegions(out.points, out.colours, graph, eligible, p.colour_threshold, p.neighbour_distance_m,
                  join_rough ? 1 : p.min_segment_points, &regions, &out.normals, p.region_max_normal_deviation_deg);
  std::vector<bool> is_ground(n);
  for (std::size_t i = 0; i < n; ++i) is_ground[i] = !eligible[i];
  if (join_rough) {
    labels = mergeFragments(out.points, out.normals, graph, p.neighbour_distance_m, labels, p.min_segment_points,
                            p.rough_fragment_max_points, p.rough_fragment_max_width_m, p.rough_min_fragments, p.rough_min_points,
                            p.rough_min_width_m, p.rough_min_normal_spread_deg, level, p.rough_max_slope_deg, &regions,
                            &region_rough, &is_ground);
  }
  // Rough segments absorb the ground points among them, then tilted regions take back
  // the ground points that continue them; both edit one ground mask (the ground is
  // exactly the points region growing was not allowed to take).
  std::size_t moved = 0;
  if (!ground_points.empty() && std::find(region_rough.begin(), region_rough.end(), true) != region_rough.end()) {
    moved += absorbGroundIntoRough(graph, p.neighbour_distance_m, region_rough, 0.5, kAbsorbPasses, labels, is_ground);
    joinTouchingRoughRegions(graph, p.neighbour_distance_m, region_rough, labels, &regions);
  }
  // Least-squares plane of every region, for the two plane-based steps below.
  std::vector<Eigen::Vector4f> planes;
  if (regions > 0 && ((out.ground_plane && p.ground_reclaim_min_angle_deg > 0) || p.adopt_max_angle_deg > 0)) {
    std::vector<std::vector<int>> region_points(static_cast<std::size_t>(regions));
    for (std::size_t i = 0; i < n; ++i) {
      if (labels[i] >= 0) region_points[static_cast<std::size_t>(labels[i])].push_back(static_cast<int>(i));
    }
    planes.resize(region_points.size());
    for (std::size_t r = 0; r < planes.size(); ++r) planes[r] = leastSquaresPlane(out.points, region_points[r]);
  }
  if (out.ground_plane && !planes.empty() && p.ground_reclaim_min_angle_deg > 0) {
    moved += reclaimGroundPoints(out.points, graph, p.neighbour_distance_m, *out.ground_plane, planes,
                                 p.ground_reclaim_min_angle_deg, p.ground_reclaim_max_angle_deg, p.ground_distance_m,
                                 labels, is_ground, &out.normals, &region_rough);
  }
  // Points that colour growing left out next to a region whose plane they lie on
  // join it (not rough regions: their plane is only a mean).
  if (!planes.empty() && p.adopt_max_angle_deg > 0) {
    adoptUnsegmentedPoints(out.points, out.normals, graph, p.neighbour_distance_m, planes, region_rough,
                           p.adopt_max_distance_m, p.adopt_max_angle_deg, labels, is_ground);
  }
  if (moved > 0) {
    ground_points.clear();
    for (std::size_t i = 0; i < n; ++i) {
      if (is_ground[i]) ground_points.push_back(static_cast<int>(i));
    }
  }
  std::vector<std::vector<int>> members(static_cast<std::size_t>(regions));
  for (std::size_t i = 0; i < n; ++i) {
    if (labels[i] >= 0) members[static_cast<std::size_t>(labels[i])].push_back(static_cast<int>(i));
  }
  if (!ground_points.empty()) {
    Segment g;
    g.is_ground = true;
    g.points = std::move(ground_points);
    out.segments.push_back(std::move(g));
  }
  for (std::size_t r = 0; r < members.size(); ++r) {
    Segment s;
    s.points = std::move(members[r]);
    s.is_rough = r < region_rough.size() && region_rough[r];
    out.segments.push_back(std::move(s));
  }
  std::size_t segmented = 0;
  for (std::size_t s = 0; s < out.segments.size(); ++s) {
    out.segments[s].id = static_cast<int>(s);
    for (int i : out.segments[s].points) out.segment_of_point[static_cast<std::size_t>(i)] = static_cast<int>(s);
    segmented += out.segments[s].points.size();
  }
  return segmented;
}

Eigen::MatrixX2d measureSurfaces(FrameResult& out, const KnnGraph& graph, const std::vector<Eigen::Vector3f>& smoothed,
                                 const std::optional<Eigen::Vector3f>& up, const PerceptionParams& p) {
  Eigen::Vector3f reference(0, -1, 0);  // camera "up" (OpenCV y points down)
  out.reference = SlopeReference::kCamera;
  if (up) {
    reference = *up;
    out.reference = SlopeReference::kGravity;
  } else if (out.ground_plane) {
    reference = out.ground_plane->head<3>();
    out.reference = SlopeReference::kGround;
  }
  // Rough segments (joined fragments) are not measured after the widening passes:
  // their roughness is creases at the fragments' scale, which those round off. Their
  // points are projected once, onto the plane of their rough_smoothing_k nearest
  // neighbours (at most normal_k, where this is the first normals pass's projection;
  // docs/PERCEPTION.md, "Rough surfaces" and "Coarser voxels").
  std::vector<Eigen::Vector3f> rough_measured;
  if (p.roughness_smoothing) {
    std::vector<int> rough_points;
    for (const Segment& seg : out.segments) {
      if (seg.is_rough) rough_points.insert(rough_points.end(), seg.points.begin(), seg.points.end());
    }
    if (!rough_points.empty()) {
      rough_measured = out.points;
      projectOntoLocalPlanes(out.points, graph, p.rough_smoothing_k, rough_points, rough_measured);
    }
  }
  Eigen::MatrixX2d features(static_cast<Eigen::Index>(out.segments.size()), 2);
  for (std::size_t s = 0; s < out.segments.size(); ++s) {
    Segment& seg = out.segments[s];
    double rms = 0.0;
    Eigen::Vector4f plane = leastSquaresPlane(out.points, seg.points, &rms);
    // RANSAC refinement rejects stragglers; its threshold is never below the
    // surface's own spread, so a rough surface keeps its mean plane.
    RansacOptions o;
    o.distance_m = std::max(p.plane_ransac_distance_m, 2.5 * rms);
    o.probability = p.ground_probability;
    o.max_iterations = 200;
    // Each segment draws from its own stream, seeded by its first point, so its
    // plane does not depend on how many segments came before it.
    std::seed_seq seq{p.random_seed, static_cast<std::uint32_t>(seg.points.front())};
    std::mt19937 seg_rng(seq);
    if (auto fit = ransacPlane(out.points, seg.points, o, seg_rng); fit && fit->inliers.size() * 2 >= seg.points.size()) {
      plane = fit->plane;
    }
    Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
    for (int i : seg.points) centroid += out.points[static_cast<std::size_t>(i)];
    centroid /= static_cast<float>(seg.points.size());
    Eigen::Vector3f normal = plane.head<3>().normalized();
    if (normal.dot(-centroid) < 0) normal = -normal;  // towards the camera
    plane = Eigen::Vector4f(normal.x(), normal.y(), normal.z(), -normal.dot(centroid));
    seg.centroid = centroid;
    seg.normal = normal;
    seg.slope_deg = std::acos(std::clamp(static_cast<double>(normal.dot(reference)), -1.0, 1.0)) * kRadToDeg;
    const std::vector<Eigen::Vector3f>& measured =
        !p.roughness_smoothing ? out.points : seg.is_rough ? rough_measured : smoothed;
    const auto [r, area] = delaunayRoughness(measured, seg.points, plane,
                                             p.max_triangle_edge_m, p.triangulator);
    seg.roughness = r;
    seg.area_m2 = area;
    features(static_cast<Eigen::Index>(s), 0) = seg.slope_deg;
    features(static_cast<Eigen::Index>(s), 1) = seg.roughness;
  }
  if (p.foot_window_m > 0 && !out.segments.empty()) return scoreAtFootScale(out, features, reference, p);
  return features;
}

}  // namespace mobmap::perception::steps
