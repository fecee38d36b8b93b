#pragma once
// Timestamped text files: TUM trajectories ("t tx ty tz qx qy qz qw"), TUM frame lists
// ("t file"), and time stamps in frame file names.

#include <Eigen/Geometry>

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace mobmap::sources {

/// "timestamp value..." lines with exactly `fields` values after the time stamp; blank
/// lines and '#' comments are skipped. IoError naming the file and line otherwise.
std::vector<std::pair<double, std::vector<std::string>>> readTimestamped(const std::string& path, std::size_t fields);

/// A TUM trajectory file, "t tx ty tz qx qy qz qw" per line ('#' comments): the
/// camera-to-world poses with their timestamps. IoError naming the file and line for
/// a missing column, a non-number or a quaternion whose norm is not 1 (+- 1e-3).
std::vector<std::pair<double, Eigen::Isometry3d>> readTumPoses(const std::string& path);

/// The timestamp in a frame's file name, in seconds: an ISO basic date-time such as
/// frame_20121214T142255.814212.pcd (UTC) or a trailing number such as
/// 1305031102.175304.pcd. nullopt when there is none.
std::optional<double> timestampFromFileName(const std::string& path);

}  // namespace mobmap::sources
