#include "mobmap/sources/sequence.hpp"

#include "recording_sequence.hpp"

#include "mobmap/mapping/gravity.hpp"
#include "mobmap/mapping/trajectory.hpp"
#include "mobmap/perception/camera.hpp"
#include "mobmap/sources/dataset.hpp"
#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/openni.hpp"
#include "mobmap/sources/pcd.hpp"
#include "mobmap/sources/trajectory_files.hpp"

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <filesystem>
#include <sstream>

namespace mobmap::sources {
namespace {

namespace fs = std::filesystem;

// A pose gap as the notes print it: "0.05".
std::string gapText(double seconds) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", seconds);
  return text;
}

class SevenScenesSequence : public Sequence {
 public:
  SevenScenesSequence(const std::string& dir, const std::string& intrinsics_spec) : dir_(dir, intrinsics_spec) {}
  std::string format() const override { return "7-Scenes layout"; }
  std::string describe() const override { return dir_.dir() + " (7-Scenes layout, " + std::to_string(dir_.frameNumbers().size()) + " frames)"; }
  const perception::PinholeIntrinsics& intrinsics() const override { return dir_.intrinsics(); }
  std::optional<Eigen::Vector3d> gravityDown() const override { return dir_.gravityDown(); }
  const std::vector<int>& frames() const override { return dir_.frameNumbers(); }
  void check(int n) const override {
    std::error_code ec;
    if (!fs::exists(dir_.posePath(n), ec)) throw IoError(dir_.posePath(n), "missing: every frame needs a pose");
    (void)dir_.readPose(n);  // parsed and found rigid now, not when the run reaches frame n
    checkPngComplete(dir_.depthPath(n));
  }
  Frame load(int n) const override {
    Frame f;
    f.number = n;
    f.depth = dir_.readDepth(n);
    f.T_world_camera = *pose(n);
    return f;
  }
  std::optional<ImageRgb> colour(int n) const override { return dir_.readColour(n); }
  std::vector<std::string> files(int n) const override { return {dir_.depthPath(n), dir_.posePath(n)}; }
  std::optional<Eigen::Isometry3d> pose(int n) const override {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.matrix() = dir_.readPose(n);
    T.linear() = mapping::nearestRotation(T.linear());
    return T;
  }

 private:
  SevenScenesDirectory dir_;
};

}  // namespace

namespace {

// A directory of .pcd frames (or one file) with a TUM-format trajectory: one pose per
// frame in file-name order, or timestamped poses matched to time stamps in the names.
class PcdSequence : public Sequence {
 public:
  [[nodiscard]] DepthUnit depthUnit() const override { return {1.0, true}; }
  PcdSequence(const std::string& input, const std::string& intrinsics_spec, double max_gap, const std::string& poses)
      : input_(input), poses_path_(poses) {
    std::error_code ec;
    std::vector<std::string> files;
    if (fs::is_directory(input, ec)) {
      for (const auto& e : fs::directory_iterator(input, ec)) {
        if (e.path().extension() == ".pcd") files.push_back(e.path().string());
      }
      std::sort(files.begin(), files.end());
      if (files.empty()) throw IoError(input, "no .pcd files in this directory");
    } else {
      files.push_back(input);
    }
    if (poses.empty()) {
      throw IoError(input, std::to_string(files.size()) + " .pcd frames but no poses: give `poses` FILE (TUM format " +
                               "'t tx ty tz qx qy qz qw'); only a single frame can be mapped without poses");
    }
    const auto list = readTumPoses(poses);
    if (list.empty()) throw IoError(poses, "no poses in this file");
    if (list.size() == files.size()) {
      for (std::size_t i = 0; i < files.size(); ++i) add(files[i], list[i].second, timestampFromFileName(files[i]));
      how_ = "one pose per frame in file-name order";
    } else {
      mapping::Trajectory trajectory;
      for (const auto& [t, T] : list) trajectory.insert(t, T);
      int skipped = 0;
      double first_t = 0, last_t = 0;
      for (const auto& f : files) {
        const auto t = timestampFromFileName(f);
        if (!t) {
          throw IoError(poses, std::to_string(list.size()) + " poses for " + std::to_string(files.size()) +
                                   " .pcd frames, and " + fs::path(f).filename().string() +
                                   " has no time stamp in its name to match poses by time: give one pose per frame " +
                                   "(in file-name order) or name the frames by time stamp");
        }
        first_t = &f == &files.front() ? *t : std::min(first_t, *t);
        last_t = &f == &files.front() ? *t : std::max(last_t, *t);
        if (auto T = trajectory.at(*t, max_gap)) {
          add(f, *T, t);
        } else {
          ++skipped;
        }
      }
      if (skipped > 0) {
        skipped_ = std::to_string(skipped) + " of " + std::to_string(files.size()) +
                   " .pcd frames have no pose within `max_pose_gap_s` " + gapText(max_gap) + " s and were skipped";
      }
      if (entries_.empty()) {
        std::ostringstream msg;
        msg.precision(15);
        msg << "no .pcd frame has poses within " << max_gap << " s around its time stamp (frames span " << first_t
            << " to " << last_t << " s, poses " << list.front().first << " to " << list.back().first
            << " s; `max_pose_gap_s` sets the tolerance)";
        throw IoError(poses, msg.str());
      }
      how_ = "poses matched by the time stamps in the file names";
    }
    // Organized frames that are a pinhole image become depth images, so free space
    // can be projected like for any depth camera.
    const Frame first = loadPcd(entries_.front().path, false);
    if (!intrinsics_spec.empty() && first.height > 1) {
      k_ = parseIntrinsics(intrinsics_spec, first.width, first.height);
      depth_ = true;
    } else if (first.height > 1) {
      // Points in another frame than the camera's (a driver's, a robot's) give the
      // camera's pose in it as well: the poses are then the cloud frame's.
      if (const auto camera = fitCloudCamera(first.points, first.width, first.height)) {
        k_ = camera->intrinsics;
        depth_ = true;
        fit_rms_ = camera->rms_px;
        fit_share_ = camera->inlier_share;
        T_cloud_camera_ = camera->T_cloud_camera;
      }
    }
  }
  std::string format() const override { return ".pcd frames"; }
  std::string describe() const override {
    std::ostringstream s;
    s << input_ << " (" << entries_.size() << " .pcd frames, " << how_ << " from " << poses_path_;
    if (depth_) {
      s << "; pinhole fx " << k_.fx << " fy " << k_.fy << " cx " << k_.cx << " cy " << k_.cy;
      if (fit_rms_) s << " fitted to the first frame, RMS " << *fit_rms_ << " px over the " << 100.0 * fit_share_ << " % of its points on their rays";
      if (T_cloud_camera_) {
        s << "; its points are in a frame turned " << Eigen::AngleAxisd(T_cloud_camera_->linear()).angle() * 180.0 / M_PI
          << " degrees from the camera's, which the poses are taken to be of";
      }
    } else {
      s << "; clouds without a pinhole model: no free-space clearing";
    }
    s << ")";
    return s.str();
  }
  const perception::PinholeIntrinsics& intrinsics() const override { return k_; }
  bool hasDepth() const override { return depth_; }
  std::optional<Eigen::Vector3d> gravityDown() const override { return std::nullopt; }
  const std::vector<int>& frames() const override { return frames_; }
  void check(int n) const override {
    std::error_code ec;
    const std::string& path = entries_.at(static_cast<std::size_t>(n)).path;
    if (!fs::exists(path, ec)) throw IoError(path, "missing");
    checkPcdComplete(path);
  }
  Frame load(int n) const override {
    const Entry& e = entries_.at(static_cast<std::size_t>(n));
    Frame lf = loadPcd(e.path, false);
    Frame f;
    f.number = n;
    f.T_world_camera = e.pose;
    f.stamp_s = e.t;
    if (T_cloud_camera_) f.T_world_camera = e.pose * *T_cloud_camera_;
    if (!depth_) {
      f.points = std::move(lf.points);
      f.width = lf.width;
      f.height = lf.height;
      return f;
    }
    if (lf.width != k_.width || lf.height != k_.height) {
      throw IoError(e.path, "cloud is " + std::to_string(lf.width) + "x" + std::to_string(lf.height) +
                                " but the sequence's frames are " + std::to_string(k_.width) + "x" + std::to_string(k_.height));
    }
    // Placeholders and points off their rays are no depth; a frame with many off their
    // rays is not the first frame's pinhole image.
    const StrayPoints stray = toCameraImage(lf.points, lf.width, CloudCamera{k_, 0.0, 1.0, T_cloud_camera_});
    if (stray.measured > 0 &&
        static_cast<double>(stray.off_ray) > (1.0 - kMinCameraInlierShare) * static_cast<double>(stray.measured)) {
      throw IoError(e.path, "its points are not a pinhole image with the intrinsics of the first frame (" +
                                std::to_string(stray.off_ray) + " of its " + std::to_string(stray.measured) +
                                " points lie off their pixels' rays); map such clouds one at a time");
    }
    f.depth = perception::DepthImage(lf.width, lf.height);
    for (std::size_t i = 0; i < lf.points.size(); ++i) {
      const Eigen::Vector3f& p = lf.points[i];
      f.depth->depth_m[i] = p.allFinite() && p.z() > 0.f ? p.z() : 0.f;
    }
    return f;
  }
  std::optional<ImageRgb> colour(int n) const override {
    if (!depth_) return std::nullopt;  // unorganized: no image to colour
    Frame lf = loadPcd(entries_.at(static_cast<std::size_t>(n)).path, false);
    if (!lf.colour || lf.colour->width != k_.width || lf.colour->height != k_.height) return std::nullopt;
    return std::move(lf.colour);
  }
  std::string skipped() const override { return skipped_; }
  std::optional<Eigen::Isometry3d> pose(int n) const override {
    return entries_.at(static_cast<std::size_t>(n)).pose * T_cloud_camera_.value_or(Eigen::Isometry3d::Identity());
  }
  std::vector<std::string> files(int n) const override { return {entries_.at(static_cast<std::size_t>(n)).path, poses_path_}; }

 private:
  struct Entry {
    std::string path;
    Eigen::Isometry3d pose;
    std::optional<double> t;  ///< the time stamp in its name
  };
  void add(const std::string& path, const Eigen::Isometry3d& T, std::optional<double> t) {
    frames_.push_back(static_cast<int>(entries_.size()));
    entries_.push_back({path, T, t});
  }
  std::optional<Eigen::Isometry3d> T_cloud_camera_;  // when its points are not in the camera frame
  std::string input_, poses_path_, how_, skipped_;
  std::vector<Entry> entries_;
  std::vector<int> frames_;
  perception::PinholeIntrinsics k_;
  bool depth_ = false;
  std::optional<double> fit_rms_;
  double fit_share_ = 1.0;
};

class TumSequence : public Sequence {
 public:
  [[nodiscard]] DepthUnit depthUnit() const override { return {5000.0, false}; }
  TumSequence(const std::string& dir, const std::string& intrinsics_spec, double max_gap) : dir_(dir) {
    const std::string gt_path = (fs::path(dir) / "groundtruth.txt").string();
    std::error_code ec;
    if (!fs::exists(gt_path, ec)) throw IoError(gt_path, "missing: mobmap reads a TUM sequence with its ground-truth poses (they number its frames)");
    for (const auto& [t, T] : readTumPoses(gt_path)) trajectory_.insert(t, T);
    const auto depth_list = readTimestamped((fs::path(dir) / "depth.txt").string(), 1);
    int skipped = 0;
    for (const auto& [t, v] : depth_list) {
      if (auto pose = trajectory_.at(t, max_gap)) {
        frames_.push_back(static_cast<int>(entries_.size()));
        entries_.push_back({t, (fs::path(dir) / v[0]).string(), *pose});
      } else {
        ++skipped;
      }
    }
    if (skipped > 0) {
      skipped_ = std::to_string(skipped) + " of " + std::to_string(depth_list.size()) +
                 " depth frames have no ground-truth pose within `max_pose_gap_s` " + gapText(max_gap) + " s and were skipped";
    }
    if (entries_.empty()) throw IoError(dir, "no depth frame of depth.txt has a ground-truth pose");
    const fs::path rgb_txt = fs::path(dir) / "rgb.txt";
    if (fs::exists(rgb_txt, ec)) {
      for (const auto& [t, v] : readTimestamped(rgb_txt.string(), 1)) rgb_.emplace_back(t, (fs::path(dir) / v[0]).string());
      std::sort(rgb_.begin(), rgb_.end());
    }
    const Image16 first = readPng16(entries_.front().path);
    k_ = intrinsics_spec.empty() ? perception::PinholeIntrinsics{first.width, first.height, 525.0, 525.0, 319.5, 239.5}
                                 : parseIntrinsics(intrinsics_spec, first.width, first.height);
  }
  std::string format() const override { return "TUM RGB-D"; }
  std::string describe() const override { return dir_ + " (TUM RGB-D, " + std::to_string(entries_.size()) + " posed frames)"; }
  const perception::PinholeIntrinsics& intrinsics() const override { return k_; }
  std::optional<Eigen::Vector3d> gravityDown() const override { return std::nullopt; }
  const std::vector<int>& frames() const override { return frames_; }
  void check(int n) const override {
    std::error_code ec;
    const std::string& path = entries_.at(static_cast<std::size_t>(n)).path;
    if (!fs::exists(path, ec)) throw IoError(path, "missing");
    checkPngComplete(path);
  }
  Frame load(int n) const override {
    const Entry& e = entries_.at(static_cast<std::size_t>(n));
    const Image16 img = readPng16(e.path);
    if (img.width != k_.width || img.height != k_.height) {
      throw IoError(e.path, "depth image is " + std::to_string(img.width) + "x" + std::to_string(img.height) +
                                " but the sequence's images are " + std::to_string(k_.width) + "x" + std::to_string(k_.height));
    }
    Frame f;
    f.number = n;
    f.depth = perception::DepthImage(img.width, img.height);
    for (std::size_t i = 0; i < img.pixels.size(); ++i) f.depth->depth_m[i] = static_cast<float>(img.pixels[i]) / 5000.f;  // TUM: 5000 per metre
    f.T_world_camera = e.pose;
    f.stamp_s = e.t;
    return f;
  }
  std::optional<ImageRgb> colour(int n) const override {
    if (rgb_.empty()) return std::nullopt;
    const double t = entries_.at(static_cast<std::size_t>(n)).t;
    auto it = std::lower_bound(rgb_.begin(), rgb_.end(), t, [](const auto& e, double v) { return e.first < v; });
    if (it == rgb_.end() || (it != rgb_.begin() && t - std::prev(it)->first < it->first - t)) --it;
    if (std::abs(it->first - t) > 0.02) return std::nullopt;  // TUM's associate.py pairs within 0.02 s
    ImageRgb c = readPngRgb(it->second);
    if (c.width != k_.width || c.height != k_.height) return std::nullopt;
    return c;
  }
  std::string skipped() const override { return skipped_; }
  std::optional<Eigen::Isometry3d> pose(int n) const override { return entries_.at(static_cast<std::size_t>(n)).pose; }
  std::vector<std::string> files(int n) const override {
    return {entries_.at(static_cast<std::size_t>(n)).path, (fs::path(dir_) / "groundtruth.txt").string(),
            (fs::path(dir_) / "depth.txt").string()};
  }

 private:
  struct Entry {
    double t;
    std::string path;
    Eigen::Isometry3d pose;
  };
  std::string dir_;
  mapping::Trajectory trajectory_;
  std::vector<Entry> entries_;
  std::vector<std::pair<double, std::string>> rgb_;  ///< rgb.txt: time stamp, image path
  std::vector<int> frames_;
  std::string skipped_;
  perception::PinholeIntrinsics k_;
};

}  // namespace

namespace {

// A single .png or .pcd: a sequence of one frame (number 0) without a pose, loaded when
// it is opened.
class SingleFileSequence : public Sequence {
 public:
  SingleFileSequence(const std::string& input, const std::string& intrinsics_spec) {
    std::error_code ec;
    if (!fs::exists(input, ec)) throw IoError(input, "no such file");
    if (fs::path(input).extension() == ".pcd") {
      frame_ = loadPcd(input);
      format_ = ".pcd file";
      return;
    }
    // Without --intrinsics, a camera-intrinsics.txt beside the PNG (as in a 7-Scenes
    // directory or the RealSense data) describes its camera.
    std::string spec = intrinsics_spec;
    if (spec.empty()) {
      const fs::path beside = fs::path(input).parent_path() / "camera-intrinsics.txt";
      if (!fs::is_regular_file(beside, ec)) {
        throw util::FieldError("intrinsics", "(fx,fy,cx,cy or a camera file) is needed for a depth PNG without a "
                                             "camera-intrinsics.txt beside it: " + input);
      }
      spec = beside.string();
      frame_.note = "intrinsics from " + spec + ", beside the PNG (`intrinsics` gives others)";
    }
    frame_.description = input;
    frame_.depth = readDepthPng(input);
    frame_.intrinsics = parseIntrinsics(spec, frame_.depth->width, frame_.depth->height);
  }
  std::string format() const override { return format_; }
  std::string describe() const override { return frame_.description; }
  const perception::PinholeIntrinsics& intrinsics() const override { return frame_.intrinsics; }
  bool hasDepth() const override { return frame_.depth.has_value(); }
  std::optional<Eigen::Vector3d> gravityDown() const override { return std::nullopt; }
  bool posed() const override { return false; }
  const std::vector<int>& frames() const override { return frames_; }
  void check(int /*n*/) const override {}
  Frame load(int /*n*/) const override { return frame_; }
  std::optional<ImageRgb> colour(int /*n*/) const override { return frame_.colour; }
  std::vector<std::string> files(int /*n*/) const override { return frame_.sources; }
  DepthUnit depthUnit() const override { return frame_.depth_unit; }

 private:
  std::string format_ = "depth PNG";
  Frame frame_;
  std::vector<int> frames_{0};
};

}  // namespace

const std::vector<std::pair<std::string, std::string>>& depthFormats() {
  static const std::vector<std::pair<std::string, std::string>> formats{
      {"sunrgbd", "SUN RGB-D's depth PNGs: millimetres rotated left by 3 bits"}};
  return formats;
}

void undoDepthFormat(perception::DepthImage& depth, double units_per_m, const std::string& format) {
  if (format != "sunrgbd") {
    std::string known;
    for (const auto& [name, what] : depthFormats()) known += (known.empty() ? "" : ", ") + name + " (" + what + ")";
    throw util::FieldError("depth_format", "must be one of: " + known + "; got '" + format + "'");
  }
  for (float& d : depth.depth_m) {
    if (!(d > 0.f) || !std::isfinite(d)) continue;
    const long stored = std::lround(static_cast<double>(d) * units_per_m);
    if (stored <= 0 || stored >= 65535) {  // not a 16-bit value, or its "no measurement"
      d = 0.f;
      continue;
    }
    const auto v = static_cast<std::uint16_t>(stored);
    const auto decoded = static_cast<std::uint16_t>((v >> 3) | (v << 13));
    // As the readers read a value: millimetres as metresFromMillimetres, others divided in float.
    d = units_per_m == 1000.0 ? perception::metresFromMillimetres(decoded)
        : decoded == 0 || decoded == 65535 ? 0.f
                                           : static_cast<float>(decoded) / static_cast<float>(units_per_m);
  }
}

namespace {

// A sequence of 16-bit depth images in another encoding (`--depth-format`), decoded.
class DepthFormatSequence : public ForwardingSequence {
 public:
  DepthFormatSequence(std::unique_ptr<Sequence> inner, std::string format)
      : ForwardingSequence(std::move(inner)), format_(std::move(format)) {}
  std::string describe() const override { return inner().describe() + ", depth decoded as " + format_; }
  Frame load(int n) const override {
    Frame f = inner().load(n);
    if (f.depth) undoDepthFormat(*f.depth, inner().depthUnit().units_per_m, format_);
    return f;
  }

 private:
  std::string format_;
};

std::unique_ptr<Sequence> openPlainSequence(const std::string& input, const SequenceOptions& options);

}  // namespace

std::unique_ptr<Sequence> openSequence(const std::string& input, const SequenceOptions& options) {
  auto seq = openPlainSequence(input, options);
  if (options.depth_format.empty()) return seq;
  perception::DepthImage probe(1, 1);
  undoDepthFormat(probe, 1000.0, options.depth_format);  // an unknown name is refused before a run
  if (!seq->hasDepth() || seq->depthUnit().cloud || seq->depthUnit().units_per_m < 2.0) {
    throw util::FieldError("depth_format", options.depth_format + " is for 16-bit depth images; " + input +
                     " gives " + (seq->hasDepth() && !seq->depthUnit().cloud ? "depth in metres as floats" : "point clouds"));
  }
  return std::make_unique<DepthFormatSequence>(std::move(seq), options.depth_format);
}

namespace {

std::unique_ptr<Sequence> openPlainSequence(const std::string& input, const SequenceOptions& options) {
  const std::string& intrinsics_spec = options.intrinsics;
  const std::string& poses_path = options.poses;
  const double max_pose_gap_s = options.max_pose_gap_s;
  std::error_code ec;
  if (isRecording(input)) return openRecordingSequence(input, options);
  if (!fs::is_directory(input, ec)) {
    const fs::path ext = fs::path(input).extension();
    if (ext == ".oni") {  // every frame, read in order
      OpenNiOptions on;
      on.uri = input;
      on.is_file = true;
      on.intrinsics_spec = intrinsics_spec;
      on.poses_path = poses_path;
      on.max_pose_gap_s = max_pose_gap_s;
      return openOpenNi(on);
    }
    if (ext == ".pcd" && !poses_path.empty()) {
      return std::make_unique<PcdSequence>(input, intrinsics_spec, max_pose_gap_s, poses_path);
    }
    if (ext == ".pcd" || ext == ".png") {
      if (!poses_path.empty()) throw IoError(poses_path, "`poses` is for .pcd frames; a depth .png is mapped on its own");
      return std::make_unique<SingleFileSequence>(input, intrinsics_spec);
    }
    if (!fs::exists(input, ec)) throw IoError(input, "no such file or directory");
    throw IoError(input, "not a directory");
  }
  if (fs::exists(fs::path(input) / "depth.txt", ec)) {
    if (!poses_path.empty()) throw IoError(poses_path, "a TUM directory brings its own groundtruth.txt; `poses` is for .pcd frames");
    return std::make_unique<TumSequence>(input, intrinsics_spec, max_pose_gap_s);
  }
  bool pcd = false, seven = false;
  for (const auto& e : fs::directory_iterator(input, ec)) {
    const std::string name = e.path().filename().string();
    pcd = pcd || e.path().extension() == ".pcd";
    seven = seven || (name.rfind("frame-", 0) == 0 && name.find(".depth.") != std::string::npos);
  }
  if (pcd && !seven) return std::make_unique<PcdSequence>(input, intrinsics_spec, max_pose_gap_s, poses_path);
  if (!poses_path.empty()) throw IoError(poses_path, "a 7-Scenes directory brings its own frame-*.pose.txt; `poses` is for .pcd frames");
  return std::make_unique<SevenScenesSequence>(input, intrinsics_spec);
}

}  // namespace

}  // namespace mobmap::sources
