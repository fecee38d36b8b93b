// mobmap's PCD adapter (libmobmap_pcd.so, opened on demand: pcd_adapter.hpp): .pcd files
// read with PCL, their headers checked against hostile values first. Only this adapter
// links PCL (and through it VTK and Boost).
#include "pcd_adapter.hpp"

#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/png.hpp"

#include <pcl/console/print.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

namespace mobmap::sources {

namespace {

struct PcdHeader {
  pcl::PCLPointCloud2 fields;  // fields, width, height, point_step; no data
  int data_type = 0;           // 0 ascii, 1 binary, 2 binary_compressed
  unsigned int data_offset = 0;
  bool has_rgb = false;
};

// PCL's header reader allocates the declared size (points x bytes per point) before it
// reads a byte of data, so the header is read here first: WIDTH, HEIGHT and POINTS are
// held to the frame-size limit, SIZE x COUNT per point to kMaxPointBytes, and the data
// the header promises to what the file can hold (a COUNT of 10^9 asked for gigabytes).
constexpr unsigned long long kMaxPointBytes = 4096;  // a VFH descriptor is 1,232

void checkDeclaredPointCount(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  unsigned long long width = 1, height = 1, points = 0;
  std::vector<unsigned long long> sizes, counts;
  std::string data;
  const auto number = [&](const std::string& key, const std::string& value) {
    if (value.empty() || value.find_first_not_of("0123456789") != std::string::npos || value.size() > 15) {
      throw IoError(path, "PCD header's " + key + " '" + value + "' is not a whole number below 10^15");
    }
    return std::stoull(value);
  };
  for (int lines = 0; lines < 64 && std::getline(in, line); ++lines) {
    std::istringstream words(line);
    std::string key, value;
    words >> key;
    if (key == "DATA") {
      words >> data;
      break;
    }
    if (key == "SIZE" || key == "COUNT") {
      auto& list = key == "SIZE" ? sizes : counts;
      while (words >> value) list.push_back(number(key, value));
      continue;
    }
    if (key != "WIDTH" && key != "HEIGHT" && key != "POINTS") continue;
    words >> value;
    (key == "WIDTH" ? width : key == "HEIGHT" ? height : points) = number(key, value);
  }
  const unsigned long long declared = std::max(points, width * height);
  if (declared > static_cast<unsigned long long>(kMaxFramePixels)) {
    throw IoError(path, "PCD header declares " + std::to_string(declared) + " points (WIDTH " + std::to_string(width) +
                            ", HEIGHT " + std::to_string(height) + "), more than mobmap reads in one frame (" +
                            std::to_string(kMaxFramePixels) + ")");
  }
  unsigned long long point_bytes = 0, values = 0;
  for (std::size_t i = 0; i < sizes.size(); ++i) {
    const unsigned long long count = i < counts.size() ? counts[i] : 1;
    if (sizes[i] > 8 || count > kMaxPointBytes) {
      throw IoError(path, "PCD header declares field " + std::to_string(i + 1) + " of SIZE " + std::to_string(sizes[i]) +
                              " and COUNT " + std::to_string(count) + "; a point of depth data is a few numbers");
    }
    point_bytes += sizes[i] * count;
    values += std::max(1ULL, count);
  }
  if (point_bytes > kMaxPointBytes) {
    throw IoError(path, "PCD header declares " + std::to_string(point_bytes) + " bytes per point, more than the " +
                            std::to_string(kMaxPointBytes) + " mobmap reads (a point of depth data is a few numbers)");
  }
  // The data the header promises must fit the file: binary data is all there, ASCII data
  // needs at least two bytes ("0 ") per value, and compressed data can hold at most 88
  // times its size (the sizes in its block are checked once PCL has found where it starts).
  const std::streamoff data_at = in ? static_cast<std::streamoff>(in.tellg()) : -1;
  std::error_code ec;
  const auto size = static_cast<unsigned long long>(std::filesystem::file_size(path, ec));
  if (ec || data_at < 0) return;  // PCL's reader says what is wrong
  const unsigned long long start = static_cast<unsigned long long>(data_at);
  const unsigned long long bytes = size > start ? size - start : 0;
  const unsigned long long cells = width * height;
  if (data == "binary" && bytes < cells * point_bytes) {
    throw IoError(path, "PCD data is shorter than its header declares (" + std::to_string(size) + " bytes, " +
                            std::to_string(start + cells * point_bytes) + " needed)");
  }
  // LZF, PCL's compression, turns at most 264 bytes into 3.
  if (data == "binary_compressed" && cells * point_bytes > 88 * bytes) {
    throw IoError(path, "PCD header declares " + std::to_string(cells) + " points of " + std::to_string(point_bytes) +
                            " bytes, more than its " + std::to_string(bytes) + " bytes of compressed data can hold");
  }
  if (data == "ascii" && cells * values * 2 > bytes) {
    throw IoError(path, "PCD header declares " + std::to_string(cells) + " points of " + std::to_string(values) +
                            " values, but its " + std::to_string(bytes) + " bytes of ASCII data hold at most " +
                            std::to_string(bytes / (2 * std::max<unsigned long long>(1, values))) + " (corrupt or truncated file)");
  }
}

// The header of a .pcd, which must exist and have x, y and z; IoError if not.
PcdHeader readPcdHeader(const std::string& path) {
  if (!std::filesystem::exists(path)) throw IoError(path, "no such file");
  checkDeclaredPointCount(path);
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);  // errors come back as codes; we word them
  pcl::PCDReader reader;
  PcdHeader h;
  Eigen::Vector4f origin;
  Eigen::Quaternionf orientation;
  int version = 0;
  if (reader.readHeader(path, h.fields, origin, orientation, version, h.data_type, h.data_offset) < 0) {
    throw IoError(path, "not a readable PCD file (bad header)");
  }
  bool has_x = false, has_y = false, has_z = false;
  for (const auto& f : h.fields.fields) {
    has_x |= f.name == "x";
    has_y |= f.name == "y";
    has_z |= f.name == "z";
    h.has_rgb |= f.name == "rgb" || f.name == "rgba";
  }
  if (!(has_x && has_y && has_z)) throw IoError(path, "PCD has no x, y and z fields");
  return h;
}

}  // namespace

namespace {

// binary_compressed data must be what the header declares, checked before PCL
// decompresses it (checkDeclaredPointCount has held the rest to the file already).
void checkPcdDeclaredSize(const std::string& path, const PcdHeader& h) {
  if (h.data_type != 2) return;
  const unsigned long long points = static_cast<unsigned long long>(h.fields.width) * h.fields.height;
  std::error_code ec;
  const auto size = static_cast<unsigned long long>(std::filesystem::file_size(path, ec));
  if (ec) throw IoError(path, "cannot read its size: " + ec.message());
  const unsigned long long start = h.data_offset;
  const unsigned long long data = size > start ? size - start : 0;
  const unsigned long long declared = points * h.fields.point_step;
  // Two little-endian 32-bit sizes (compressed, uncompressed), then the compressed bytes.
  std::ifstream in(path, std::ios::binary);
  unsigned char sizes[8] = {};
  if (!in.seekg(static_cast<std::streamoff>(start)) || !in.read(reinterpret_cast<char*>(sizes), 8)) {
    throw IoError(path, "PCD data is corrupt or shorter than its header declares (no compressed block sizes)");
  }
  const auto le32 = [&](int at) {
    return static_cast<unsigned long long>(sizes[at]) | static_cast<unsigned long long>(sizes[at + 1]) << 8 |
           static_cast<unsigned long long>(sizes[at + 2]) << 16 | static_cast<unsigned long long>(sizes[at + 3]) << 24;
  };
  const unsigned long long compressed = le32(0), uncompressed = le32(4);
  if (data < 8 + compressed) {
    throw IoError(path, "PCD data is shorter than its header declares (" + std::to_string(size) + " bytes, " +
                            std::to_string(start + 8 + compressed) + " needed)");
  }
  if (uncompressed != declared) {
    throw IoError(path, "PCD compressed data says it holds " + std::to_string(uncompressed) + " bytes, but " +
                            std::to_string(points) + " points of " + std::to_string(h.fields.point_step) + " bytes are " +
                            std::to_string(declared) + " (corrupt file)");
  }
}

const pcl::PCLPointField* findField(const pcl::PCLPointCloud2& c, const std::string& name) {
  for (const auto& f : c.fields) {
    if (f.name == name) return &f;
  }
  return nullptr;
}

}  // namespace

// PcdAdapter::check.
void checkPcdHeaderAndSize(const std::string& path) {
  const PcdHeader h = readPcdHeader(path);  // the declared size within the frame limit
  if (h.data_type == 0) return;  // ASCII: only loading it tells whether the points are all there
  checkPcdDeclaredSize(path, h);
}

// PcdAdapter::load.
Frame loadPcdCloud(const std::string& path) {
  const PcdHeader h = readPcdHeader(path);
  checkPcdDeclaredSize(path, h);
  pcl::PCDReader reader;
  pcl::PCLPointCloud2 cloud;
  Eigen::Vector4f origin;
  Eigen::Quaternionf orientation;
  int version = 0;
  if (reader.read(path, cloud, origin, orientation, version) < 0) throw IoError(path, "PCD data is corrupt or shorter than its header declares");
  // x, y and z as the file stores them: 4- or 8-byte floats (PCL writes both; its
  // conversion to float points leaves 8-byte fields at zero).
  const pcl::PCLPointField* axes[3] = {findField(cloud, "x"), findField(cloud, "y"), findField(cloud, "z")};
  for (const auto* f : axes) {
    if (f->datatype != pcl::PCLPointField::FLOAT32 && f->datatype != pcl::PCLPointField::FLOAT64) {
      throw IoError(path, "PCD field " + f->name + " is not a 4- or 8-byte float (TYPE F, SIZE 4 or 8); mobmap reads "
                          "coordinates in metres as floats");
    }
    const std::size_t bytes = f->datatype == pcl::PCLPointField::FLOAT64 ? 8 : 4;
    if (f->offset + bytes > cloud.point_step) throw IoError(path, "PCD field " + f->name + " lies outside its point (corrupt header)");
  }
  const std::size_t n = static_cast<std::size_t>(cloud.width) * cloud.height;
  if (cloud.data.size() < n * cloud.point_step) throw IoError(path, "PCD data is corrupt or shorter than its header declares");
  const pcl::PCLPointField* rgb = findField(cloud, "rgb");
  if (!rgb) rgb = findField(cloud, "rgba");
  if (rgb && (rgb->datatype == pcl::PCLPointField::FLOAT64 || rgb->datatype == pcl::PCLPointField::INT8 ||
              rgb->datatype == pcl::PCLPointField::UINT8 || rgb->datatype == pcl::PCLPointField::INT16 ||
              rgb->datatype == pcl::PCLPointField::UINT16 || rgb->offset + 4 > cloud.point_step)) {
    rgb = nullptr;  // not a packed colour: drawn without it
  }
  const auto coordinate = [](const std::uint8_t* p, const pcl::PCLPointField& f) {
    if (f.datatype == pcl::PCLPointField::FLOAT64) {
      double v;
      std::memcpy(&v, p + f.offset, 8);
      return static_cast<float>(v);
    }
    float v;
    std::memcpy(&v, p + f.offset, 4);
    return v;
  };
  Frame f;
  f.points.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* p = cloud.data.data() + i * cloud.point_step;
    f.points.emplace_back(coordinate(p, *axes[0]), coordinate(p, *axes[1]), coordinate(p, *axes[2]));
  }
  f.width = static_cast<int>(cloud.width);
  f.height = static_cast<int>(cloud.height);
  f.depth_unit = {1.0, true};  // PCD coordinates are metres
  if (rgb && cloud.height > 1) {
    ImageRgb c{f.width, f.height, {}};
    c.pixels.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
      std::uint32_t v;
      std::memcpy(&v, cloud.data.data() + i * cloud.point_step + rgb->offset, 4);
      c.pixels.push_back({static_cast<std::uint8_t>(v >> 16), static_cast<std::uint8_t>(v >> 8), static_cast<std::uint8_t>(v)});
    }
    f.colour = std::move(c);
  }
  f.sources = {path};
  std::ostringstream d;
  d << path << " (" << (cloud.height > 1 ? "organized " : "unorganized ") << cloud.width << "x" << cloud.height << ")";
  f.description = d.str();
  return f;
}

const PcdAdapter kAdapter{kPcdAdapterVersion, &loadPcdCloud, &checkPcdHeaderAndSize};

}  // namespace mobmap::sources

extern "C" const mobmap::sources::PcdAdapter* mobmap_pcd_adapter() { return &mobmap::sources::kAdapter; }
