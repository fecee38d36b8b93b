#pragma once
// The one interface to depth inputs: a sequence of frames (7-Scenes / 3DMatch layout,
// TUM RGB-D, .pcd frames with poses, a robot's recording, OpenNI2 in openni.hpp), where
// a single .png or .pcd file is a sequence of one frame without a pose.

#include "mobmap/perception/camera.hpp"
#include "mobmap/sources/frame.hpp"
#include "mobmap/sources/png.hpp"
#include "mobmap/sources/recording.hpp"

#include <Eigen/Geometry>

#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace mobmap::sources {

/// The topic and frame choices for a robot's recording (empty: the recording's own; see
/// RecordingOptions).
struct RecordingChoice {
  std::string depth_topic;
  std::string camera_info_topic;
  std::string world_frame;
  std::string imu_topic;
};

/// A sequence of depth frames with camera-to-world poses (none for a single file).
/// load() may run on several threads at once.
class Sequence {
 public:
  virtual ~Sequence() = default;
  [[nodiscard]] virtual std::string describe() const = 0;
  /// What kind of input it is: "7-Scenes layout", "TUM RGB-D", ".pcd frames", "depth
  /// PNG", ".pcd file", "OpenNI2", or the recording's format ("ROS 2 bag (MCAP)").
  [[nodiscard]] virtual std::string format() const = 0;
  /// The depth camera; meaningless when hasDepth() is false.
  [[nodiscard]] virtual const perception::PinholeIntrinsics& intrinsics() const = 0;
  /// Whether frames come as depth images (free space can then be projected).
  [[nodiscard]] virtual bool hasDepth() const { return true; }
  [[nodiscard]] virtual std::optional<Eigen::Vector3d> gravityDown() const = 0;
  /// Where gravityDown() comes from, for the user and MAP.json.
  [[nodiscard]] virtual std::string gravitySource() const { return "gravity-direction.txt"; }
  /// Whether its frames come with poses (false for a single file).
  [[nodiscard]] virtual bool posed() const { return true; }
  /// Numbers of the frames that have a pose, ascending.
  [[nodiscard]] virtual const std::vector<int>& frames() const = 0;
  /// Checks cheaply (before a long run) that frame `n` can be loaded; IoError if not.
  virtual void check(int n) const = 0;
  /// Frame `n`: its number, depth image (or cloud) and pose; a single file's frame
  /// comes with everything Frame holds.
  [[nodiscard]] virtual Frame load(int n) const = 0;
  /// Frame `n`'s camera-to-world pose without its depth (the one load() gives), for
  /// sequences that know their poses before the run; nullopt for streams (OpenNI2),
  /// whose poses arrive with their frames.
  [[nodiscard]] virtual std::optional<Eigen::Isometry3d> pose(int /*n*/) const { return std::nullopt; }
  /// Frame `n`'s colour image, pixel for pixel with its depth, when the input has one:
  /// a 7-Scenes / 3DMatch `.color.png` of the depth's size, the TUM `rgb.txt` image
  /// within 0.02 s of the depth (TUM registers colour to depth), an organized .pcd's
  /// rgb. For pictures; load() does not read it. IoError if the file is unreadable.
  [[nodiscard]] virtual std::optional<ImageRgb> colour(int /*n*/) const { return std::nullopt; }
  /// The files frame `n` is read from (its depth image or cloud, its pose file), so a
  /// command that writes files can refuse to write over them.
  [[nodiscard]] virtual std::vector<std::string> files(int /*n*/) const { return {}; }
  /// Frames left out and why ("12 depth frames without a pose within 0.05 s"), or "".
  [[nodiscard]] virtual std::string skipped() const { return {}; }
  /// The unit load() gives depth in, as the input is read: a depth image's values per
  /// metre (1000 for 7-Scenes and OpenNI2, 5000 for TUM), 1 for clouds in metres.
  [[nodiscard]] virtual DepthUnit depthUnit() const { return {}; }
  /// The robot recording it reads (its topics, TF tree and choices), or null.
  [[nodiscard]] virtual const Recording* recording() const { return nullptr; }
};

/// A sequence that hands every call to another: the base of those that change one thing
/// about it (its depth's encoding or unit, its poses) and override what they change.
class ForwardingSequence : public Sequence {
 public:
  explicit ForwardingSequence(std::unique_ptr<Sequence> inner) : inner_(std::move(inner)) {}
  [[nodiscard]] std::string describe() const override { return inner_->describe(); }
  [[nodiscard]] std::string format() const override { return inner_->format(); }
  [[nodiscard]] const perception::PinholeIntrinsics& intrinsics() const override { return inner_->intrinsics(); }
  [[nodiscard]] bool hasDepth() const override { return inner_->hasDepth(); }
  [[nodiscard]] std::optional<Eigen::Vector3d> gravityDown() const override { return inner_->gravityDown(); }
  [[nodiscard]] std::string gravitySource() const override { return inner_->gravitySource(); }
  [[nodiscard]] bool posed() const override { return inner_->posed(); }
  [[nodiscard]] const std::vector<int>& frames() const override { return inner_->frames(); }
  void check(int n) const override { inner_->check(n); }
  [[nodiscard]] Frame load(int n) const override { return inner_->load(n); }
  [[nodiscard]] std::optional<Eigen::Isometry3d> pose(int n) const override { return inner_->pose(n); }
  [[nodiscard]] std::optional<ImageRgb> colour(int n) const override { return inner_->colour(n); }
  [[nodiscard]] std::vector<std::string> files(int n) const override { return inner_->files(n); }
  [[nodiscard]] std::string skipped() const override { return inner_->skipped(); }
  [[nodiscard]] DepthUnit depthUnit() const override { return inner_->depthUnit(); }
  [[nodiscard]] const Recording* recording() const override { return inner_->recording(); }

 protected:
  [[nodiscard]] const Sequence& inner() const { return *inner_; }

 private:
  std::unique_ptr<Sequence> inner_;
};

/// How openSequence reads an input.
struct SequenceOptions {
  /// "fx,fy,cx,cy", "fov:DEGREES" or a camera file (parseIntrinsics): replaces the
  /// input's own intrinsics. Empty: the input's (TUM has none in its files and takes
  /// 525, 525, 319.5, 239.5, its documented default; organized .pcd frames get
  /// intrinsics fitted to their first frame; a lone PNG needs a camera-intrinsics.txt
  /// beside it).
  std::string intrinsics;
  /// Frames whose neighbouring timestamped poses are farther apart in time are skipped.
  double max_pose_gap_s = 0.05;
  /// A TUM trajectory ("t tx ty tz qx qy qz qw"): the poses of .pcd frames, or of a
  /// recording's images (matched by stamp) instead of its TF tree.
  std::string poses;
  RecordingChoice recording;
  /// How 16-bit depth values are encoded beyond their unit (depthFormats()); empty:
  /// plainly, as numbers of units.
  std::string depth_format;
};

/// The depth encodings undoDepthFormat() knows, with what each is: "sunrgbd" (SUN RGB-D's
/// depth PNGs: millimetres rotated left by 3 bits, so most values are multiples of 8).
const std::vector<std::pair<std::string, std::string>>& depthFormats();

/// Undoes `format` (depthFormats()) on `depth` read from 16-bit values at `units_per_m`
/// values per metre: each value is taken back to its 16 bits, decoded, and read at the
/// same unit (0 and 65535 stay "no measurement"). util::FieldError (`depth_format`) for an unknown format.
void undoDepthFormat(perception::DepthImage& depth, double units_per_m, const std::string& format);

/// Opens INPUT: a robot's recording (isRecording: a ROS 2 bag folder, .db3 or .mcap, a
/// ROS 1 .bag), an OpenNI2 .oni file (every frame; load them in order), a TUM RGB-D
/// directory (it has depth.txt), a directory of .pcd frames (these need `poses`), a
/// 7-Scenes / 3DMatch layout directory, a single .pcd (a posed sequence of one with
/// `poses`, else a lone frame whose organized cloud's camera is recovered, see
/// recoverCameraFrame) or a single 16-bit depth .png in millimetres.
/// IoError naming the file and the problem; util::FieldError for an invalid
/// `options.intrinsics`, a PNG without intrinsics, or a depth format for an input whose
/// depth is not 16-bit images (clouds, 32-bit float images).
std::unique_ptr<Sequence> openSequence(const std::string& input, const SequenceOptions& options = {});

/// The recording options `choice` and `max_pose_gap_s` give (topics, world frame, IMU).
RecordingOptions recordingOptions(const RecordingChoice& choice, double max_pose_gap_s);

}  // namespace mobmap::sources
