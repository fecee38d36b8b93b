#pragma once
// A robot's recording (mobmap/sources/recording.hpp) as a Sequence: its depth images,
// numbered in stamp order, posed through its TF tree.

#include "mobmap/sources/sequence.hpp"

#include <memory>
#include <string>

namespace mobmap::sources {

/// Opens `path` (isRecording) as a Sequence with `options.recording`'s choices;
/// `options.intrinsics` replaces its camera_info, `options.poses` (a TUM trajectory,
/// matched to the images' stamps) its TF tree.
std::unique_ptr<Sequence> openRecordingSequence(const std::string& path, const SequenceOptions& options);

}  // namespace mobmap::sources
