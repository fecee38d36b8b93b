#pragma once
// `mobmap build`'s options, and the run they describe (mobmap::builder::buildMap with the
// command line's output): shared with `serve --live`, which builds with the same options.

#include "io/sequence.hpp"

#include "mobmap/builder/map_builder.hpp"

#include <memory>
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
  std::string surface_ply;
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

/// What a caller of runBuild() adds to the run (`mobmap serve --live`): its started,
/// fused, before_frame and saved callbacks (the command line's own handle the rest).
using LiveHooks = builder::BuildHooks;

/// Runs `mobmap build` with the options parsed into `o`: prints what the run says and its
/// summary; returns its exit code (130 after Ctrl-C, 143 after SIGTERM, 129 after SIGHUP,
/// with the map saved). `hooks` may be null.
int runBuild(BuildOptions& o, const LiveHooks* hooks);

/// The library's options for the command line's.
builder::BuildOptions toLibrary(const BuildOptions& o);

}  // namespace mobmap::app::build
