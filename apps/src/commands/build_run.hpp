#pragma once
// `mobmap build`'s run as an object: its steps (open the input, settle gravity, place the
// map, run the frames through a LiveMapper with checkpoints, save, summarise) are its
// methods, and what the run knows is its members. build.cpp holds the steps before the
// frames, build_run.cpp the run and what follows it.
#include "commands/build_steps.hpp"
#include "commands/progress.hpp"
#include "io/config.hpp"
#include "io/depth_checks.hpp"
#include "io/frame_source.hpp"
#include "io/sequence.hpp"

#include "mobmap/mapping/live_mapper.hpp"
#include "mobmap/mapping/map_lock.hpp"
#include "mobmap/mapping/map_metadata.hpp"
#include "mobmap/mapping/mobility_map.hpp"
#include "mobmap/perception/pipeline.hpp"

#include <Eigen/Geometry>

#include <array>
#include <atomic>
#include <chrono>
#include <csignal>
#include <exception>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

namespace mobmap::app::build {

// Ctrl-C, SIGTERM (a service manager, `kill`) and SIGHUP (a closed terminal or SSH
// session) all end the run the same way: the frames fused so far are saved, and the exit
// code is 128 + the signal's number (130, 143, 129).
inline std::atomic<bool> g_interrupted{false};
inline std::atomic<int> g_signal{0};
inline constexpr int kStopSignals[] = {SIGINT, SIGTERM, SIGHUP};
inline int interruptedCode() { return 128 + (g_signal.load() ? g_signal.load() : SIGINT); }

class BuildRun {
 public:
  BuildRun(BuildOptions& options, const LiveHooks* run_hooks) : o(&options), given(options.given), hooks(run_hooks) {}
  BuildRun(const BuildRun&) = delete;
  BuildRun& operator=(const BuildRun&) = delete;
  /// The whole run; the exit code (0, or 128 + a stop signal's number).
  int execute();

 private:
  // The steps, in order.
  void prepare();        // options, the map's lock and paths, the configuration
  void openInput();      // the sequence or single frame, the frames selected and checked
  void settleGravity();  // given, checked against the floor, estimated; a lone frame perceived
  void placeMap();       // origin, the run's counters and progress line
  void runFrames();      // read, perceive and fuse every frame; checkpoints
  int finish();          // refuse a map that hides a mistake, save, summarise

  // Within the steps.
  void noteUnreadable(const std::string& what);  // a frame left out (--skip-bad-frames)
  [[nodiscard]] int done() const { return used + no_pose + unreadable_in_run + outside_frames; }
  void showProgress(std::size_t nodes) { progress->update(done(), "map " + std::to_string(nodes) + " nodes"); }
  [[nodiscard]] bool checkpointDue() const;
  void holdIfAsked();
  // The map files: all written, then renamed into place, MAP.ot first, MAP.json last. A
  // checkpoint (--checkpoint) writes the same files in the middle of the run; fusion then
  // goes on in the finalized (pruned) tree, which gives the same map as without
  // (docs/MAPPING.md).
  mapping::MapMetadata writeMap(const mapping::MobilityMap& map, bool checkpoint, double run_s);

  BuildOptions* const o;
  const BuildOptions::Given& given;  // which options were given
  const LiveHooks* const hooks;
  std::error_code ec;

  // prepare()
  std::optional<mapping::MapLock> map_lock;  // one writer per map for the whole run
  std::string stem;
  std::array<std::string, 4> map_paths;
  Config config;
  perception::PerceptionParams& pp = config.perception;
  mapping::MapParams& mp = config.mapping;
  std::optional<ExistingMap> existing;
  gp::MobilityModel model;
  std::optional<perception::FramePipeline> pipeline;

  // openInput()
  std::unique_ptr<Sequence> dir;
  std::vector<int> frames;
  int keyframes_considered = 0;  // frames selected before --keyframes (0: not used)
  std::optional<Eigen::Vector3d> gravity_world;
  Frame single;
  bool live = false, oni = false, bag = false, is_dir = false;
  // Frames left out as unreadable (--skip-bad-frames): "FILE: problem", in the order found.
  std::vector<std::string> unreadable;
  std::size_t unreadable_before_run = 0;  // left out of `frames` by the checks before the run
  std::optional<Eigen::Isometry3d> T_base_camera;  // --extrinsics, read once

  // settleGravity()
  std::string gravity_source;
  std::optional<Eigen::Vector3d> gravity_given;
  std::optional<double> gravity_floor_angle;
  PerceivedForRun perceived_for_run;
  std::chrono::steady_clock::time_point run_start;
  Eigen::Isometry3d T_world_single = Eigen::Isometry3d::Identity();
  std::optional<perception::FrameResult> single_result;
  Eigen::Vector3d g_world = Eigen::Vector3d(0, 0, -1);
  Eigen::Matrix3d R_map_world = Eigen::Matrix3d::Identity();

  // placeMap(), and what the run has done so far. Frames are read by runFrames(),
  // perceived and fused by the LiveMapper's threads; its callbacks (the fusion thread)
  // and the reading thread both count, so the counts, the progress line and the camera
  // path are shared under `state`.
  std::optional<Eigen::Vector3d> origin_world;
  std::string origin_source;
  const perception::PinholeIntrinsics* depth_k = nullptr;
  int stop_after_frames = -1;
  std::mutex state;
  std::optional<Progress> progress;
  std::vector<std::pair<std::string, double>> stage_ms;  // in pipeline order
  std::size_t points = 0;
  int used = 0, no_ground = 0, no_pose = 0;
  // Points beyond the map's extent (a pose far from the origin, poses in another unit):
  // counted and reported, never dropped silently. A frame with no point inside adds
  // nothing and is not counted as fused.
  int outside_frames = 0, outside_warnings = 0;
  std::size_t points_outside = 0;
  std::size_t map_nodes = 0;  // after the last frame fused
  int frames_before = 0;      // frames the map held before this run (--extend)
  int unreadable_in_run = 0;  // frames skipped as unreadable after the run started
  int last_fused = 0;         // frame number of the last frame fused
  std::vector<Eigen::Vector3d> trajectory;  // camera positions, map frame
  double read_ms = 0, fuse_ms = 0;
  struct Pushed {
    int number;
    Eigen::Isometry3d T_world_camera;
    std::optional<LowZeroBits> bits;  // of its stored depth values, for the unit check
  };
  std::vector<Pushed> pushed;  // by LiveMapper's frame index
  std::string device_label;
  DepthCheckTally depth_checks;  // under `state`, as the rest the callbacks update
  DepthUnit depth_unit;

  // runFrames()
  std::exception_ptr checkpoint_error;
  mapping::LiveMapper* mapper_ptr = nullptr;
  std::shared_ptr<const mapping::MobilityMap> final_map;
};

}  // namespace mobmap::app::build
