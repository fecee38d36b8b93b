#pragma once
// Posed depth sequences for `mobmap build`: the 7-Scenes / 3DMatch layout and TUM RGB-D.

#include "mobmap/perception/camera.hpp"

#include <Eigen/Geometry>

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace mobmap::app {

struct SequenceFrame {
  int number = 0;
  perception::DepthImage depth;
  Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();
};

/// A sequence of depth frames with camera-to-world poses. load() may run on several
/// threads at once.
class Sequence {
 public:
  virtual ~Sequence() = default;
  [[nodiscard]] virtual std::string describe() const = 0;
  [[nodiscard]] virtual const perception::PinholeIntrinsics& intrinsics() const = 0;
  [[nodiscard]] virtual std::optional<Eigen::Vector3d> gravityDown() const = 0;
  /// Numbers of the frames that have a pose, ascending.
  [[nodiscard]] virtual const std::vector<int>& frames() const = 0;
  /// Checks cheaply (before a long run) that frame `n` can be loaded; IoError if not.
  virtual void check(int n) const = 0;
  [[nodiscard]] virtual SequenceFrame load(int n) const = 0;
  /// Frames left out and why ("12 depth frames without a pose within 0.05 s"), or "".
  [[nodiscard]] virtual std::string skipped() const { return {}; }
};

/// Opens a directory: TUM RGB-D if it has depth.txt, else the 7-Scenes layout.
/// `intrinsics_spec` (fx,fy,cx,cy or a file) overrides the sequence's own; TUM has
/// none in its files and defaults to 525, 525, 319.5, 239.5 (its documented default).
/// `max_pose_gap_s`: TUM frames whose neighbouring ground-truth poses are farther
/// apart in time are skipped.
std::unique_ptr<Sequence> openSequence(const std::string& dir, const std::string& intrinsics_spec,
                                       double max_pose_gap_s);

}  // namespace mobmap::app
