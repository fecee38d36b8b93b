#pragma once
// A robot's recording (a ROS 2 bag: folder, .db3 or .mcap; mobmap/sources/recording.hpp)
// as a Sequence: its depth images, numbered in stamp order, posed through its TF tree.

#include "io/sequence.hpp"

#include "mobmap/sources/recording.hpp"

#include <memory>
#include <string>

namespace mobmap::app {

/// The library's options for `choice`: its topics, world frame and IMU, and the pose gap.
sources::RecordingOptions recordingOptions(const RecordingChoice& choice, double max_pose_gap_s);

/// Opens `path` (isRecording) as a Sequence; `intrinsics_spec` replaces its camera_info,
/// `poses_path` (a TUM trajectory, matched to the images' stamps) its TF tree.
std::unique_ptr<Sequence> openRecordingSequence(const std::string& path, const RecordingChoice& choice,
                                                const std::string& intrinsics_spec, double max_pose_gap_s,
                                                const std::string& poses_path = "");

}  // namespace mobmap::app
