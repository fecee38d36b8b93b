#pragma once
// `mobmap info RECORDING`: a robot's recording described (its topics, its TF tree) with
// what `build` would choose from it.

#include "io/sequence.hpp"

#include <string>

namespace mobmap::app {

/// Prints the description of the recording at `path` (a table, or one JSON object);
/// returns the exit code: 0, also when build could not choose its frames (the reason is
/// printed), since the recording itself was read.
int describeRecording(const std::string& path, const RecordingChoice& choice, double max_pose_gap_s, bool json);

}  // namespace mobmap::app
