#pragma once
// The `mobmap` subcommands. Each registers its options on the CLI11 app and returns
// the function that runs it (exit code).

#include "io/files.hpp"
#include "io/io_error.hpp"
#include "io/sequence.hpp"

#include <CLI/CLI.hpp>

#include <functional>
#include <cstdio>
#include <string>
#include <vector>

namespace mobmap::app {

using Command = std::function<int()>;

/// `--voxel` of analyze and build.
inline constexpr const char* kVoxelHelp =
    "Perception voxel size, metres (default: perception.voxel_size_m, 0.01 as in the paper). The point counts and "
    "sample spacings of the configuration are rescaled to keep their physical sizes (docs/PERCEPTION.md, \"Coarser "
    "voxels\"). 0.02 makes perception ~3x faster, but texture at the 10 cm scale then reads less rough and small surfaces blur";

/// `--intrinsics` of analyze and build.
inline constexpr const char* kIntrinsicsHelp =
    "fx,fy,cx,cy or a camera file: a 3x3 matrix as text (camera-intrinsics.txt), ROS camera_info YAML (K, k or "
    "camera_matrix) or OpenCV calibration YAML (default: a 7-Scenes / 3DMatch directory's camera-intrinsics.txt, or "
    "its parent's; for a PNG, the camera-intrinsics.txt beside it; TUM 525,525,319.5,239.5). Needed for Microsoft's "
    "7-Scenes download, which has no such file: 585,585,320,240";

/// `--depth-scale` of analyze and build.
inline constexpr const char* kDepthScaleHelp =
    "Depth values per metre of the input (default: its own: 1000 for 7-Scenes, 3DMatch, PNG and OpenNI2 millimetres, "
    "5000 for TUM, 1 for PCD metres). A warning suggests it when the depths read implausibly for a depth camera: "
    "10000 for tenths of a millimetre, 1000 for a PCD in millimetres";

/// `--depth-format` of analyze and build.
inline constexpr const char* kDepthFormatHelp =
    "How the input's 16-bit depth values are encoded beyond their unit: sunrgbd for SUN RGB-D's depth PNGs "
    "(millimetres rotated left by 3 bits: most values are multiples of 8; a warning suggests it)";

/// `--fov` of analyze and build.
inline constexpr const char* kFovHelp =
    "For a camera whose calibration is unknown: its horizontal field of view in degrees (fx = fy from it, the principal "
    "point at the image centre; Kinect v1 about 57, Kinect v2 about 70, RealSense D435 depth about 87)";

/// "fov:DEGREES", the intrinsics spec `--fov` stands for (parseIntrinsics); UsageError
/// naming --fov unless it lies between 1 and 179 degrees.
inline std::string fovSpec(double degrees) {
  char text[64];
  if (!(degrees > 1.0 && degrees < 179.0)) {
    std::snprintf(text, sizeof text, "%g", degrees);
    throw UsageError(std::string("--fov must be a horizontal field of view between 1 and 179 degrees, got ") + text);
  }
  std::snprintf(text, sizeof text, "fov:%.17g", degrees);
  return text;
}

/// The options that choose what a robot's recording (a ROS 1 or ROS 2 bag) is read for
/// (build, serve --live, analyze, overlay, info): its depth and camera_info topics, the TF
/// frame its poses are in, the IMU that gives gravity.
inline void addRecordingOptions(CLI::App& cmd, RecordingChoice& choice) {
  cmd.add_option("--depth-topic", choice.depth_topic,
                 "A bag: the depth image topic to read (default: its only depth topic, 16UC1 / 32FC1 "
                 "sensor_msgs/Image or compressedDepth; several are an error listing them)");
  cmd.add_option("--camera-info-topic", choice.camera_info_topic,
                 "A bag: the camera_info giving the depth camera's intrinsics (default: the one in the depth "
                 "topic's namespace; --intrinsics replaces it)");
  cmd.add_option("--world-frame", choice.world_frame,
                 "A bag: the TF frame the camera poses are in (default: map if the TF tree has it, else odom, else the "
                 "root of the camera's tree; gravity is map's and odom's -z, REP 105)");
  cmd.add_option("--imu-topic", choice.imu_topic,
                 "A bag: the sensor_msgs/Imu topic whose accelerometer, while the robot is still, gives gravity "
                 "through the TF tree (default: the only Imu topic when the world frame is neither map nor odom)");
}

/// `--extrinsics` of build and overlay.
inline constexpr const char* kExtrinsicsHelp =
    "The camera's pose in the frame the poses are given for (a robot's base from odometry, a motion-capture body): "
    "x,y,z,qx,qy,qz,qw, or a YAML file (rtabmap's local_transform, translation + rotation, or data: 12 or 16 values). "
    "Each camera pose is then the pose times it. For sequences of files; a bag's TF tree has its camera's mounting";

/// `--background` of overlay and analyze --overlay.
inline constexpr const char* kBackgroundHelp =
    "What the mobility colours are laid over, shown in grey: colour (the frame's colour image when the input has one "
    "of the depth's size, else shaded depth) or depth (shaded depth: for colour images not registered to the depth, "
    "such as the .color.png frames of Microsoft's 7-Scenes download)";

/// For options that take a length or a time: a finite number >= 0. (CLI::NonNegativeNumber
/// lets "nan" through, which then compares false with every bound.)
inline CLI::Validator finiteNonNegative() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        const auto v = parseFiniteNumber(text);
        return v && *v >= 0 ? std::string() : "must be a finite number >= 0, got '" + text + "'";
      },
      "NUMBER>=0");
}

/// Parses `args` (a subcommand and its options) with `app` and runs it, as if typed;
/// `demo` uses it to run `build`. Defined in main.cpp, which owns the command table.
int runSubcommand(CLI::App& app, const std::vector<std::string>& args);

Command addSimulateCommand(CLI::App& app);
Command addScoreCommand(CLI::App& app);
Command addDemoCommand(CLI::App& app);
Command addAnalyzeCommand(CLI::App& app);
Command addBuildCommand(CLI::App& app);
Command addQueryCommand(CLI::App& app);
Command addReachCommand(CLI::App& app);
Command addPlanCommand(CLI::App& app);
Command addInfoCommand(CLI::App& app);
Command addServeCommand(CLI::App& app);
Command addEvaluateCommand(CLI::App& app);
Command addExportCommand(CLI::App& app);
Command addOverlayCommand(CLI::App& app);
Command addConfigCommand(CLI::App& app);
Command addRecordCommand(CLI::App& app);

}  // namespace mobmap::app
