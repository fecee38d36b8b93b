#include "mobmap/builder/frames.hpp"

#include "mobmap/sources/dataset.hpp"
#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/text.hpp"
#include "mobmap/util/field_error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace mobmap::builder {

using sources::IoError;
using sources::openSequence;
using sources::SevenScenesDirectory;
using sources::splitNumbers;

Eigen::Vector3f parseVector3(const std::string& spec, const std::string& what) {
  const auto v = splitNumbers(spec);
  if (v.size() != 3) throw util::ValueError(what + " must be three numbers X,Y,Z, got '" + spec + "'");
  // Normalised in double (stableNorm does not overflow): 1e39 is finite as a double
  // but not as a float, and squaring 1e20 overflows a float.
  const Eigen::Vector3d d(v[0], v[1], v[2]);
  const double length = d.stableNorm();
  if (length < 1e-6) throw util::ValueError(what + " must not be the zero vector");
  return (d / length).cast<float>();
}

Frame loadSequenceFrame(const Sequence& seq, const std::string& input, int frame) {
  const auto& numbers = seq.frames();
  if (!seq.posed() && frame != numbers.front()) {
    throw IoError(input, "is a single frame (number 0); `frame` " + std::to_string(frame) + " is for directories");
  }
  if (std::find(numbers.begin(), numbers.end(), frame) == numbers.end()) {
    throw IoError(input, "has no posed frame " + std::to_string(frame) + " (frames " + std::to_string(numbers.front()) + ".." +
                             std::to_string(numbers.back()) + ", " + std::to_string(numbers.size()) + " of them)");
  }
  Frame f = seq.load(frame);
  if (!f.T_world_camera && seq.posed()) {
    throw IoError(input, "frame " + std::to_string(frame) + ": no pose within `max_pose_gap_s` of its time stamp");
  }
  if (f.description.empty()) f.description = "frame " + std::to_string(frame) + " of " + input;
  f.intrinsics = seq.intrinsics();
  if (!f.colour) f.colour = seq.colour(frame);
  if (f.sources.empty()) f.sources = seq.files(frame);
  f.depth_unit = seq.depthUnit();
  if (const auto down = seq.gravityDown(); down && f.T_world_camera) {
    f.gravity_camera = (f.T_world_camera->linear().transpose() * *down).cast<float>();
  }
  return f;
}

Frame loadSingleFrame(const std::string& input, int frame, const std::string& intrinsics_spec, const RecordingChoice& choice) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (sources::isRecording(input)) {
    const auto seq = openSequence(input, {intrinsics_spec, 0.05, "", choice, ""});
    if (seq->frames().empty()) throw IoError(input, "none of its depth images has a pose (" + seq->skipped() + ")");
    Frame f = loadSequenceFrame(*seq, input, frame < 0 ? seq->frames().front() : frame);
    f.description = "depth image " + std::to_string(f.number) + " of " + seq->describe();
    return f;
  }
  const bool tum = fs::is_directory(input, ec) && fs::exists(fs::path(input) / "depth.txt", ec);
  const std::string ext = fs::path(input).extension().string();
  if (tum || (!fs::is_directory(input, ec) && (ext == ".pcd" || ext == ".png"))) {
    // TUM RGB-D (frames numbered as build numbers them: the depth frames with a pose), or
    // a single file, a sequence of one frame.
    const auto seq = openSequence(input, {intrinsics_spec, 0.05, "", {}, ""});
    Frame f = loadSequenceFrame(*seq, input, frame < 0 ? seq->frames().front() : frame);
    if (tum) f.description += " (TUM RGB-D)";
    return f;
  }
  if (fs::is_directory(input, ec)) {
    const SevenScenesDirectory dir(input, intrinsics_spec);
    const int n = frame < 0 ? dir.frameNumbers().front() : frame;
    if (std::find(dir.frameNumbers().begin(), dir.frameNumbers().end(), n) == dir.frameNumbers().end()) {
      throw IoError(input, "has no frame " + std::to_string(n) + " (frames " + std::to_string(dir.frameNumbers().front()) +
                               ".." + std::to_string(dir.frameNumbers().back()) + ")");
    }
    // Read directly, not as a sequence: analyze takes a frame without its pose file.
    Frame f;
    f.description = "frame " + std::to_string(n) + " of " + input;
    f.intrinsics = dir.intrinsics();
    f.depth = dir.readDepth(n);
    f.colour = dir.readColour(n);
    f.sources = {dir.depthPath(n), dir.posePath(n)};
    if (fs::exists(dir.posePath(n), ec)) {
      f.T_world_camera = Eigen::Isometry3d(dir.readPose(n));
      if (dir.gravityDown()) {
        const Eigen::Matrix3d r_wc = f.T_world_camera->matrix().topLeftCorner<3, 3>();
        f.gravity_camera = (r_wc.transpose() * *dir.gravityDown()).cast<float>();
      }
    }
    return f;
  }
  if (!fs::exists(input, ec)) throw IoError(input, "no such file or directory");
  throw IoError(input, "unknown input type (expected a .pcd, a 16-bit depth .png, a 7-Scenes or a TUM RGB-D directory)");
}

void toInputFrame(perception::FrameResult& r, const Frame& f) {
  if (!f.T_cloud_camera) return;
  const Eigen::Isometry3f T = f.T_cloud_camera->cast<float>();
  const Eigen::Matrix3f R = T.linear();
  for (Eigen::Vector3f& p : r.points) p = T * p;
  for (Eigen::Vector3f& n : r.normals) n = R * n;
  for (perception::Segment& s : r.segments) {
    s.centroid = T * s.centroid;
    s.normal = R * s.normal;
  }
  if (r.ground_plane) {  // n.p + d = 0 in the camera frame: (R n).q + d - (R n).t = 0
    const Eigen::Vector3f n = R * r.ground_plane->head<3>();
    const float d = (*r.ground_plane)(3) - n.dot(T.translation());
    *r.ground_plane = Eigen::Vector4f(n.x(), n.y(), n.z(), d);
  }
}

void decodeDepthFormat(Frame& f, const std::string& format, const std::string& input) {
  if (!f.depth || f.depth_unit.cloud || f.depth_unit.units_per_m < 2.0) {
    throw util::FieldError("depth_format", format + " is for 16-bit depth images; " + input + " gives " +
                     (f.depth ? "depth in metres as floats" : "a point cloud"));
  }
  sources::undoDepthFormat(*f.depth, f.depth_unit.units_per_m, format);
}

perception::FrameResult perceiveFrame(const perception::FramePipeline& pipeline, const Frame& f,
                                      const std::optional<Eigen::Vector3f>& gravity_down_camera) {
  if (f.depth) return pipeline.process(*f.depth, f.intrinsics, gravity_down_camera);
  return f.height > 1 ? pipeline.processOrganized(f.points, f.width, f.height, gravity_down_camera)
                      : pipeline.process(f.points, gravity_down_camera);
}

std::optional<GroundExtent> groundExtent(const perception::FrameResult& r) {
  const perception::Segment* ground = nullptr;
  for (const perception::Segment& s : r.segments) {
    if (s.is_ground) ground = &s;
  }
  if (!ground || ground->points.empty()) return std::nullopt;
  GroundExtent g;
  g.points = ground->points.size(), g.frame_points = r.points.size(), g.area_m2 = ground->area_m2;
  std::vector<double> d;
  d.reserve(ground->points.size());
  for (const int i : ground->points) d.push_back(r.points[static_cast<std::size_t>(i)].cast<double>().norm());
  const auto at = [&d](double q) {
    const auto k = static_cast<std::size_t>(std::lround(q * static_cast<double>(d.size() - 1)));
    std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(k), d.end());
    return d[k];
  };
  g.near_m = at(0.05), g.median_m = at(0.5), g.far_m = at(0.95);
  return g;
}

std::string describeGround(const GroundExtent& g) {
  char buf[200];
  std::snprintf(buf, sizeof buf, "%.1f m2, %.0f %% of the frame's points, 90 %% of them %.1f-%.1f m from the camera", g.area_m2,
                g.frame_points ? 100.0 * static_cast<double>(g.points) / static_cast<double>(g.frame_points) : 0.0, g.near_m,
                g.far_m);
  return buf;
}

std::string groundChoiceNote(const perception::FrameResult& r, double upright_prior_deg) {
  if (!r.ground_plane) return {};
  const double tilt = perception::imageUpTiltDeg(*r.ground_plane);
  char buf[400];
  if (r.ground_rule == perception::GroundRule::kUprightPrior) {
    std::snprintf(buf, sizeof buf,
                  "note: no gravity given; the largest plane found leans away from the image's up axis (a wall?), so the "
                  "ground is the largest plane below the camera within %.0f degrees of that axis (this one: %.0f degrees; "
                  "the camera taken as held upright). `gravity` X,Y,Z sets it.",
                  upright_prior_deg, tilt);
    return buf;
  }
  if (r.ground_rule != perception::GroundRule::kLargestPlane || !(tilt > 45.0)) return {};
  // A plane far from the image's up axis is a wall only if the camera was held upright.
  // What else the frame shows decides whether to say so: a surface that would be the
  // floor of an upright camera (within 30 degrees of the up axis) makes it likely; levels
  // parallel to the plane at other heights (treads, a floor with things on it, seen from
  // above) make it a floor, and nothing is said.
  const Eigen::Vector3f n = r.ground_plane->head<3>();
  const float d = (*r.ground_plane)(3);
  // A segment counts as evidence with 1 % of the ground's points (a tread seen at the
  // edge of a view from above has a few hundred), and at least 100.
  std::size_t ground_points = 0;
  for (const perception::Segment& s : r.segments) ground_points = std::max(ground_points, s.is_ground ? s.points.size() : 0);
  const std::size_t substantial = std::max<std::size_t>(100, ground_points / 100);
  bool upright_floor = false, parallel_level = false;
  for (const perception::Segment& s : r.segments) {
    if (s.is_ground || s.points.size() < substantial) continue;
    const Eigen::Vector3f sn = s.normal.normalized();
    const Eigen::Vector4f as_plane(sn.x(), sn.y(), sn.z(), -sn.dot(s.centroid));
    if (perception::imageUpTiltDeg(as_plane) < 30.0) upright_floor = true;
    const double offset = std::abs(n.dot(s.centroid) + d);
    if (std::abs(sn.dot(n)) > std::cos(10.0 * M_PI / 180.0) && offset > 0.05) parallel_level = true;
  }
  if (!upright_floor && parallel_level) return {};
  if (!upright_floor) {
    std::snprintf(buf, sizeof buf,
                  "note: no gravity given, so the ground is the largest plane, %.0f degrees from the image's up axis: a "
                  "floor seen from above, or a wall if the camera was held level (then pass `gravity` 0,1,0).",
                  tilt);
    return buf;
  }
  if (upright_prior_deg > 0) {
    std::snprintf(buf, sizeof buf,
                  "note: no gravity given and no floor within %.0f degrees of the image's up axis, so the ground is the "
                  "largest plane; this one is %.0f degrees from that axis and may be a wall. If the camera was held "
                  "level, pass `gravity` 0,1,0.",
                  upright_prior_deg, tilt);
  } else {
    std::snprintf(buf, sizeof buf,
                  "note: no gravity given, so the ground is the largest plane (ground_upright_prior_deg is 0); this one "
                  "is %.0f degrees from the image's up axis and may be a wall. If the camera was held level, pass "
                  "`gravity` 0,1,0.",
                  tilt);
  }
  return buf;
}

}  // namespace mobmap::builder
