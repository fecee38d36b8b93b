#pragma once
// OpenNI2 inputs: a live depth sensor or an .oni recording as a Sequence, read through
// OpenNI2 (Debian's libopenni2), and recording a sensor to an .oni file.

#include "mobmap/sources/sequence.hpp"

#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

namespace mobmap::sources {

struct OpenNiOptions {
  /// A device URI, "" for the first attached sensor, or (with is_file) an .oni path.
  std::string uri;
  bool is_file = false;
  std::string intrinsics_spec;  ///< overrides the intrinsics derived from the field of view
  /// Optional TUM trajectory matched to the stream's frame time stamps (seconds of
  /// the device clock); without one the camera is static (world = first camera frame).
  std::string poses_path;
  double max_pose_gap_s = 0.05;
  /// Frames to use: numbers count the depth frames as they arrive (0, 1, ...).
  int first = 0;
  int last = -1;  ///< -1: to the end of a recording; a live sensor then stops after 300
  int step = 1;
  double frame_timeout_s = 5.0;  ///< a live sensor that sends nothing this long is an error
  /// Live sensors: asked every 100 ms while waiting for a frame; once it returns true,
  /// load() throws StreamInterrupted instead of waiting on (Ctrl-C on a silent sensor).
  std::function<bool()> interrupted;
};

/// Thrown by a live sensor's load() when OpenNiOptions::interrupted said stop.
class StreamInterrupted : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Opens the sensor or recording; IoError naming it when there is no device, it cannot
/// be opened, has no depth stream, an unsupported pixel format, no field of view (and no
/// `intrinsics_spec`), or (recordings) lacks what OpenNI2's player needs to play it.
/// load() must be called in the order of frames(); frames without a pose within the gap
/// come back with has_pose false.
std::unique_ptr<Sequence> openOpenNi(const OpenNiOptions& options);

/// Records `frames` depth frames of a sensor into an .oni file (written to a temporary
/// name, then renamed). Returns the number of frames in the file.
int recordOni(const std::string& device_uri, const std::string& out_path, int frames, double frame_timeout_s,
              const std::function<bool()>& interrupted);

}  // namespace mobmap::sources
