#pragma once
// The steps of a build that are not the run itself (internal to the builder): frame
// selection, "down" from the floor, and opening a map to extend.

#include "mobmap/builder/map_builder.hpp"
#include "mobmap/gp/mobility_model.hpp"
#include "mobmap/mapping/gravity.hpp"
#include "mobmap/mapping/map_metadata.hpp"
#include "mobmap/mapping/mobility_octree.hpp"
#include "mobmap/perception/pipeline.hpp"
#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/sequence.hpp"

#include <Eigen/Core>

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace mobmap::builder {

using sources::Frame;
using sources::IoError;
using sources::Sequence;

// The error of a frame that cannot be read, when the run stops for it: it says how not to.
IoError withSkipHint(const IoError& e);

perception::FrameResult perceive(const perception::FramePipeline& pipeline, const Sequence& dir, const Frame& f,
                                 const std::optional<Eigen::Vector3f>& gravity_down_camera);

// A frame's floor as a vote for "down" in the world frame: its ground plane's normal
// turned by the camera's rotation r_wc, weighted by the plane's points. None without one.
std::optional<mapping::DownObservation> floorVote(const perception::FrameResult& r, const Eigen::Matrix3d& r_wc);

// Up to 8 posed frames spread over the selection, each perceived by `finder` with the
// camera-frame gravity `down_in_camera(r_wc)` gives: their floors' votes, and the
// rotations of the posed frames sampled. An unreadable frame is skipped with
// `skip_bad_frames` (the run skips it too, and says so), else its error stops the run.
struct FloorSample {
  std::vector<mapping::DownObservation> floors;
  std::vector<Eigen::Matrix3d> rotations;
};
// The sampled depth frames perceived for the run as well, with its ground cone and the
// same gravity hint (FramePipeline::processPerGroundCone shares the stages before the
// ground), by frame number: the run fuses these instead of perceiving them again when
// its gravity is the one the sample was given.
struct PerceivedForRun {
  double ground_cone_deg = 0;
  struct Early {
    perception::FrameResult result;
    Eigen::Vector3f gravity_down_camera;  ///< the hint it was perceived with
  };
  std::map<int, Early> results;
};
FloorSample sampleFloors(const Sequence& dir, const std::vector<int>& frames, const perception::FramePipeline& finder,
                         const std::function<Eigen::Vector3f(const Eigen::Matrix3d&)>& down_in_camera, bool skip_unreadable,
                         PerceivedForRun* for_run = nullptr);

struct GravityGuess {
  Eigen::Vector3d down;
  std::string how;  // for the note and MAP.json
};

// "Down" for a posed sequence that does not give it (no gravity-direction.txt, no
// `gravity`). World frames differ: 7-Scenes and 3DMatch keep the first camera's axes
// (y down), a motion-capture frame has z up. The floor says which: up to 8 frames
// spread over the selection look for a ground plane within 45 degrees of the image's
// up axis (a camera held upright, tilted at most that much), and the floor normals,
// taken to the world frame, vote. Without a floor in view, the cameras' mean +y axis.
GravityGuess estimateGravity(const Sequence& dir, const std::vector<int>& frames, const perception::PerceptionParams& pp,
                             const gp::MobilityModel& model, bool skip_unreadable);

// Gravity is refined to the floor within this cone of the given direction, when the
// two differ by more than kGravityAgreesDeg: closer, the given one is kept (on exact
// synthetic floors the vote of 8 frames lies ~0.15 degrees from the truth; on the real
// kitchen floor normals spread over ~0.5 degrees).
constexpr double kGravityRefineConeDeg = 10.0;
constexpr double kGravityAgreesDeg = 1.0;
// A run of at most this many frames keeps the results of the frames the gravity check
// perceived (8, a few MB each) until it fuses them; a longer run perceives them again,
// the check being then under ~5 % of its time.
constexpr std::size_t kPerceiveForRunFrames = 120;

// The floor near a given "down": up to 8 frames spread over the selection (or the lone
// frame) look for a ground plane within kGravityRefineConeDeg of it; the floor normals,
// in the world frame, vote as in estimateGravity. Nullopt when no floor agreed on.
struct FloorCheck {
  mapping::DownConsensus vote;
  std::size_t sampled = 0;
};
// With `for_run`, the sampled depth frames of `dir` are perceived for the run too.
std::optional<FloorCheck> floorNear(const Eigen::Vector3d& given_down, const Sequence* dir, const std::vector<int>& frames,
                                    const Frame* single, const perception::PerceptionParams& pp,
                                    const gp::MobilityModel& model, bool skip_unreadable,
                                    PerceivedForRun* for_run = nullptr);

// The map that `extend` adds frames to: its tree, its metadata, and the frame it was
// built in (gravity in the input's world frame and the rotation to the map frame).
struct ExistingMap {
  std::unique_ptr<mapping::MobilityOcTree> tree;
  mapping::MapMetadata meta;
  Eigen::Vector3d down_world;
  Eigen::Matrix3d R_map_world;
  Eigen::Vector3d origin_world;
};

ExistingMap openForExtension(const std::string& ot_path);

double angleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

std::string formatVector(const Eigen::Vector3d& v);

// The runs of an extended map that fused frames from the same input in the range
// selected now: (run number from 1, first and last frame it fused). Fusing a frame
// again counts it twice.
struct RunRange {
  std::size_t run = 0;
  long long first = 0, last = 0;
};
std::vector<RunRange> overlappingRuns(const mapping::MapMetadata& earlier, const std::string& input, int first, int last);

}  // namespace mobmap::builder
