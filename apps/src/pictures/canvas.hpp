#pragma once
// An RGB drawing surface for the tool's pictures (plots, overlays, top views), with
// a built-in 5x7 bitmap font so no font library is needed.

#include "io/png_io.hpp"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace mobmap::app {

using Rgb = std::array<std::uint8_t, 3>;

/// Mobility colour: red at 0, yellow at 0.5, green at 1 (the paper's figures), as
/// mapping::mobilityRgb() and so the octovis export; grey (128) for a non-finite value.
Rgb mobilityColour(double mobility);

class Canvas {
 public:
  Canvas(int width, int height, Rgb background = {255, 255, 255});
  [[nodiscard]] int width() const { return image_.width; }
  [[nodiscard]] int height() const { return image_.height; }
  void set(int x, int y, Rgb c);  ///< ignores points outside
  [[nodiscard]] Rgb get(int x, int y) const;
  void fillRect(int x0, int y0, int x1, int y1, Rgb c);  ///< inclusive corners
  void rect(int x0, int y0, int x1, int y1, Rgb c);      ///< outline
  void line(int x0, int y0, int x1, int y1, Rgb c);
  /// Text with the top-left corner at (x, y); `scale` multiplies the 5x7 glyphs.
  /// Letters are drawn upper-case; characters without a glyph are drawn as '?'.
  void text(int x, int y, const std::string& s, Rgb c, int scale = 1);
  [[nodiscard]] static int textWidth(const std::string& s, int scale = 1) {
    return static_cast<int>(s.size()) * 6 * scale;
  }
  [[nodiscard]] const ImageRgb& image() const { return image_; }
  void save(const std::string& path) const { writePngRgb(path, image_); }

 private:
  ImageRgb image_;
};

/// A colour's grey (luma, BT.601 weights).
[[nodiscard]] Rgb greyOf(Rgb c);

/// A frame as the background of a picture drawn over it: its colour image in grey
/// (greyOf) when it has one of width x height, else its depth (metres, row-major,
/// 0 = nothing measured) shaded grey, nearer lighter (250 - 40 z, kept within 40..240),
/// black where 0. Grey either way, so that the only colours in the picture are the
/// mobility colours laid over it: a red cabinet, a green carpet or a sensor's fill
/// colour where it measured nothing cannot be read as a mobility.
[[nodiscard]] Canvas framePicture(int width, int height, const ImageRgb* colour, const std::vector<float>& depth_m);

/// Lays a mobility colour over pixel (x, y): 2 parts picture to 3 parts paint, so the
/// picture shows through.
void paintOver(Canvas& c, int x, int y, Rgb paint);

}  // namespace mobmap::app
