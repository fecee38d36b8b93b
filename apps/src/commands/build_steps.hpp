#pragma once
// The parts of `mobmap build` that are not the run itself (internal to the commands):
// frame selection, "down" from the floor, and opening a map to extend.

#include "io/sequence.hpp"
#include "io/io_error.hpp"
#include "io/sequence.hpp"

#include "mobmap/gp/mobility_model.hpp"
#include "mobmap/mapping/gravity.hpp"
#include "mobmap/mapping/live_mapper.hpp"
#include "mobmap/mapping/map_metadata.hpp"
#include "mobmap/mapping/mobility_octree.hpp"
#include "mobmap/perception/pipeline.hpp"

#include <Eigen/Core>

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace CLI {
class App;
class Option;
}  // namespace CLI

namespace mobmap::app::build {

/// The options of `mobmap build` (build --help describes them).
struct BuildOptions {
  std::string input;
  std::string out;
  std::string frames;
  double max_range = 3.0;
  double depth_scale = 0;
  std::string depth_format;
  double resolution = 0.02;
  double voxel = 0;
  std::string gravity;
  std::string gravity_refine = "on";
  std::vector<double> origin;
  bool force = false;
  bool extend = false;
  int checkpoint = 0;
  std::vector<double> keyframes;  // metres, degrees
  bool quiet = false;
  bool no_free_space = false;
  bool skip_bad_frames = false;
  std::string config;
  std::string intrinsics;
  double fov = 0;
  double max_pose_gap = 0.05;
  std::string poses;
  std::string device;
  RecordingChoice recording;  // a robot recording's topics and world frame
  std::string extrinsics;     // the camera's pose in the posed frame
  /// The options whose presence (not only value) matters, as CLI11 registered them.
  struct Given {
    CLI::Option* max_range = nullptr;
    CLI::Option* resolution = nullptr;
    CLI::Option* device = nullptr;
    CLI::Option* voxel = nullptr;
    CLI::Option* keyframes = nullptr;
    CLI::Option* origin = nullptr;
    CLI::Option* depth_scale = nullptr;
    CLI::Option* fov = nullptr;
    CLI::Option* out = nullptr;
  } given;
};

/// The help of build's INPUT (serve --live takes the same inputs).
inline constexpr const char* kBuildInputHelp =
    "A 7-Scenes / 3DMatch layout directory (frame-NNNNNN.depth.png + .pose.txt), a TUM RGB-D directory "
    "(depth.txt + groundtruth.txt), a directory of .pcd frames with --poses, one .pcd frame, one 16-bit "
    "depth .png in millimetres (with --intrinsics or a camera-intrinsics.txt beside it), an OpenNI2 .oni recording, "
    "a ROS 2 bag (its folder, a .db3 or an .mcap file) or a ROS 1 .bag, posed through its TF tree (a crashed "
    "recorder's folder without metadata.yaml, .db3 with its -wal, or .bag.active is read as far as it goes)";

/// Registers `build` and its options on `app`; the options are filled when it parses.
std::shared_ptr<BuildOptions> addBuildOptions(CLI::App& app);
/// Registers the options of a build run other than INPUT on `cmd` (which registers INPUT
/// its own way): `serve --live` builds with them.
void addBuildRunOptions(CLI::App& cmd, BuildOptions& o);

/// What a caller of runBuild() adds to the run (`mobmap serve --live`). The callbacks
/// run on the thread named; none may throw.
struct LiveHooks {
  /// The mapper exists and serves snapshots (LiveMapper::Config::serve_snapshots), before
  /// the first frame is read; `frames_in_map` counts those of a map being extended. The
  /// reading thread.
  std::function<void(const mapping::LiveMapper& mapper, int frames_in_map)> started;
  /// After each frame fused: the map with it, the frames in it and the camera's position
  /// (map frame). The fusion thread.
  std::function<void(std::shared_ptr<const mapping::MobilityMap> map, int frames_in_map, const Eigen::Vector3d& camera_map)>
      fused;
  /// Before each frame is read. The reading thread.
  std::function<void()> before_frame;
  /// The map as saved (finalized) and what its MAP.json says, once its files are written.
  /// The reading thread.
  std::function<void(std::shared_ptr<const mapping::MobilityMap> map, const mapping::MapMetadata& meta)> saved;
};

/// Runs `mobmap build` with the options parsed into `o`; returns its exit code (130
/// after Ctrl-C, 143 after SIGTERM, 129 after SIGHUP, with the map saved). `hooks` may be null.
int runBuild(BuildOptions& o, const LiveHooks* hooks);


// The error of a frame that cannot be read, when the run stops for it: it says how not to.
IoError withSkipHint(const IoError& e);

struct FrameRange {
  int first = 0, last = -1, step = 1;
};

FrameRange parseRange(const std::string& spec);

perception::FrameResult perceive(const perception::FramePipeline& pipeline, const Sequence& dir, const Frame& f,
                                 const std::optional<Eigen::Vector3f>& gravity_down_camera);

// A frame's floor as a vote for "down" in the world frame: its ground plane's normal
// turned by the camera's rotation r_wc, weighted by the plane's points. None without one.
std::optional<mapping::DownObservation> floorVote(const perception::FrameResult& r, const Eigen::Matrix3d& r_wc);

// Up to 8 posed frames spread over the selection, each perceived by `finder` with the
// camera-frame gravity `down_in_camera(r_wc)` gives: their floors' votes, and the
// rotations of the posed frames sampled. An unreadable frame is skipped with
// --skip-bad-frames (the run skips it too, and says so), else its error stops the run.
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
// --gravity). World frames differ: 7-Scenes and 3DMatch keep the first camera's axes
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

// The map that --extend adds frames to: its tree, its metadata, and the frame it was
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

}  // namespace mobmap::app::build
