#pragma once
// Cairo, in the adapter libmobmap_cairo.so (cairo_render.cpp) that picture.cpp opens when
// the first picture measures a text or is written (util/plugin.hpp): a command that draws
// no picture never loads Cairo and the ~15 libraries it brings (fontconfig, FreeType,
// pixman, X11's).
//
// A Picture is a list of drawing operations; the adapter measures text for it and draws
// the list into pixels, SVG or PDF.

#include "io/png_io.hpp"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace mobmap::app {

/// Changes whenever CairoAdapter or DrawOp does.
inline constexpr int kCairoAdapterVersion = 1;

/// One drawing operation, in picture units (y down).
struct DrawOp {
  enum Kind : std::uint8_t {
    kFill,      ///< `points` (x, y pairs) as a closed polygon, filled
    kStroke,    ///< `points` as a line `width` wide, round joins and caps; closed if `closed`
    kSegments,  ///< `points` as separate segments (x0 y0 x1 y1 each), square caps
    kCircle,    ///< `points` = centre x, y and radius, stroked `width` wide
    kImage,     ///< images[`image`] stretched over `points` = x, y, w, h, without smoothing
    kText,      ///< `text` with the top of its box at `points` = x, y, font `size` (`bold`)
  };
  Kind kind = kFill;
  std::array<std::uint8_t, 3> colour{0, 0, 0};
  double width = 1, size = 12;
  bool closed = false, bold = false;
  std::size_t image = 0;
  std::vector<double> points;
  std::string text;
};

struct DrawList {
  int width = 0, height = 0;
  std::vector<DrawOp> ops;
  std::vector<ImageRgb> images;
};

/// What a text takes at a font size: its advance width, the font's ascent and descent.
struct TextMetrics {
  double width = 0, ascent = 0, descent = 0;
};

struct CairoAdapter {
  int version;
  TextMetrics (*measure)(const std::string& text, double size, bool bold);
  /// The list drawn into pixels (width x height).
  ImageRgb (*raster)(const DrawList& list);
  /// The list as an SVG (`pdf` false) or PDF document; std::runtime_error if Cairo fails.
  std::string (*document)(const DrawList& list, bool pdf);
};

}  // namespace mobmap::app

extern "C" const mobmap::app::CairoAdapter* mobmap_cairo_adapter();
