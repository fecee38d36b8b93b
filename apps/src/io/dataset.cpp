#include "io/dataset.hpp"

#include "io/files.hpp"
#include "io/png_io.hpp"

#include <cmath>
#include <iomanip>
#include <sstream>

namespace mobmap::app {
namespace {

std::string formatRows(const Eigen::MatrixXd& m) {
  std::ostringstream out;
  out << std::scientific << std::setprecision(18);
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    for (Eigen::Index c = 0; c < m.cols(); ++c) out << (c ? " " : "") << m(r, c);
    out << '\n';
  }
  return out.str();
}

}  // namespace

void writeIntrinsicsFile(const std::string& path, const perception::PinholeIntrinsics& k) {
  Eigen::Matrix3d m;
  m << k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1;
  writeTextFileAtomically(path, formatRows(m));
}

void writePoseFile(const std::string& path, const Eigen::Matrix4d& t) {
  writeTextFileAtomically(path, formatRows(t));
}

void writeGravityFile(const std::string& path, const Eigen::Vector3d& g) {
  writeTextFileAtomically(path, formatRows(g));
}

void writeDepthPng(const std::string& path, const perception::DepthImage& depth) {
  Image16 img;
  img.width = depth.width;
  img.height = depth.height;
  img.pixels.resize(depth.depth_m.size());
  for (std::size_t i = 0; i < depth.depth_m.size(); ++i) {
    const double mm = std::round(static_cast<double>(depth.depth_m[i]) * 1000.0);
    img.pixels[i] = (depth.depth_m[i] > 0 && mm < 65535.0) ? static_cast<std::uint16_t>(mm) : 0;
  }
  writePng16(path, img);
}

}  // namespace mobmap::app
