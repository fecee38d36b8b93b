#pragma once
// One frame of any input (a single file is a sequence of one frame), loaded for the
// pipeline, and what is done with a frame before and after it: the builder's lone
// frames, `mobmap analyze`'s frame.

#include "mobmap/sources/frame.hpp"
#include "mobmap/sources/sequence.hpp"

#include "mobmap/perception/camera.hpp"
#include "mobmap/perception/pipeline.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace mobmap::builder {

using sources::Frame;
using sources::RecordingChoice;
using sources::Sequence;

/// The frame's results taken to the frame of the input's points: the cloud's when
/// T_cloud_camera is set (points, normals, segment centroids and normals, ground
/// plane); unchanged otherwise. Slopes, roughness and mobility do not change.
void toInputFrame(perception::FrameResult& r, const Frame& f);

/// Decodes `f`'s 16-bit depth values as `format` says (`depth_format`,
/// sources::undoDepthFormat). util::FieldError naming `input` when its depth is not 16-bit
/// values (a cloud, 32-bit floats).
void decodeDepthFormat(Frame& f, const std::string& format, const std::string& input);

/// Runs `pipeline` on a loaded frame: its depth image, else its cloud (organized when
/// it has more than one row).
perception::FrameResult perceiveFrame(const perception::FramePipeline& pipeline, const Frame& f,
                                      const std::optional<Eigen::Vector3f>& gravity_down_camera);

/// For a frame perceived without gravity, a note for the user on how its ground was
/// chosen, or empty: when the largest plane leaned away from the image's up axis and a
/// floor within `upright_prior_deg` of it was taken instead (the camera assumed
/// upright), and when the ground is the largest plane and more than 45 degrees from
/// that axis: "may be a wall" when a surface within 30 degrees of that axis (the floor of
/// an upright camera) is in view too; nothing when none is and surfaces parallel to the
/// plane lie at other heights (levels seen from above: treads, a floor); else that it is
/// a floor seen from above or a wall. `analyze` and `build` both take `--gravity`.
std::string groundChoiceNote(const perception::FrameResult& r, double upright_prior_deg);

/// Where the ground plane of a frame lay: how much of the frame it holds and how far
/// from the camera (a far floor gives a less certain gravity: depth noise grows with
/// the square of the range).
struct GroundExtent {
  std::size_t points = 0;        ///< the ground segment's points
  std::size_t frame_points = 0;  ///< the frame's points after reduction
  double area_m2 = 0;            ///< its triangulated area
  double near_m = 0, median_m = 0, far_m = 0;  ///< 5th, 50th and 95th percentile of its points' distances
};
/// nullopt when the frame has no ground segment.
std::optional<GroundExtent> groundExtent(const perception::FrameResult& r);
/// "4.2 m2, 61 % of the frame's points, 90 % of them 1.9-4.6 m from the camera".
std::string describeGround(const GroundExtent& g);
/// A ground whose nearest 5 % lie at least this far away is far: `build` says so when
/// gravity comes from it.
constexpr double kFarGroundM = 1.5;

/// Parses "X,Y,Z" (non-zero, finite), a direction: returned as a unit vector. Throws
/// util::ValueError naming `what`.
Eigen::Vector3f parseVector3(const std::string& spec, const std::string& what);

/// Frame `frame` of `seq` (opened from `input`, which errors name): its depth, pose,
/// intrinsics and colour image. IoError naming the frames there are if `seq` has no
/// frame with that number.
Frame loadSequenceFrame(const Sequence& seq, const std::string& input, int frame);

/// Loads INPUT as `mobmap analyze` describes it. `frame` picks the frame of a
/// directory (-1: the first one), numbered as `build` numbers them. `intrinsics_spec`
/// is required for a PNG unless a camera-intrinsics.txt lies beside it (then `note`
/// says it was used).
/// A robot's recording (a ROS 2 bag) is read with `choice`; its frame N is its depth
/// image N in stamp order.
Frame loadSingleFrame(const std::string& input, int frame, const std::string& intrinsics_spec,
                      const RecordingChoice& choice = {});

}  // namespace mobmap::builder
