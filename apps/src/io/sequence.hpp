#pragma once
// The one interface to depth inputs: a sequence of frames (7-Scenes / 3DMatch layout,
// TUM RGB-D, .pcd frames with poses, OpenNI2 in openni_source.hpp), where a single .png
// or .pcd file is a sequence of one frame without a pose.

#include "io/depth_checks.hpp"
#include "io/frame.hpp"
#include "io/png_io.hpp"

#include "mobmap/perception/camera.hpp"
#include "mobmap/sources/recording.hpp"

#include <Eigen/Geometry>

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace mobmap::app {

/// The topic and frame choices for a robot's recording, as the command line gives them
/// (empty: the recording's own).
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
  [[nodiscard]] virtual const sources::Recording* recording() const { return nullptr; }
};

/// `f`'s depth (or cloud coordinates, and the camera offset of a cloud in another frame)
/// multiplied by `factor`: read at `units_per_m` instead (depthRescaleFactor gives the
/// factor).
void scaleFrame(Frame& f, float factor, double units_per_m);

/// `seq` with its depth read at `units_per_m` instead of its own unit (depth and cloud
/// coordinates multiplied by own / units_per_m; poses unchanged). `seq` itself when the
/// two agree.
std::unique_ptr<Sequence> withDepthScale(std::unique_ptr<Sequence> seq, double units_per_m);

/// Opens INPUT: a TUM RGB-D directory (it has depth.txt), a directory of .pcd frames
/// (these need `poses_path`), a 7-Scenes layout directory, a single .pcd (a posed
/// sequence of one with `poses_path`, else a lone frame whose organized cloud's camera
/// is recovered, see recoverCameraFrame) or a single 16-bit depth .png in millimetres
/// (its intrinsics from `intrinsics_spec` or a camera-intrinsics.txt beside it).
/// `intrinsics_spec` (fx,fy,cx,cy or a file) overrides the sequence's own; TUM has
/// none in its files and defaults to 525, 525, 319.5, 239.5 (its documented default);
/// organized .pcd frames get intrinsics fitted to their first frame.
/// `max_pose_gap_s`: frames whose neighbouring timestamped poses are farther apart in
/// time are skipped.
/// A ROS 2 bag (sources::isRecording) is opened with `choice` (recording_sequence.hpp).
std::unique_ptr<Sequence> openSequence(const std::string& input, const std::string& intrinsics_spec,
                                       double max_pose_gap_s, const std::string& poses_path = "",
                                       const RecordingChoice& choice = {});

}  // namespace mobmap::app
