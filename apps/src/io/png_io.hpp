#pragma once
// PNG writing (libpng), for depth, label and colour images; reading is the library's
// (mobmap/sources/png.hpp).

#include "mobmap/sources/png.hpp"

#include <string>

namespace mobmap::app {

using sources::checkPngComplete;
using sources::Image16;
using sources::ImageRgb;
using sources::kMaxFramePixels;
using sources::kMaxFrameSide;
using sources::readPng16;
using sources::readPngRgb;

/// Writes atomically (temporary file + rename).
void writePng16(const std::string& path, const Image16& image);
void writePngRgb(const std::string& path, const ImageRgb& image);

}  // namespace mobmap::app
