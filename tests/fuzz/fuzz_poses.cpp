// libFuzzer target: arbitrary bytes as each kind of pose and camera file mobmap reads
// (TUM trajectory, 7-Scenes 4x4 pose, gravity direction, 3x3 intrinsics) and as a frame
// file name with a time stamp. Each must parse into sound values or be rejected with
// IoError; never crash, hang or return a non-rigid pose.
#include "scratch_file.hpp"

#include "mobmap/sources/dataset.hpp"
#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/trajectory_files.hpp"

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>

namespace {

void require(bool ok) {
  if (!ok) std::abort();  // libFuzzer reports the input
}

bool rotationIsSound(const Eigen::Matrix3d& r) {
  return r.allFinite() && (r.transpose() * r - Eigen::Matrix3d::Identity()).norm() < 1e-6 && r.determinant() > 0;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const mobmap::fuzz::ScratchFile scratch("poses.txt");
  const std::string& path = scratch.write(data, size);
  using mobmap::sources::IoError;
  try {
    for (const auto& [t, T] : mobmap::sources::readTumPoses(path)) {
      require(std::isfinite(t) && T.translation().allFinite() && rotationIsSound(T.linear()));
    }
  } catch (const IoError&) {
  }
  try {
    const Eigen::Matrix4d T = mobmap::sources::readPoseFile(path);
    require(T.allFinite());
  } catch (const IoError&) {
  }
  try {
    const Eigen::Vector3d g = mobmap::sources::readGravityFile(path);
    require(g.allFinite() && std::abs(g.norm() - 1.0) < 1e-9);
  } catch (const IoError&) {
  }
  try {
    const auto k = mobmap::sources::readIntrinsicsFile(path, 640, 480);
    require(std::isfinite(k.fx) && k.fx > 0 && std::isfinite(k.fy) && k.fy > 0 && std::isfinite(k.cx) && std::isfinite(k.cy));
  } catch (const IoError&) {
  }
  const std::string name(reinterpret_cast<const char*>(data), std::min<std::size_t>(size, 256));
  if (const auto t = mobmap::sources::timestampFromFileName(name)) require(std::isfinite(*t));
  return 0;
}
