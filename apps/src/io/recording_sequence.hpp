#pragma once
// A robot's recording (a ROS 2 bag: folder, .db3 or .mcap; mobmap/sources/recording.hpp)
// as a Sequence: its depth images, numbered in stamp order, posed through its TF tree.

#include "io/sequence.hpp"

#include "mobmap/sources/recording.hpp"

#include <memory>
#include <string>

namespace mobmap::app {

/// Opens `path` (isRecording) as a Sequence; `intrinsics_spec` replaces its camera_info.
std::unique_ptr<Sequence> openRecordingSequence(const std::string& path, const RecordingChoice& choice,
                                                const std::string& intrinsics_spec, double max_pose_gap_s);

}  // namespace mobmap::app
