#pragma once
// PNG (libpng) for depth and colour images: read from files and from memory (a bag's
// compressed depth), written to memory (the apps write the bytes to files atomically).

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace mobmap::sources {

/// The largest frame mobmap reads, checked before anything is allocated: at most this
/// many pixels a side, and at most kMaxFramePixels pixels (a depth PNG) or points (a
/// .pcd) in all: 4096 x 4096, 14x a 1280 x 720 RealSense frame.
inline constexpr int kMaxFrameSide = 16384;
inline constexpr long long kMaxFramePixels = 1LL << 24;

/// A 16-bit single-channel image, row-major.
struct Image16 {
  int width = 0;
  int height = 0;
  std::vector<std::uint16_t> pixels;
};

/// An 8-bit RGB image, row-major.
struct ImageRgb {
  int width = 0;
  int height = 0;
  std::vector<std::array<std::uint8_t, 3>> pixels;
};

/// Reads a 16-bit greyscale PNG. IoError (with the path) if the file is missing,
/// not a PNG, corrupt or truncated, not 16-bit greyscale, or larger than kMaxFrameSide a
/// side or kMaxFramePixels in all.
Image16 readPng16(const std::string& path);
/// Reads any 8-bit PNG (grey, RGB, RGBA, palette) as RGB.
ImageRgb readPngRgb(const std::string& path);

/// Checks cheaply, without decoding, that a PNG file opens, has the PNG signature and
/// ends with its IEND chunk (a file cut short by a recorder that was killed does not):
/// `build` checks every frame this way before a long run. IoError (with the path) if not.
void checkPngComplete(const std::string& path);

/// Decodes a 16-bit greyscale PNG held in memory; IoError naming `what` (a file and the
/// message in it) on the problems readPng16 reports.
Image16 decodePng16(const std::uint8_t* data, std::size_t size, const std::string& what);

/// The PNG file's bytes of an image (compression level 3: depth images favour speed).
/// std::invalid_argument when its pixels do not match its size or a side is not in
/// 1..kMaxFrameSide.
std::vector<std::uint8_t> encodePng16(const Image16& image);
std::vector<std::uint8_t> encodePngRgb(const ImageRgb& image);

}  // namespace mobmap::sources
