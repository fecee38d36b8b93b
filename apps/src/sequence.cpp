#include "sequence.hpp"

#include "dataset.hpp"
#include "files.hpp"
#include "frame_source.hpp"
#include "io_error.hpp"
#include "png_io.hpp"

#include "mobmap/mapping/gravity.hpp"
#include "mobmap/mapping/trajectory.hpp"

#include <cmath>
#include <filesystem>
#include <sstream>

namespace mobmap::app {
namespace {

namespace fs = std::filesystem;

class SevenScenesSequence : public Sequence {
 public:
  SevenScenesSequence(const std::string& dir, const std::string& intrinsics_spec) : dir_(dir) {
    k_ = intrinsics_spec.empty() ? dir_.intrinsics() : parseIntrinsics(intrinsics_spec, dir_.intrinsics().width, dir_.intrinsics().height);
  }
  std::string describe() const override { return dir_.dir() + " (7-Scenes layout, " + std::to_string(dir_.frameNumbers().size()) + " frames)"; }
  const perception::PinholeIntrinsics& intrinsics() const override { return k_; }
  std::optional<Eigen::Vector3d> gravityDown() const override { return dir_.gravityDown(); }
  const std::vector<int>& frames() const override { return dir_.frameNumbers(); }
  void check(int n) const override {
    std::error_code ec;
    if (!fs::exists(dir_.posePath(n), ec)) throw IoError(dir_.posePath(n), "missing: every frame needs a pose");
  }
  SequenceFrame load(int n) const override {
    SequenceFrame f;
    f.number = n;
    f.depth = dir_.readDepth(n);
    f.T_world_camera.matrix() = dir_.readPose(n);
    f.T_world_camera.linear() = mapping::nearestRotation(f.T_world_camera.linear());
    return f;
  }

 private:
  SevenScenesDirectory dir_;
  perception::PinholeIntrinsics k_;
};

// "timestamp value..." lines; '#' comments. Errors name the file and line.
std::vector<std::pair<double, std::vector<std::string>>> readTimestamped(const std::string& path, std::size_t fields) {
  std::vector<std::pair<double, std::vector<std::string>>> out;
  std::istringstream in(readTextFile(path, 256u << 20));
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream ls(line);
    std::string t_str;
    ls >> t_str;
    std::vector<std::string> rest;
    for (std::string v; ls >> v;) rest.push_back(v);
    const auto t = parseFiniteNumber(t_str);
    if (!t) throw IoError(path, "line " + std::to_string(line_no) + ": '" + t_str + "' is not a timestamp");
    if (rest.size() != fields) {
      throw IoError(path, "line " + std::to_string(line_no) + ": expected " + std::to_string(fields + 1) + " columns, found " +
                              std::to_string(rest.size() + 1));
    }
    out.emplace_back(*t, std::move(rest));
  }
  return out;
}

class TumSequence : public Sequence {
 public:
  TumSequence(const std::string& dir, const std::string& intrinsics_spec, double max_gap) : dir_(dir) {
    const std::string gt_path = (fs::path(dir) / "groundtruth.txt").string();
    std::error_code ec;
    if (!fs::exists(gt_path, ec)) throw IoError(gt_path, "missing: a TUM sequence needs ground-truth poses to build a map");
    int line = 0;
    for (const auto& [t, v] : readTimestamped(gt_path, 7)) {
      ++line;
      double x[7];
      for (int i = 0; i < 7; ++i) {
        const auto value = parseFiniteNumber(v[static_cast<std::size_t>(i)]);
        if (!value) {
          throw IoError(gt_path, "pose " + std::to_string(line) + ": '" + v[static_cast<std::size_t>(i)] + "' is not a finite number");
        }
        x[i] = *value;
      }
      const Eigen::Quaterniond q(x[6], x[3], x[4], x[5]);  // file order qx qy qz qw
      if (std::abs(q.norm() - 1.0) > 1e-3) {
        throw IoError(gt_path, "pose " + std::to_string(line) + ": quaternion norm " + std::to_string(q.norm()) + " is not 1");
      }
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.linear() = q.normalized().toRotationMatrix();
      T.translation() = Eigen::Vector3d(x[0], x[1], x[2]);
      trajectory_.insert(t, T);
    }
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
                 " depth frames have no ground-truth pose within " + std::to_string(max_gap) + " s and were skipped";
    }
    if (entries_.empty()) throw IoError(dir, "no depth frame of depth.txt has a ground-truth pose");
    const Image16 first = readPng16(entries_.front().path);
    k_ = intrinsics_spec.empty() ? perception::PinholeIntrinsics{first.width, first.height, 525.0, 525.0, 319.5, 239.5}
                                 : parseIntrinsics(intrinsics_spec, first.width, first.height);
  }
  std::string describe() const override { return dir_ + " (TUM RGB-D, " + std::to_string(entries_.size()) + " posed frames)"; }
  const perception::PinholeIntrinsics& intrinsics() const override { return k_; }
  std::optional<Eigen::Vector3d> gravityDown() const override { return std::nullopt; }
  const std::vector<int>& frames() const override { return frames_; }
  void check(int n) const override {
    std::error_code ec;
    if (!fs::exists(entries_.at(static_cast<std::size_t>(n)).path, ec)) throw IoError(entries_.at(static_cast<std::size_t>(n)).path, "missing");
  }
  SequenceFrame load(int n) const override {
    const Entry& e = entries_.at(static_cast<std::size_t>(n));
    const Image16 img = readPng16(e.path);
    if (img.width != k_.width || img.height != k_.height) {
      throw IoError(e.path, "depth image is " + std::to_string(img.width) + "x" + std::to_string(img.height) +
                                " but the sequence's images are " + std::to_string(k_.width) + "x" + std::to_string(k_.height));
    }
    SequenceFrame f;
    f.number = n;
    f.depth = perception::DepthImage(img.width, img.height);
    for (std::size_t i = 0; i < img.pixels.size(); ++i) f.depth.depth_m[i] = static_cast<float>(img.pixels[i]) / 5000.f;  // TUM: 5000 per metre
    f.T_world_camera = e.pose;
    return f;
  }
  std::string skipped() const override { return skipped_; }

 private:
  struct Entry {
    double t;
    std::string path;
    Eigen::Isometry3d pose;
  };
  std::string dir_;
  mapping::Trajectory trajectory_;
  std::vector<Entry> entries_;
  std::vector<int> frames_;
  std::string skipped_;
  perception::PinholeIntrinsics k_;
};

}  // namespace

std::unique_ptr<Sequence> openSequence(const std::string& dir, const std::string& intrinsics_spec, double max_pose_gap_s) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw IoError(dir, "not a directory");
  if (fs::exists(fs::path(dir) / "depth.txt", ec)) return std::make_unique<TumSequence>(dir, intrinsics_spec, max_pose_gap_s);
  return std::make_unique<SevenScenesSequence>(dir, intrinsics_spec);
}

}  // namespace mobmap::app
