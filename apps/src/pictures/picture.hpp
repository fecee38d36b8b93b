#pragma once
// The tool's pictures (top views, level views, frame overlays, the mobility plot), drawn
// with Cairo: anti-aliased lines and fills, text in a real font, and the same drawing
// saved as PNG, SVG or PDF. Every text drawn is recorded with its box, and a label that
// would cover one drawn before it is moved or left out, so no two texts overlap.

#include "io/png_io.hpp"
#include "pictures/cairo_adapter.hpp"

#include "mobmap/mapping/mobility_map.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace mobmap::app {

using Rgb = std::array<std::uint8_t, 3>;
using mapping::ColourScale;

/// A mobility's colour on `scale` (mapping::mobilityRgb); the unknown colour for NaN.
[[nodiscard]] inline Rgb mobilityColour(double mobility, ColourScale scale = ColourScale::kViridis) {
  return mapping::mobilityRgb(mobility, scale);
}
/// The colour of a surface without a mobility estimate on `scale`.
[[nodiscard]] inline Rgb unknownColour(ColourScale scale = ColourScale::kViridis) { return mapping::unknownRgb(scale); }

/// An axis-aligned box in picture units (pixels of the PNG; points in SVG and PDF), y down.
struct Box {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  [[nodiscard]] bool intersects(const Box& o) const { return x0 < o.x1 && o.x0 < x1 && y0 < o.y1 && o.y0 < y1; }
  [[nodiscard]] bool inside(const Box& o) const { return x0 >= o.x0 && y0 >= o.y0 && x1 <= o.x1 && y1 <= o.y1; }
};

/// A text drawn in a picture, with the box it covers.
struct PlacedText {
  std::string text;
  Box box;
};

/// The format a picture is written in, from its path's extension: ".png", ".svg" or ".pdf"
/// (any case). UsageError naming the path for any other.
enum class PictureFormat { kPng, kSvg, kPdf };
PictureFormat pictureFormat(const std::string& path);

class Picture {
 public:
  /// A white (or `background`) picture of width x height units (1 to 32767 each;
  /// std::invalid_argument otherwise).
  Picture(int width, int height, Rgb background = {255, 255, 255});

  [[nodiscard]] int width() const { return list_.width; }
  [[nodiscard]] int height() const { return list_.height; }

  /// An RGB image with its top-left corner at (x, y), each pixel a square of `scale`
  /// units, drawn without smoothing (cells stay sharp when enlarged).
  void image(const ImageRgb& image, double x, double y, double scale);
  /// The same image stretched over the box w x h.
  void image(const ImageRgb& image, double x, double y, double w, double h);
  void fillRect(double x, double y, double w, double h, Rgb c);
  /// An outline `line_width` wide centred on the rectangle's edges.
  void strokeRect(double x, double y, double w, double h, Rgb c, double line_width = 1);
  /// A line through `points` (closed back to the first when `closed`).
  void polyline(const std::vector<Eigen::Vector2d>& points, Rgb c, double line_width, bool closed = false);
  /// Many separate segments of one colour and width, as one path.
  void segments(const std::vector<std::array<double, 4>>& segments, Rgb c, double line_width);
  void circle(double cx, double cy, double r, Rgb c, double line_width);
  /// A filled triangle (an arrow head).
  void triangle(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& d, Rgb c);

  /// The box `s` takes at font `size` with its top-left corner at the origin: the
  /// advance width by the font's ascent plus descent. Loads Cairo (cairo_adapter.hpp)
  /// the first time: std::runtime_error saying where it looked if it cannot.
  [[nodiscard]] static Box textBox(const std::string& s, double size, bool bold = false);
  /// Draws `s` with its box's top-left corner at (x, y) and records it; returns the box.
  Box text(double x, double y, const std::string& s, Rgb c, double size, bool bold = false);
  /// A label on a white background `pad` units wider than its text on every side, at
  /// the first of `centres` where its padded box lies within `bounds` and meets neither
  /// a text drawn before nor a box kept clear. Returns false, drawing nothing, if no
  /// centre is free.
  bool label(const std::vector<Eigen::Vector2d>& centres, const std::string& s, Rgb c, double size, const Box& bounds,
             double pad = 2);
  /// A box labels must keep clear of (a legend, a marked point).
  void keepClear(const Box& b) { clear_.push_back(b); }
  /// Every text drawn so far (a label: its padded box).
  [[nodiscard]] const std::vector<PlacedText>& texts() const { return texts_; }

  /// The picture as pixels (width x height), as the PNG holds it.
  [[nodiscard]] ImageRgb toImage() const;
  /// Writes the picture atomically in the format of `path`'s extension (pictureFormat).
  /// With MOBMAP_PICTURE_TEXTS set to a file name, also appends one JSON line there
  /// naming the picture and every text's box (what the tests check for overlaps).
  void save(const std::string& path) const;
  /// The same in `format`, whatever `path` ends in (a temporary file's name); `name` is
  /// the file's own name for MOBMAP_PICTURE_TEXTS (default `path`).
  void save(const std::string& path, PictureFormat format, const std::string& name = "") const;

 private:
  void add(DrawOp::Kind kind, Rgb c, std::vector<double> points, double line_width = 1, bool closed = false);
  DrawList list_;
  std::vector<PlacedText> texts_;
  std::vector<Box> clear_;
};

/// A colour's grey (luma, BT.601 weights).
[[nodiscard]] Rgb greyOf(Rgb c);

/// A frame as the background of a picture drawn over it: its colour image in grey
/// (greyOf) when it has one of width x height, else its depth (metres, row-major,
/// 0 = nothing measured) shaded grey, nearer lighter (250 - 40 z, kept within 40..240),
/// black where 0. Grey either way, so that the only colours in the picture are the
/// mobility colours laid over it: a red cabinet, a green carpet or a sensor's fill
/// colour where it measured nothing cannot be read as a mobility.
[[nodiscard]] ImageRgb framePicture(int width, int height, const ImageRgb* colour, const std::vector<float>& depth_m);

/// Lays a mobility colour over pixel (x, y): 2 parts picture to 3 parts paint, so the
/// picture shows through. Ignores pixels outside.
void paintOver(ImageRgb& image, int x, int y, Rgb paint);

/// A frame picture with its mobility paint (framePicture, paintOver) above a legend: the
/// colour scale with the unknown colour, and `caption` (the frame's file or number and
/// what was painted).
[[nodiscard]] Picture framePictureWithLegend(const ImageRgb& frame, const std::string& caption, ColourScale scale);

/// The mobility colour bar of a legend, `height` units tall, its top-left at (x, y):
/// the heading "mobility", ticks at 0, 0.5 and 1, then (with `unknown`) the unknown
/// colour and each of `swatches` (colour, text) below. Returns the height it took below
/// (x, y).
double drawMobilityLegend(Picture& p, double x, double y, double height, ColourScale scale,
                          const std::vector<std::pair<Rgb, std::string>>& swatches = {}, bool unknown = true);
/// The widest the legend of drawMobilityLegend gets with these swatches.
[[nodiscard]] double mobilityLegendWidth(const std::vector<std::pair<Rgb, std::string>>& swatches = {});

}  // namespace mobmap::app
