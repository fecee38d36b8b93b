#include "depth_decode.hpp"

#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/png.hpp"

#include <cmath>
#include <cstring>

namespace mobmap::sources {
namespace {

std::string trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t");
  if (a == std::string::npos) return {};
  return s.substr(a, s.find_last_not_of(" \t") - a + 1);
}

void checkSize(std::uint64_t width, std::uint64_t height, const std::string& what) {
  if (width == 0 || height == 0 || width > static_cast<std::uint64_t>(kMaxFrameSide) ||
      height > static_cast<std::uint64_t>(kMaxFrameSide) || width * height > static_cast<std::uint64_t>(kMaxFramePixels)) {
    throw IoError(what, "the image is " + std::to_string(width) + "x" + std::to_string(height) +
                            " pixels (mobmap reads 1 to " + std::to_string(kMaxFrameSide) + " a side, " +
                            std::to_string(kMaxFramePixels) + " in all)");
  }
}

float fromMetres(float m) { return std::isfinite(m) && m > 0.f ? m : 0.f; }

}  // namespace

bool isDepthEncoding(const std::string& encoding) { return encoding == "16UC1" || encoding == "32FC1"; }

std::string compressedDepthEncoding(const std::string& format) {
  const auto semi = format.find(';');
  if (semi == std::string::npos) return {};
  const std::string rest = trim(format.substr(semi + 1));
  if (rest.rfind("compressedDepth", 0) != 0) return {};
  return trim(format.substr(0, semi));
}

perception::DepthImage depthFromImage(const ros::Image& m, const std::string& what) {
  if (!isDepthEncoding(m.encoding)) {
    throw IoError(what, "its encoding is \"" + m.encoding + "\", not depth (mobmap reads 16UC1 millimetres and 32FC1 metres)");
  }
  if (m.big_endian) throw IoError(what, "its pixels are big-endian (is_bigendian is set); mobmap reads little-endian depth");
  checkSize(m.width, m.height, what);
  const std::size_t bpp = m.encoding == "16UC1" ? 2 : 4;
  const std::uint64_t row = static_cast<std::uint64_t>(m.width) * bpp;
  if (m.step < row) {
    throw IoError(what, "its step is " + std::to_string(m.step) + " bytes, less than a row of " + std::to_string(m.width) +
                            " " + m.encoding + " pixels (" + std::to_string(row) + ")");
  }
  if (static_cast<std::uint64_t>(m.step) * m.height != m.data_size) {
    throw IoError(what, "it holds " + std::to_string(m.data_size) + " bytes, not the " + std::to_string(m.height) +
                            " rows of " + std::to_string(m.step) + " its step and height make");
  }
  perception::DepthImage d(static_cast<int>(m.width), static_cast<int>(m.height));
  for (std::uint32_t v = 0; v < m.height; ++v) {
    const std::uint8_t* r = m.data + static_cast<std::size_t>(v) * m.step;
    float* out = d.depth_m.data() + static_cast<std::size_t>(v) * m.width;
    for (std::uint32_t u = 0; u < m.width; ++u) {
      if (bpp == 2) {
        out[u] = perception::metresFromMillimetres(static_cast<std::uint16_t>(r[2 * u] | (r[2 * u + 1] << 8)));
      } else {
        float x;
        std::memcpy(&x, r + 4 * static_cast<std::size_t>(u), 4);
        out[u] = fromMetres(x);
      }
    }
  }
  return d;
}

perception::DepthImage depthFromCompressed(const ros::CompressedImage& m, const std::string& what) {
  const std::string encoding = compressedDepthEncoding(m.format);
  if (encoding.empty()) throw IoError(what, "its format \"" + m.format + "\" is not compressedDepth (a colour image is not depth)");
  if (!isDepthEncoding(encoding)) {
    throw IoError(what, "its compressedDepth encoding is \"" + encoding + "\", not depth (mobmap reads 16UC1 and 32FC1)");
  }
  if (m.format.find("rvl") != std::string::npos) throw IoError(what, "its compressedDepth codec is RVL; mobmap reads the PNG codec");
  // image_transport's header: the format (int32), then the two inverse-depth
  // quantisation parameters (float32), little-endian.
  constexpr std::size_t kHeader = 12;
  if (m.data_size <= kHeader) throw IoError(what, "its data is too short for compressedDepth's 12-byte header");
  float quant[2];
  std::memcpy(quant, m.data + 4, 8);
  const Image16 png = decodePng16(m.data + kHeader, m.data_size - kHeader, what);
  checkSize(static_cast<std::uint64_t>(png.width), static_cast<std::uint64_t>(png.height), what);
  perception::DepthImage d(png.width, png.height);
  for (std::size_t i = 0; i < png.pixels.size(); ++i) {
    const std::uint16_t v = png.pixels[i];
    if (encoding == "16UC1") {
      d.depth_m[i] = perception::metresFromMillimetres(v);
    } else {
      // PNG value = A / depth + B, 0 where invalid.
      d.depth_m[i] = v == 0 ? 0.f : fromMetres(quant[0] / (static_cast<float>(v) - quant[1]));
    }
  }
  return d;
}

}  // namespace mobmap::sources
