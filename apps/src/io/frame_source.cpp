#include "io/frame_source.hpp"

#include "io/dataset.hpp"
#include "io/files.hpp"
#include "io/io_error.hpp"
#include "io/png_io.hpp"
#include "io/sequence.hpp"

#include <pcl/console/print.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace mobmap::app {

Eigen::Vector3f parseVector3(const std::string& spec, const std::string& what) {
  const auto v = splitNumbers(spec);
  if (v.size() != 3) throw UsageError(what + " must be three numbers X,Y,Z, got '" + spec + "'");
  // Normalised in double (stableNorm does not overflow): 1e39 is finite as a double
  // but not as a float, and squaring 1e20 overflows a float.
  const Eigen::Vector3d d(v[0], v[1], v[2]);
  const double length = d.stableNorm();
  if (length < 1e-6) throw UsageError(what + " must not be the zero vector");
  return (d / length).cast<float>();
}

namespace {

struct PcdHeader {
  pcl::PCLPointCloud2 fields;  // fields, width, height, point_step; no data
  int data_type = 0;           // 0 ascii, 1 binary, 2 binary_compressed
  unsigned int data_offset = 0;
  bool has_rgb = false;
};

// PCL's header reader allocates the declared size: WIDTH, HEIGHT and POINTS are read
// here first and checked against the frame-size limit.
void checkDeclaredPointCount(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  unsigned long long width = 1, height = 1, points = 0;
  for (int lines = 0; lines < 64 && std::getline(in, line); ++lines) {
    std::istringstream words(line);
    std::string key;
    words >> key;
    if (key == "DATA") break;
    if (key != "WIDTH" && key != "HEIGHT" && key != "POINTS") continue;
    std::string value;
    words >> value;
    if (value.empty() || value.find_first_not_of("0123456789") != std::string::npos || value.size() > 15) {
      throw IoError(path, "PCD header's " + key + " '" + value + "' is not a whole number below 10^15");
    }
    (key == "WIDTH" ? width : key == "HEIGHT" ? height : points) = std::stoull(value);
  }
  const unsigned long long declared = std::max(points, width * height);
  if (declared > static_cast<unsigned long long>(kMaxFramePixels)) {
    throw IoError(path, "PCD header declares " + std::to_string(declared) + " points (WIDTH " + std::to_string(width) +
                            ", HEIGHT " + std::to_string(height) + "), more than mobmap reads in one frame (" +
                            std::to_string(kMaxFramePixels) + ")");
  }
}

// The header of a .pcd, which must exist and have x, y and z; IoError if not.
PcdHeader readPcdHeader(const std::string& path) {
  if (!std::filesystem::exists(path)) throw IoError(path, "no such file");
  checkDeclaredPointCount(path);
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);  // errors come back as codes; we word them
  pcl::PCDReader reader;
  PcdHeader h;
  Eigen::Vector4f origin;
  Eigen::Quaternionf orientation;
  int version = 0;
  if (reader.readHeader(path, h.fields, origin, orientation, version, h.data_type, h.data_offset) < 0) {
    throw IoError(path, "not a readable PCD file (bad header)");
  }
  bool has_x = false, has_y = false, has_z = false;
  for (const auto& f : h.fields.fields) {
    has_x |= f.name == "x";
    has_y |= f.name == "y";
    has_z |= f.name == "z";
    h.has_rgb |= f.name == "rgb" || f.name == "rgba";
  }
  if (!(has_x && has_y && has_z)) throw IoError(path, "PCD has no x, y and z fields");
  return h;
}

}  // namespace

namespace {

// What the header declares must fit the file, checked before PCL allocates the declared
// size (a header claiming 10^7 points over a few kilobytes of data); readPcdHeader has
// held it to the frame-size limit already. Binary data must be all there; ASCII data
// needs at least two bytes ("0 ") per value.
void checkPcdDeclaredSize(const std::string& path, const PcdHeader& h) {
  const unsigned long long points = static_cast<unsigned long long>(h.fields.width) * h.fields.height;
  std::error_code ec;
  const auto size = static_cast<unsigned long long>(std::filesystem::file_size(path, ec));
  if (ec) throw IoError(path, "cannot read its size: " + ec.message());
  const unsigned long long start = h.data_offset;
  const unsigned long long data = size > start ? size - start : 0;
  const unsigned long long declared = points * h.fields.point_step;
  if (h.data_type == 1) {
    if (data < declared) {
      throw IoError(path, "PCD data is shorter than its header declares (" + std::to_string(size) + " bytes, " +
                              std::to_string(start + declared) + " needed)");
    }
  } else if (h.data_type == 2) {
    // Two little-endian 32-bit sizes (compressed, uncompressed), then the compressed bytes.
    std::ifstream in(path, std::ios::binary);
    unsigned char sizes[8] = {};
    if (!in.seekg(static_cast<std::streamoff>(start)) || !in.read(reinterpret_cast<char*>(sizes), 8)) {
      throw IoError(path, "PCD data is corrupt or shorter than its header declares (no compressed block sizes)");
    }
    const auto le32 = [&](int at) {
      return static_cast<unsigned long long>(sizes[at]) | static_cast<unsigned long long>(sizes[at + 1]) << 8 |
             static_cast<unsigned long long>(sizes[at + 2]) << 16 | static_cast<unsigned long long>(sizes[at + 3]) << 24;
    };
    const unsigned long long compressed = le32(0), uncompressed = le32(4);
    if (data < 8 + compressed) {
      throw IoError(path, "PCD data is shorter than its header declares (" + std::to_string(size) + " bytes, " +
                              std::to_string(start + 8 + compressed) + " needed)");
    }
    if (uncompressed != declared) {
      throw IoError(path, "PCD compressed data says it holds " + std::to_string(uncompressed) + " bytes, but " +
                              std::to_string(points) + " points of " + std::to_string(h.fields.point_step) +
                              " bytes are " + std::to_string(declared) + " (corrupt file)");
    }
  } else {
    std::size_t values = 0;
    for (const auto& f : h.fields.fields) values += std::max<std::size_t>(1, f.count);
    if (points * values * 2 > data) {
      throw IoError(path, "PCD header declares " + std::to_string(points) + " points of " + std::to_string(values) +
                              " values, but its " + std::to_string(data) + " bytes of ASCII data hold at most " +
                              std::to_string(data / (2 * std::max<std::size_t>(1, values))) + " (corrupt or truncated file)");
    }
  }
}

const pcl::PCLPointField* findField(const pcl::PCLPointCloud2& c, const std::string& name) {
  for (const auto& f : c.fields) {
    if (f.name == name) return &f;
  }
  return nullptr;
}

}  // namespace

void checkPcdComplete(const std::string& path) {
  const PcdHeader h = readPcdHeader(path);  // the declared size within the frame limit
  if (h.data_type == 0) return;  // ASCII: only loading it tells whether the points are all there
  checkPcdDeclaredSize(path, h);
}

LoadedFrame loadPcd(const std::string& path, bool recover_camera) {
  const PcdHeader h = readPcdHeader(path);
  checkPcdDeclaredSize(path, h);
  pcl::PCDReader reader;
  pcl::PCLPointCloud2 cloud;
  Eigen::Vector4f origin;
  Eigen::Quaternionf orientation;
  int version = 0;
  if (reader.read(path, cloud, origin, orientation, version) < 0) throw IoError(path, "PCD data is corrupt or shorter than its header declares");
  // x, y and z as the file stores them: 4- or 8-byte floats (PCL writes both; its
  // conversion to float points leaves 8-byte fields at zero).
  const pcl::PCLPointField* axes[3] = {findField(cloud, "x"), findField(cloud, "y"), findField(cloud, "z")};
  for (const auto* f : axes) {
    if (f->datatype != pcl::PCLPointField::FLOAT32 && f->datatype != pcl::PCLPointField::FLOAT64) {
      throw IoError(path, "PCD field " + f->name + " is not a 4- or 8-byte float (TYPE F, SIZE 4 or 8); mobmap reads "
                          "coordinates in metres as floats");
    }
    const std::size_t bytes = f->datatype == pcl::PCLPointField::FLOAT64 ? 8 : 4;
    if (f->offset + bytes > cloud.point_step) throw IoError(path, "PCD field " + f->name + " lies outside its point (corrupt header)");
  }
  const std::size_t n = static_cast<std::size_t>(cloud.width) * cloud.height;
  if (cloud.data.size() < n * cloud.point_step) throw IoError(path, "PCD data is corrupt or shorter than its header declares");
  const pcl::PCLPointField* rgb = findField(cloud, "rgb");
  if (!rgb) rgb = findField(cloud, "rgba");
  if (rgb && (rgb->datatype == pcl::PCLPointField::FLOAT64 || rgb->datatype == pcl::PCLPointField::INT8 ||
              rgb->datatype == pcl::PCLPointField::UINT8 || rgb->datatype == pcl::PCLPointField::INT16 ||
              rgb->datatype == pcl::PCLPointField::UINT16 || rgb->offset + 4 > cloud.point_step)) {
    rgb = nullptr;  // not a packed colour: drawn without it
  }
  const auto coordinate = [](const std::uint8_t* p, const pcl::PCLPointField& f) {
    if (f.datatype == pcl::PCLPointField::FLOAT64) {
      double v;
      std::memcpy(&v, p + f.offset, 8);
      return static_cast<float>(v);
    }
    float v;
    std::memcpy(&v, p + f.offset, 4);
    return v;
  };
  LoadedFrame f;
  f.points.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* p = cloud.data.data() + i * cloud.point_step;
    f.points.emplace_back(coordinate(p, *axes[0]), coordinate(p, *axes[1]), coordinate(p, *axes[2]));
  }
  f.width = static_cast<int>(cloud.width);
  f.height = static_cast<int>(cloud.height);
  f.depth_unit = {1.0, true};  // PCD coordinates are metres
  if (rgb && cloud.height > 1) {
    ImageRgb c{f.width, f.height, {}};
    c.pixels.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
      std::uint32_t v;
      std::memcpy(&v, cloud.data.data() + i * cloud.point_step + rgb->offset, 4);
      c.pixels.push_back({static_cast<std::uint8_t>(v >> 16), static_cast<std::uint8_t>(v >> 8), static_cast<std::uint8_t>(v)});
    }
    f.colour = std::move(c);
  }
  f.sources = {path};
  std::ostringstream d;
  d << path << " (" << (cloud.height > 1 ? "organized " : "unorganized ") << cloud.width << "x" << cloud.height << ")";
  f.description = d.str();
  if (recover_camera) recoverCameraFrame(f, path);
  return f;
}

LoadedFrame loadSequenceFrame(const Sequence& seq, const std::string& input, int frame) {
  const auto& numbers = seq.frames();
  if (std::find(numbers.begin(), numbers.end(), frame) == numbers.end()) {
    throw IoError(input, "has no posed frame " + std::to_string(frame) + " (frames " + std::to_string(numbers.front()) + ".." +
                             std::to_string(numbers.back()) + ", " + std::to_string(numbers.size()) + " of them)");
  }
  SequenceFrame sf = seq.load(frame);
  if (!sf.has_pose) throw IoError(input, "frame " + std::to_string(frame) + ": no pose within --max-pose-gap of its time stamp");
  LoadedFrame f;
  f.description = "frame " + std::to_string(frame) + " of " + input;
  f.intrinsics = seq.intrinsics();
  f.depth = std::move(sf.depth);
  f.colour = seq.colour(frame);
  f.T_world_camera = sf.T_world_camera.matrix();
  f.sources = seq.files(frame);
  f.depth_unit = seq.depthUnit();
  return f;
}

LoadedFrame loadSingleFrame(const std::string& input, int frame, const std::string& intrinsics_spec) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::is_directory(input, ec) && fs::exists(fs::path(input) / "depth.txt", ec)) {
    // TUM RGB-D: frames numbered as build numbers them (the depth frames with a pose).
    const auto seq = openSequence(input, intrinsics_spec, 0.05);
    LoadedFrame f = loadSequenceFrame(*seq, input, frame < 0 ? seq->frames().front() : frame);
    f.description += " (TUM RGB-D)";
    return f;
  }
  if (fs::is_directory(input, ec)) {
    const SevenScenesDirectory dir(input, intrinsics_spec);
    const int n = frame < 0 ? dir.frameNumbers().front() : frame;
    if (std::find(dir.frameNumbers().begin(), dir.frameNumbers().end(), n) == dir.frameNumbers().end()) {
      throw IoError(input, "has no frame " + std::to_string(n) + " (frames " + std::to_string(dir.frameNumbers().front()) +
                               ".." + std::to_string(dir.frameNumbers().back()) + ")");
    }
    LoadedFrame f;
    f.description = "frame " + std::to_string(n) + " of " + input;
    f.intrinsics = dir.intrinsics();
    f.depth = dir.readDepth(n);
    f.colour = dir.readColour(n);
    f.sources = {dir.depthPath(n), dir.posePath(n)};
    if (fs::exists(dir.posePath(n), ec)) {
      f.T_world_camera = dir.readPose(n);
      if (dir.gravityDown()) {
        const Eigen::Matrix3d r_wc = f.T_world_camera->topLeftCorner<3, 3>();
        f.gravity_camera = (r_wc.transpose() * *dir.gravityDown()).cast<float>();
      }
    }
    return f;
  }
  const std::string ext = fs::path(input).extension().string();
  if (ext == ".pcd") return loadPcd(input);
  if (ext == ".png") {
    // Without --intrinsics, a camera-intrinsics.txt beside the PNG (as in a 7-Scenes
    // directory or the RealSense data) describes its camera.
    std::string spec = intrinsics_spec;
    LoadedFrame f;
    if (spec.empty()) {
      const fs::path beside = fs::path(input).parent_path() / "camera-intrinsics.txt";
      if (!fs::is_regular_file(beside, ec)) {
        throw UsageError("a depth PNG needs --intrinsics fx,fy,cx,cy or FILE (or a camera-intrinsics.txt beside it)");
      }
      spec = beside.string();
      f.note = "intrinsics from " + spec + ", beside the PNG (--intrinsics gives others)";
    }
    f.description = input;
    f.depth = readDepthPng(input);
    f.intrinsics = parseIntrinsics(spec, f.depth->width, f.depth->height);
    return f;
  }
  if (!fs::exists(input, ec)) throw IoError(input, "no such file or directory");
  throw IoError(input, "unknown input type (expected a .pcd, a 16-bit depth .png, a 7-Scenes or a TUM RGB-D directory)");
}

std::optional<CloudCamera> fitCloudCamera(const std::vector<Eigen::Vector3f>& organized, int width, int height,
                                          double* best_rms_px) {
  constexpr double kMaxRmsPx = 0.5, kMaxSkew = 0.01;
  if (best_rms_px) *best_rms_px = std::nan("");
  double rms = 0;
  if (const auto k = perception::fitIntrinsics(organized, width, height, &rms); k && rms < kMaxRmsPx) return CloudCamera{*k, rms, {}};
  const auto fit = perception::fitOrganizedCamera(organized, width, height);
  if (!fit) return std::nullopt;
  if (best_rms_px) *best_rms_px = fit->rms_px;
  if (!(fit->rms_px < kMaxRmsPx) || !(std::abs(fit->skew) < kMaxSkew)) return std::nullopt;
  return CloudCamera{fit->intrinsics, fit->rms_px, fit->T_cloud_camera};
}

void toCameraFrame(std::vector<Eigen::Vector3f>& points, const Eigen::Isometry3d& T_cloud_camera) {
  const Eigen::Isometry3f T_camera_cloud = T_cloud_camera.inverse().cast<float>();
  for (Eigen::Vector3f& p : points) {
    if (p.allFinite()) p = T_camera_cloud * p;
  }
}

void recoverCameraFrame(LoadedFrame& f, const std::string& path) {
  if (f.height <= 1 || f.depth) return;
  double best_rms = 0;
  const auto camera = fitCloudCamera(f.points, f.width, f.height, &best_rms);
  if (camera && !camera->T_cloud_camera) return;  // the camera's frame
  char text[500];
  if (!camera) {
    std::size_t valid = 0;
    for (const Eigen::Vector3f& p : f.points) valid += p.allFinite();
    if (valid < 100) return;  // too few points to tell
    std::snprintf(text, sizeof text,
                  "%s: an organized cloud whose points do not lie on their pixels' rays for any pinhole camera "
                  "(best fit: %s): its frame cannot be recovered, so it is scored as it is, with the image's up axis "
                  "taken as up (--gravity in the cloud's frame says otherwise)",
                  path.c_str(), std::isnan(best_rms) ? "none" : ("RMS " + std::to_string(best_rms) + " px").c_str());
    f.note = text;
    return;
  }
  const Eigen::Isometry3d& T = *camera->T_cloud_camera;
  toCameraFrame(f.points, T);
  f.T_cloud_camera = T;
  std::snprintf(text, sizeof text,
                "%s: its points are not in its camera's frame; the camera, fitted from the pixel grid (fx %.1f fy %.1f "
                "cx %.1f cy %.1f, RMS %.3f px), is turned %.1f degrees and moved %.3f m from the cloud's frame: scored "
                "in the camera's frame, reported in the cloud's",
                path.c_str(), camera->intrinsics.fx, camera->intrinsics.fy, camera->intrinsics.cx, camera->intrinsics.cy,
                camera->rms_px, Eigen::AngleAxisd(T.linear()).angle() * 180.0 / M_PI, T.translation().norm());
  f.note = text;
}

void toInputFrame(perception::FrameResult& r, const LoadedFrame& f) {
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

void rescaleDepth(LoadedFrame& f, double units_per_m) {
  const float factor = depthRescaleFactor(f.depth_unit, units_per_m);
  if (units_per_m == f.depth_unit.units_per_m) return;
  std::vector<float> no_depth;
  scaleDepth(f.depth ? f.depth->depth_m : no_depth, f.points, factor);
  if (f.T_cloud_camera) f.T_cloud_camera->translation() *= static_cast<double>(factor);
  f.depth_unit.units_per_m = units_per_m;
}

perception::FrameResult perceiveFrame(const perception::FramePipeline& pipeline, const LoadedFrame& f,
                                      const std::optional<Eigen::Vector3f>& gravity_down_camera) {
  if (f.depth) return pipeline.process(*f.depth, f.intrinsics, gravity_down_camera);
  return f.height > 1 ? pipeline.processOrganized(f.points, f.width, f.height, gravity_down_camera)
                      : pipeline.process(f.points, gravity_down_camera);
}

std::string groundChoiceNote(const perception::FrameResult& r, double upright_prior_deg) {
  if (!r.ground_plane) return {};
  const double tilt = perception::imageUpTiltDeg(*r.ground_plane);
  char buf[400];
  if (r.ground_rule == perception::GroundRule::kUprightPrior) {
    std::snprintf(buf, sizeof buf,
                  "note: no gravity given; the largest plane found leans away from the image's up axis (a wall?), so the "
                  "ground is the largest plane below the camera within %.0f degrees of that axis (this one: %.0f degrees; "
                  "the camera taken as held upright). --gravity X,Y,Z sets it.",
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
                  "floor seen from above, or a wall if the camera was held level (then pass --gravity 0,1,0).",
                  tilt);
    return buf;
  }
  if (upright_prior_deg > 0) {
    std::snprintf(buf, sizeof buf,
                  "note: no gravity given and no floor within %.0f degrees of the image's up axis, so the ground is the "
                  "largest plane; this one is %.0f degrees from that axis and may be a wall. If the camera was held "
                  "level, pass --gravity 0,1,0.",
                  upright_prior_deg, tilt);
  } else {
    std::snprintf(buf, sizeof buf,
                  "note: no gravity given, so the ground is the largest plane (ground_upright_prior_deg is 0); this one "
                  "is %.0f degrees from the image's up axis and may be a wall. If the camera was held level, pass "
                  "--gravity 0,1,0.",
                  tilt);
  }
  return buf;
}

}  // namespace mobmap::app
