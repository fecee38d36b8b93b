#include "mobmap/sources/dataset.hpp"

#include "mobmap/mapping/gravity.hpp"
#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/png.hpp"
#include "mobmap/sources/text.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <regex>
#include <sstream>

namespace mobmap::sources {
namespace {

// Parses whitespace-separated numbers, `rows` lines of `cols` numbers (blank lines
// and '#' comments skipped). Errors name the line.
Eigen::MatrixXd readMatrixFile(const std::string& path, int rows, int cols) {
  const std::string text = readTextFile(path, 1 << 20);
  std::istringstream in(text);
  std::string line;
  Eigen::MatrixXd m(rows, cols);
  int row = 0, line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    if (row == rows) throw IoError(path, "line " + std::to_string(line_no) + ": more than " + std::to_string(rows) + " rows");
    std::istringstream ls(line);
    std::string token;
    int col = 0;
    while (ls >> token) {
      if (col == cols) throw IoError(path, "line " + std::to_string(line_no) + ": more than " + std::to_string(cols) + " numbers");
      const auto v = parseFiniteNumber(token);
      if (!v) throw IoError(path, "line " + std::to_string(line_no) + ": '" + token + "' is not a finite number");
      m(row, col++) = *v;
    }
    if (col != cols) {
      throw IoError(path, "line " + std::to_string(line_no) + ": expected " + std::to_string(cols) +
                              " numbers, found " + std::to_string(col));
    }
    ++row;
  }
  if (row != rows) {
    throw IoError(path, "expected " + std::to_string(rows) + " rows of numbers, found " + std::to_string(row));
  }
  return m;
}

}  // namespace

std::string frameStem(int index) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "frame-%06d", index);
  return buf;
}

namespace {

// A camera file in YAML: ROS camera_info (a message dump with K or k, or a calibration
// file with camera_matrix {rows, cols, data}) or OpenCV's FileStorage YAML ("%YAML:1.0",
// camera_matrix: !!opencv-matrix). Returns K row by row and, when the file states it,
// the image size it was calibrated for.
struct YamlCamera {
  Eigen::Matrix3d k;
  std::optional<std::pair<int, int>> size;  // width, height
};

bool looksLikeYaml(const std::string& text) {
  return text.rfind("%YAML", 0) == 0 || text.find("camera_matrix") != std::string::npos ||
         std::regex_search(text, std::regex(R"((^|\n)\s*[Kk]\s*:)"));
}

YamlCamera readYamlCamera(const std::string& path, const std::string& text) {
  // yaml-cpp reads YAML 1.2; OpenCV writes a YAML 1.0 directive ("%YAML:1.0") it refuses.
  std::string body = text;
  if (body.rfind("%YAML:", 0) == 0) body = body.substr(std::min(body.size(), body.find('\n')));
  YAML::Node root;
  try {
    root = YAML::Load(body);
  } catch (const YAML::Exception& e) {
    throw IoError(path, std::string("not valid YAML: ") + e.what());
  }
  if (!root.IsMap()) throw IoError(path, "not a camera file (expected a YAML mapping with K, k or camera_matrix)");
  YAML::Node data;
  std::string key;
  for (const char* name : {"camera_matrix", "K", "k"}) {
    if (root[name]) {
      key = name;
      data = root[name];
      break;
    }
  }
  if (key.empty()) throw IoError(path, "has no camera matrix: expected K (ROS 1 camera_info), k (ROS 2) or camera_matrix");
  if (data.IsMap()) {  // {rows: 3, cols: 3, data: [...]}, OpenCV's with dt
    try {
      if (data["rows"] && data["cols"] && (data["rows"].as<int>() != 3 || data["cols"].as<int>() != 3)) {
        throw IoError(path, "\"" + key + "\" must be 3x3, it is " + data["rows"].as<std::string>() + "x" +
                                data["cols"].as<std::string>());
      }
    } catch (const YAML::Exception&) {
      throw IoError(path, "\"" + key + "\": rows and cols must be whole numbers");
    }
    data = data["data"];
  }
  if (!data || !data.IsSequence() || data.size() != 9) {
    throw IoError(path, "\"" + key + "\" must hold 9 numbers (the 3x3 matrix row by row)");
  }
  YamlCamera cam;
  for (std::size_t i = 0; i < 9; ++i) {
    const auto v = data[i].IsScalar() ? parseFiniteNumber(data[i].Scalar()) : std::nullopt;
    if (!v) throw IoError(path, "\"" + key + "\" entry " + std::to_string(i) + " is not a finite number");
    cam.k(static_cast<int>(i / 3), static_cast<int>(i % 3)) = *v;
  }
  for (const auto& [w, h] : {std::pair<const char*, const char*>{"image_width", "image_height"}, {"width", "height"}}) {
    if (!root[w] || !root[h]) continue;
    // -1: not a number.
    const double wv = root[w].IsScalar() ? parseFiniteNumber(root[w].Scalar()).value_or(-1.0) : -1.0;
    const double hv = root[h].IsScalar() ? parseFiniteNumber(root[h].Scalar()).value_or(-1.0) : -1.0;
    if (wv < 0 || hv < 0 || wv != std::floor(wv) || hv != std::floor(hv) || wv > 1e5 || hv > 1e5) {
      throw IoError(path, std::string("\"") + w + "\" and \"" + h + "\" must be whole numbers of pixels");
    }
    // ROS writes 0 x 0 for a camera_info without a size.
    if (wv > 0 && hv > 0) cam.size = std::make_pair(static_cast<int>(wv), static_cast<int>(hv));
    break;
  }
  return cam;
}

}  // namespace

perception::PinholeIntrinsics readIntrinsicsFile(const std::string& path, int width, int height) {
  const std::string text = readTextFile(path, 1 << 20);
  Eigen::MatrixXd k;
  if (looksLikeYaml(text)) {
    const YamlCamera cam = readYamlCamera(path, text);
    if (cam.size && (cam.size->first != width || cam.size->second != height)) {
      throw IoError(path, "is for " + std::to_string(cam.size->first) + "x" + std::to_string(cam.size->second) +
                              " images, but the depth frames are " + std::to_string(width) + "x" + std::to_string(height) +
                              " (the calibration of another camera or resolution?)");
    }
    k = cam.k;
  } else {
    k = readMatrixFile(path, 3, 3);
  }
  if (k(0, 1) != 0 || k(1, 0) != 0 || k(2, 0) != 0 || k(2, 1) != 0 || k(2, 2) != 1) {
    throw IoError(path, "not a pinhole camera matrix [fx 0 cx; 0 fy cy; 0 0 1]");
  }
  perception::PinholeIntrinsics out{width, height, k(0, 0), k(1, 1), k(0, 2), k(1, 2)};
  try {
    perception::validate(out);
  } catch (const std::invalid_argument& e) {
    throw IoError(path, e.what());
  }
  return out;
}

Eigen::Matrix4d readPoseFile(const std::string& path) {
  const Eigen::Matrix4d t = readMatrixFile(path, 4, 4);
  if (auto problem = mapping::checkRigid(t)) throw IoError(path, "not a rigid transform: " + *problem);
  return t;
}

Eigen::Vector3d readGravityFile(const std::string& path) {
  const std::string text = readTextFile(path, 1 << 16);
  std::istringstream in(text);
  Eigen::Vector3d g;
  for (int i = 0; i < 3; ++i) {
    std::string token;
    if (!(in >> token)) throw IoError(path, "expected 3 numbers, found " + std::to_string(i));
    const auto v = parseFiniteNumber(token);
    if (!v) throw IoError(path, "'" + token + "' is not a finite number");
    g(i) = *v;
  }
  std::string extra;
  if (in >> extra) throw IoError(path, "more than 3 numbers");
  // stableNorm: a plain norm squares the components and overflows to infinity for
  // values above ~1e154, which would normalise a valid direction to zero.
  const double length = g.stableNorm();
  if (length < 1e-9) throw IoError(path, "gravity direction is the zero vector");
  return g / length;
}

perception::DepthImage readDepthPng(const std::string& path) {
  const Image16 img = readPng16(path);
  perception::DepthImage d(img.width, img.height);
  for (std::size_t i = 0; i < img.pixels.size(); ++i) {
    d.depth_m[i] = perception::metresFromMillimetres(img.pixels[i]);
  }
  return d;
}

perception::PinholeIntrinsics intrinsicsFromFov(double horizontal_fov_deg, int width, int height) {
  if (!(horizontal_fov_deg > 1.0 && horizontal_fov_deg < 179.0)) {
    std::ostringstream value;
    value << horizontal_fov_deg;
    throw util::FieldError("intrinsics", "'fov:" + value.str() + "': the horizontal field of view must lie between 1 and 179 degrees");
  }
  const double f = 0.5 * width / std::tan(0.5 * horizontal_fov_deg * M_PI / 180.0);
  perception::PinholeIntrinsics k{width, height, f, f, 0.5 * (width - 1), 0.5 * (height - 1)};
  perception::validate(k);
  return k;
}

perception::PinholeIntrinsics parseIntrinsics(const std::string& spec, int width, int height) {
  if (spec.rfind(kFovSpecPrefix, 0) == 0) {
    const auto fov = parseFiniteNumber(spec.substr(std::string(kFovSpecPrefix).size()));
    if (!fov) throw util::FieldError("intrinsics", "'" + spec + "': the field of view must be a number of degrees");
    return intrinsicsFromFov(*fov, width, height);
  }
  const auto v = splitNumbers(spec);
  if (v.size() == 4) {
    perception::PinholeIntrinsics k{width, height, v[0], v[1], v[2], v[3]};
    try {
      perception::validate(k);
    } catch (const std::invalid_argument& e) {
      throw util::FieldError("intrinsics", "'" + spec + "': " + e.what());
    }
    return k;
  }
  if (!std::filesystem::exists(spec)) {
    throw util::FieldError("intrinsics", "must be fx,fy,cx,cy or a camera file (3x3 matrix text, ROS camera_info or OpenCV "
                                         "YAML); '" + spec + "' is neither");
  }
  return readIntrinsicsFile(spec, width, height);
}

namespace {

// A 7-Scenes depth frame's file name; the match's first group is its number.
const std::regex& depthFramePattern() {
  static const std::regex pattern(R"(frame-(\d{6})\.depth\.png)");
  return pattern;
}

// How many frame-NNNNNN.depth.png files a directory holds.
std::size_t countDepthFrames(const std::filesystem::path& dir) {
  std::error_code ec;
  std::size_t n = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    n += std::regex_match(entry.path().filename().string(), depthFramePattern());
  }
  return n;
}

}  // namespace

SevenScenesDirectory::SevenScenesDirectory(std::string dir, const std::string& intrinsics_spec) : dir_(std::move(dir)) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(dir_, ec)) throw IoError(dir_, "not a directory");
  for (const auto& entry : fs::directory_iterator(dir_, ec)) {
    std::smatch m;
    const std::string name = entry.path().filename().string();
    if (std::regex_match(name, m, depthFramePattern())) frames_.push_back(std::stoi(m[1]));
  }
  if (ec) throw IoError(dir_, "cannot list: " + ec.message());
  if (frames_.empty()) {
    // 7-Scenes and 3DMatch keep each sequence in its own folder (seq-01, ...): name them.
    std::vector<std::pair<std::string, std::size_t>> sequences;  // folder name, frames
    for (const auto& entry : fs::directory_iterator(dir_, ec)) {
      if (!entry.is_directory(ec)) continue;
      const std::size_t n = countDepthFrames(entry.path());
      if (n > 0) sequences.emplace_back(entry.path().filename().string(), n);
    }
    std::sort(sequences.begin(), sequences.end());
    if (!sequences.empty()) {
      std::string list;
      for (std::size_t i = 0; i < sequences.size() && i < 6; ++i) {
        const auto& [name, n] = sequences[i];
        list += (i ? ", " : "") + name + " (" + std::to_string(n) + (n == 1 ? " frame)" : " frames)");
      }
      if (sequences.size() > 6) list += ", ...";
      throw IoError(dir_, "no frame-NNNNNN.depth.png files here, but these sub-folders have them: " + list +
                              "; pass one sequence folder, such as " + (fs::path(dir_) / sequences.front().first).string());
    }
    throw IoError(dir_, "no frame-NNNNNN.depth.png files (not a 7-Scenes layout directory; for one depth image, "
                        "pass the .png itself)");
  }
  std::sort(frames_.begin(), frames_.end());
  const Image16 first = readPng16(depthPath(frames_.front()));
  if (!intrinsics_spec.empty()) {
    intrinsics_ = parseIntrinsics(intrinsics_spec, first.width, first.height);
  } else {
    std::string kpath = (fs::path(dir_) / "camera-intrinsics.txt").string();
    if (!fs::exists(kpath, ec)) {
      const std::string parent = (fs::absolute(dir_, ec).parent_path() / "camera-intrinsics.txt").string();
      if (!fs::exists(parent, ec)) {
        throw IoError(dir_, "no camera-intrinsics.txt here or in the parent directory: give `intrinsics` "
                            "fx,fy,cx,cy (Microsoft's 7-Scenes Kinect: 585,585,320,240)");
      }
      kpath = parent;
    }
    intrinsics_ = readIntrinsicsFile(kpath, first.width, first.height);
  }
  const std::string gpath = (fs::path(dir_) / "gravity-direction.txt").string();
  if (fs::exists(gpath, ec)) gravity_ = readGravityFile(gpath);
}

std::string SevenScenesDirectory::depthPath(int frame) const {
  return (std::filesystem::path(dir_) / (frameStem(frame) + ".depth.png")).string();
}
std::string SevenScenesDirectory::posePath(int frame) const {
  return (std::filesystem::path(dir_) / (frameStem(frame) + ".pose.txt")).string();
}
std::optional<ImageRgb> SevenScenesDirectory::readColour(int frame) const {
  const std::filesystem::path path = std::filesystem::path(dir_) / (frameStem(frame) + ".color.png");
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return std::nullopt;
  ImageRgb c = readPngRgb(path.string());
  if (c.width != intrinsics_.width || c.height != intrinsics_.height) return std::nullopt;
  return c;
}
std::string SevenScenesDirectory::labelsPath(int frame) const {
  return (std::filesystem::path(dir_) / (frameStem(frame) + ".labels.png")).string();
}

perception::DepthImage SevenScenesDirectory::readDepth(int frame) const {
  const std::string path = depthPath(frame);
  perception::DepthImage d = readDepthPng(path);
  if (d.width != intrinsics_.width || d.height != intrinsics_.height) {
    throw IoError(path, "depth image is " + std::to_string(d.width) + "x" + std::to_string(d.height) +
                            " but the sequence's images are " + std::to_string(intrinsics_.width) + "x" +
                            std::to_string(intrinsics_.height));
  }
  return d;
}

Eigen::Matrix4d SevenScenesDirectory::readPose(int frame) const { return readPoseFile(posePath(frame)); }

}  // namespace mobmap::sources
