#include "mobmap/perception/pipeline.hpp"

#include "mobmap/perception/stages.hpp"
#include "pipeline_steps.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace mobmap::perception {
namespace {


class StageClock {
 public:
  explicit StageClock(std::vector<StageTiming>& out) : out_(out) {}
  void start() { t0_ = std::chrono::steady_clock::now(); }
  void startAt(std::chrono::steady_clock::time_point t) { t0_ = t; }
  void stop(const char* name, std::size_t in, std::size_t out) {
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0_).count();
    out_.push_back({name, ms, in, out});
  }

 private:
  std::vector<StageTiming>& out_;
  std::chrono::steady_clock::time_point t0_;
};

// Extra neighbours per row of the shared graph beyond normal_k, so that a row that lost
// a neighbour or two to the outlier removal still holds normal_k kept ones and need not
// be searched again (see restrictKnnGraph).
constexpr int kRestrictMargin = 2;

// Grid cell for the kNN search: large enough that the k-th neighbour on a surface
// sampled every voxel_m usually lies inside the guaranteed radius (sqrt(k / pi)
// spacings on a plane), so the exact search rarely widens.
float knnCell(double voxel_m, int k) {
  return static_cast<float>(voxel_m * (std::sqrt(k / M_PI) + 0.6));
}

// Stages 5-8 of a frame perceived through stage 4 (its points, normals, colours), for
// the params `p` (whose ground cone may differ from the pipeline's).
void finishFrame(FrameResult& out, const KnnGraph& graph, const std::vector<Eigen::Vector3f>& smoothed,
                 const std::optional<Eigen::Vector3f>& up, const PerceptionParams& p, const gp::MobilityModel& model) {
  StageClock clock(out.stages);
  std::mt19937 rng(p.random_seed);
  const std::size_t n = out.points.size();
  // 5. Ground removal.
  clock.start();
  std::vector<int> ground_points = steps::findGround(out, up, p, rng);
  clock.stop("ground", n, n - ground_points.size());

  // 6. Colour region growing on what is not ground, and the departures from the paper.
  clock.start();
  const std::size_t segmented = steps::segment(out, graph, std::move(ground_points), up, p);
  clock.stop("segmentation", n, segmented);

  // 7. Surface properties: slope and roughness.
  clock.start();
  const Eigen::MatrixX2d features = steps::measureSurfaces(out, graph, smoothed, up, p);
  clock.stop("surface properties", n, out.segments.size());

  // 8. Mobility: the model scores (slope, roughness).
  clock.start();
  if (!out.segments.empty()) {
    const auto scores = model.predict(features);
    for (std::size_t s = 0; s < out.segments.size(); ++s) {
      out.segments[s].mobility = scores[s].mobility;
      out.segments[s].variance = scores[s].variance;
    }
  }
  clock.stop("mobility", out.segments.size(), out.segments.size());
}

}  // namespace


const char* toString(GroundRule r) {
  switch (r) {
    case GroundRule::kNone: return "none";
    case GroundRule::kGravity: return "gravity";
    case GroundRule::kLargestPlane: return "largest plane";
    case GroundRule::kUprightPrior: return "upright prior";
  }
  return "unknown";
}

const char* toString(SlopeReference r) {
  switch (r) {
    case SlopeReference::kGravity: return "gravity";
    case SlopeReference::kGround: return "ground";
    case SlopeReference::kCamera: return "camera";
  }
  return "unknown";
}

double FrameResult::totalMilliseconds() const {
  double t = 0;
  for (const auto& s : stages) t += s.milliseconds;
  return t;
}

namespace {

// The range crop: a point is kept when its squared distance from the camera is within
// [lo2, hi2] = [min_range_m^2, max_range_m^2] (as floats).
struct RangeGate {
  explicit RangeGate(const PerceptionParams& p)
      : lo2(static_cast<float>(p.min_range_m * p.min_range_m)), hi2(static_cast<float>(p.max_range_m * p.max_range_m)) {}
  float lo2, hi2;
};

// A sample of a frame's valid points (about one in 16), for the RangeReport: their
// ranges, and the points, whose heights are measured once the frame's "down" is known.
struct RangeSample {
  void add(const Eigen::Vector3f& q) {
    range.push_back(q.norm());
    point.push_back(q);
  }
  std::vector<float> range;
  std::vector<Eigen::Vector3f> point;
};

// The q-quantile of `v` (reordered); 0 for an empty one.
double quantile(std::vector<float>& v, double q) {
  if (v.empty()) return 0.0;
  const auto k = static_cast<std::ptrdiff_t>(std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size()))));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[static_cast<std::size_t>(k)];
}

// The range summary of a processed frame. Heights are measured along gravity when the
// frame had it, else along the ground plane found (a pitched camera's +y axis tilts the
// far floor below the near one), else along the camera's +y.
RangeReport summarizeRanges(RangeSample sample, const PerceptionParams& p, std::size_t valid, std::size_t beyond,
                            std::size_t nearer, const std::optional<Eigen::Vector3f>& gravity,
                            const std::optional<Eigen::Vector4f>& ground_plane) {
  RangeReport r;
  r.valid_points = valid;
  r.beyond_max_range = beyond;
  r.nearer_than_min_range = nearer;
  r.min_range_m = p.min_range_m;
  r.max_range_m = p.max_range_m;
  Eigen::Vector3f down(0.f, 1.f, 0.f);
  if (gravity && gravity->allFinite() && gravity->stableNorm() > 1e-6f) {
    down = gravity->normalized();
    r.down_from_gravity = true;
  } else if (ground_plane && ground_plane->head<3>().allFinite() && ground_plane->head<3>().stableNorm() > 1e-6f) {
    // Its normal points towards the camera; a ground more than 45 degrees from the
    // image's up axis may be a wall, and +y says more then.
    const Eigen::Vector3f ground_down = -ground_plane->head<3>().normalized();
    if (ground_down.y() > std::cos(static_cast<float>(M_PI) / 4.f)) {
      down = ground_down;
      r.down_from_ground = true;
    }
  }
  std::vector<float> height(sample.point.size());
  for (std::size_t i = 0; i < sample.point.size(); ++i) height[i] = sample.point[i].dot(down);
  std::vector<float> ranges = sample.range;
  r.median_range_m = quantile(ranges, 0.5);
  r.range_p95_m = quantile(ranges, 0.95);
  constexpr std::size_t kMinSample = 200;
  if (sample.range.size() < kMinSample) return r;
  // The lowest surface: a band of 8 cm either side of the 98th percentile of height
  // (the lowest 2 % may be noise under the floor).
  std::vector<float> heights = height;
  const double floor_h = quantile(heights, 0.98);
  std::vector<float> band_range, band_height;
  for (std::size_t i = 0; i < sample.range.size(); ++i) {
    if (std::abs(height[i] - floor_h) > 0.08) continue;
    band_range.push_back(sample.range[i]);
    band_height.push_back(height[i]);
  }
  if (band_range.size() < kMinSample / 4) return r;
  RangeReport::Lowest low;
  low.sampled = band_range.size();
  std::size_t far = 0;
  for (float x : band_range) far += x > p.max_range_m;
  low.share_beyond = static_cast<double>(far) / static_cast<double>(band_range.size());
  low.below_camera_m = quantile(band_height, 0.5);
  low.range_p95_m = quantile(band_range, 0.95);
  r.lowest = low;
  return r;
}

// What the range limits took from a frame: the counts, and a sample for the summary.
struct RangeTaken {
  RangeSample sample;
  std::size_t valid = 0, beyond = 0, nearer = 0;
};

// The finite points of `points` within the range limits, in order; `index` (if given)
// receives the position of each in `points`; `taken` what the limits took.
std::vector<Eigen::Vector3f> finiteInRange(const std::vector<Eigen::Vector3f>& points, const RangeGate& in_range,
                                           std::vector<int>* index, RangeTaken& taken) {
  // Sized for every point and cut to the kept ones after (not a push_back per point).
  std::vector<Eigen::Vector3f> raw(points.size());
  if (index) index->resize(points.size());
  RangeSample& sample = taken.sample;
  std::size_t n = 0, valid = 0, beyond = 0, nearer = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) continue;
    if (valid++ % 16 == 0) sample.add(points[i]);
    const float r2 = points[i].squaredNorm();
    if (r2 > in_range.hi2) {
      ++beyond;
      continue;
    }
    if (r2 < in_range.lo2) {
      ++nearer;
      continue;
    }
    raw[n] = points[i];
    if (index) (*index)[n] = static_cast<int>(i);
    ++n;
  }
  raw.resize(n);
  if (index) index->resize(n);
  taken.valid = valid, taken.beyond = beyond, taken.nearer = nearer;
  return raw;
}

}  // namespace

FramePipeline::FramePipeline(PerceptionParams params, gp::MobilityModel model)
    : params_(params), model_(std::move(model)) {
  validate(params_);
}

FrameResult FramePipeline::process(const DepthImage& depth, const PinholeIntrinsics& k,
                                   const std::optional<Eigen::Vector3f>& gravity) const {
  return std::move(processPerGroundCone(depth, k, gravity, {params_.ground_max_tilt_deg}).front());
}

std::vector<FrameResult> FramePipeline::processPerGroundCone(const DepthImage& depth, const PinholeIntrinsics& k,
                                                             const std::optional<Eigen::Vector3f>& gravity,
                                                             const std::vector<double>& cones) const {
  if (cones.empty()) throw std::invalid_argument("FramePipeline::processPerGroundCone: no ground cone");
  for (const double c : cones) {
    if (!(c >= 0 && c <= 90)) throw std::invalid_argument("FramePipeline::processPerGroundCone: a ground cone must be in [0, 90] degrees");
  }
  validate(k);
  if (depth.width != k.width || depth.height != k.height ||
      depth.depth_m.size() != static_cast<std::size_t>(k.width) * k.height) {
    std::ostringstream msg;
    msg << "FramePipeline::process: depth image is " << depth.width << "x" << depth.height
        << " but the intrinsics are for " << k.width << "x" << k.height;
    throw std::invalid_argument(msg.str());
  }
  // The frame's points within the range limits, back-projected and cropped in one pass
  // (and timed with the reduction). Sized for every pixel and cut to the kept ones
  // after: a push_back per pixel was an out-of-line call each (~0.7 % of a frame).
  const auto started = std::chrono::steady_clock::now();
  const RangeGate in_range(params_);
  std::vector<Eigen::Vector3f> raw(depth.depth_m.size());
  std::vector<int> pixel_of_raw(depth.depth_m.size());
  std::size_t n = 0, valid = 0, beyond = 0;
  const float inv_fx = static_cast<float>(1.0 / k.fx), inv_fy = static_cast<float>(1.0 / k.fy);
  RangeSample sample;
  for (int v = 0; v < k.height; ++v) {
    const float ry = (static_cast<float>(v) - static_cast<float>(k.cy)) * inv_fy;
    for (int u = 0; u < k.width; ++u) {
      const float z = depth.depth_m[static_cast<std::size_t>(v) * k.width + u];
      if (!(z > 0.f) || !std::isfinite(z)) continue;
      ++valid;
      const Eigen::Vector3f q((static_cast<float>(u) - static_cast<float>(k.cx)) * inv_fx * z, ry * z, z);
      const float r2 = q.squaredNorm();
      if (r2 < in_range.lo2 || r2 > in_range.hi2) {
        beyond += r2 > in_range.hi2;
        continue;
      }
      raw[n] = q;
      pixel_of_raw[n++] = v * k.width + u;
    }
  }
  raw.resize(n);
  pixel_of_raw.resize(n);
  // Every 4th pixel of every 4th row for the RangeReport.
  sample.range.reserve(static_cast<std::size_t>((k.width + 3) / 4) * static_cast<std::size_t>((k.height + 3) / 4));
  sample.point.reserve(sample.range.capacity());
  for (int v = 0; v < k.height; v += 4) {
    const float ry = (static_cast<float>(v) - static_cast<float>(k.cy)) * inv_fy;
    for (int u = 0; u < k.width; u += 4) {
      const float z = depth.depth_m[static_cast<std::size_t>(v) * k.width + u];
      if (!(z > 0.f) || !std::isfinite(z)) continue;
      sample.add(Eigen::Vector3f((static_cast<float>(u) - static_cast<float>(k.cx)) * inv_fx * z, ry * z, z));
    }
  }
  std::vector<FrameResult> outs = run(std::move(raw), std::move(pixel_of_raw), depth.depth_m.size(), valid, started, gravity, cones);
  for (std::size_t i = 0; i < outs.size(); ++i) {  // the last result takes the sample
    outs[i].range = summarizeRanges(i + 1 < outs.size() ? RangeSample(sample) : std::move(sample), params_, valid, beyond,
                                    valid - n - beyond, gravity, outs[i].ground_plane);
  }
  return outs;
}

FrameResult FramePipeline::processOrganized(const std::vector<Eigen::Vector3f>& points, int width, int height,
                                            const std::optional<Eigen::Vector3f>& gravity) const {
  if (width <= 0 || height <= 0 || points.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height)) {
    std::ostringstream msg;
    msg << "FramePipeline::processOrganized: " << points.size() << " points do not make a " << width << "x"
        << height << " organized cloud";
    throw std::invalid_argument(msg.str());
  }
  const auto started = std::chrono::steady_clock::now();
  std::vector<int> pixel_of_raw;
  RangeTaken taken;
  std::vector<Eigen::Vector3f> raw = finiteInRange(points, RangeGate(params_), &pixel_of_raw, taken);
  FrameResult out = std::move(run(std::move(raw), std::move(pixel_of_raw), points.size(), taken.valid, started, gravity).front());
  out.range = summarizeRanges(std::move(taken.sample), params_, taken.valid, taken.beyond, taken.nearer, gravity, out.ground_plane);
  return out;
}

FrameResult FramePipeline::process(const std::vector<Eigen::Vector3f>& points,
                                   const std::optional<Eigen::Vector3f>& gravity) const {
  const auto started = std::chrono::steady_clock::now();
  RangeTaken taken;
  std::vector<Eigen::Vector3f> raw = finiteInRange(points, RangeGate(params_), nullptr, taken);
  FrameResult out = std::move(run(std::move(raw), {}, 0, taken.valid, started, gravity).front());
  out.range = summarizeRanges(std::move(taken.sample), params_, taken.valid, taken.beyond, taken.nearer, gravity, out.ground_plane);
  return out;
}

std::vector<FrameResult> FramePipeline::run(std::vector<Eigen::Vector3f> raw, std::vector<int> pixel_of_raw, std::size_t pixels,
                                           std::size_t valid, std::chrono::steady_clock::time_point started,
                                           const std::optional<Eigen::Vector3f>& gravity, const std::vector<double>& cones) const {
  std::optional<Eigen::Vector3f> up;
  if (gravity) {
    const float norm = gravity->stableNorm();  // a plain norm overflows for components above ~1e19
    if (!gravity->allFinite() || norm < 1e-6f) {
      throw std::invalid_argument("FramePipeline::process: gravity vector must be finite and non-zero");
    }
    up = -*gravity / norm;
  }
  const PerceptionParams& p = params_;
  FrameResult out;
  StageClock clock(out.stages);

  // 1. Data reduction: range crop (done as the points were made), then 1 cm voxel
  // centroids.
  clock.startAt(started);
  std::vector<int> voxel_of_raw;
  std::vector<Eigen::Vector3f> voxels = voxelReduce(raw, static_cast<float>(p.voxel_size_m), &voxel_of_raw);
  clock.stop("reduction", valid, voxels.size());

  // 2. Statistical outlier removal. One neighbour search serves both this stage and
  // the normals: the graph holds max(outlier_k, normal_k + 2) neighbours per voxel, SOR
  // reads the first outlier_k, and the normals' graph over the kept points is derived
  // from it (exactly; only points that lost neighbours to the removal search again).
  clock.start();
  const int graph_k = std::max(p.outlier_k, p.normal_k + kRestrictMargin);
  const float cell = knnCell(p.voxel_size_m, std::max(p.outlier_k, p.normal_k));
  const float max_radius = static_cast<float>(20 * p.voxel_size_m);
  std::vector<int> kept_index(voxels.size(), -1);
  // The graph lives on from frame to frame in this thread (~15 MB for a VGA frame):
  // filling a fresh one cost ~1.2 ms per frame. The normals' graph replaces it in the
  // same buffer.
  thread_local KnnGraph graph_buffer;
  buildKnnGraph(voxels, graph_k, cell, max_radius, graph_buffer);
  const std::vector<bool> keep = statisticalOutlierMask(graph_buffer, p.outlier_alpha, p.outlier_k);
  for (std::size_t i = 0; i < voxels.size(); ++i) {
    if (!keep[i]) continue;
    kept_index[i] = static_cast<int>(out.points.size());
    out.points.push_back(voxels[i]);
  }
  clock.stop("denoising", voxels.size(), out.points.size());
  if (pixels > 0) {
    out.point_of_pixel.assign(pixels, -1);
    for (std::size_t i = 0; i < raw.size(); ++i) {
      out.point_of_pixel[static_cast<std::size_t>(pixel_of_raw[i])] = kept_index[static_cast<std::size_t>(voxel_of_raw[i])];
    }
  }
  const std::size_t n = out.points.size();

  // 3. Normals (and the smoothed points roughness is measured on).
  clock.start();
  restrictKnnGraphInPlace(graph_buffer, voxels, keep, p.normal_k, cell, max_radius);
  const KnnGraph& graph = graph_buffer;
  const std::vector<Eigen::Vector3f> smoothed = steps::estimateNormalsAndSmooth(out, graph, p);
  clock.stop("normals", n, n);

  // 4. RGB-N colours.
  clock.start();
  out.colours = normalColours(out.normals);
  clock.stop("rgb-n", n, n);

  // Stages 5-8 depend on the ground cone: once per cone asked for, each from a copy of
  // the frame as it stands (the last takes it), each with the random stream a pipeline
  // of that cone would use.
  const std::vector<double> own = {p.ground_max_tilt_deg};
  const std::vector<double>& for_cones = cones.empty() ? own : cones;
  std::vector<FrameResult> results;
  results.reserve(for_cones.size());
  for (std::size_t c = 0; c < for_cones.size(); ++c) {
    PerceptionParams pc = p;
    pc.ground_max_tilt_deg = for_cones[c];
    results.push_back(c + 1 < for_cones.size() ? out : std::move(out));
    finishFrame(results.back(), graph, smoothed, up, pc, model_);
  }
  return results;
}

}  // namespace mobmap::perception
