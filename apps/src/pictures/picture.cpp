#include "pictures/picture.hpp"

#include "io/io_error.hpp"
#include "io/files.hpp"

#include "mobmap/util/plugin.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <stdexcept>

namespace mobmap::app {
namespace {

// Cairo, opened when the first picture needs it.
const CairoAdapter& cairo() {
  static const CairoAdapter* const loaded = [] {
    return &util::pluginTable<CairoAdapter>("cairo", "mobmap_cairo_adapter", kCairoAdapterVersion);
  }();
  return *loaded;
}

}  // namespace

PictureFormat pictureFormat(const std::string& path) {
  std::string ext;
  const std::size_t dot = path.find_last_of('.');
  const std::size_t slash = path.find_last_of('/');
  if (dot != std::string::npos && (slash == std::string::npos || dot > slash)) ext = path.substr(dot);
  for (char& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  if (ext == ".png") return PictureFormat::kPng;
  if (ext == ".svg") return PictureFormat::kSvg;
  if (ext == ".pdf") return PictureFormat::kPdf;
  throw UsageError(path + ": a picture's name must end in .png, .svg or .pdf (the format is taken from it)");
}

Picture::Picture(int width, int height, Rgb background) {
  if (width < 1 || height < 1 || width > 32767 || height > 32767) {
    throw std::invalid_argument("a picture must be 1 to 32767 units on each side, not " + std::to_string(width) + " x " +
                                std::to_string(height));
  }
  list_.width = width;
  list_.height = height;
  fillRect(0, 0, width, height, background);
}

void Picture::add(DrawOp::Kind kind, Rgb c, std::vector<double> points, double line_width, bool closed) {
  DrawOp op;
  op.kind = kind;
  op.colour = c;
  op.points = std::move(points);
  op.width = line_width;
  op.closed = closed;
  list_.ops.push_back(std::move(op));
}

void Picture::image(const ImageRgb& img, double x, double y, double scale) {
  image(img, x, y, scale * img.width, scale * img.height);
}

void Picture::image(const ImageRgb& img, double x, double y, double w, double h) {
  if (img.width < 1 || img.height < 1) return;
  list_.images.push_back(img);
  add(DrawOp::kImage, {0, 0, 0}, {x, y, w, h});
  list_.ops.back().image = list_.images.size() - 1;
}

void Picture::fillRect(double x, double y, double w, double h, Rgb c) {
  add(DrawOp::kFill, c, {x, y, x + w, y, x + w, y + h, x, y + h});
}

void Picture::strokeRect(double x, double y, double w, double h, Rgb c, double line_width) {
  add(DrawOp::kStroke, c, {x, y, x + w, y, x + w, y + h, x, y + h}, line_width, true);
}

void Picture::polyline(const std::vector<Eigen::Vector2d>& points, Rgb c, double line_width, bool closed) {
  if (points.size() < 2) return;
  std::vector<double> xy;
  for (const Eigen::Vector2d& p : points) xy.insert(xy.end(), {p.x(), p.y()});
  add(DrawOp::kStroke, c, std::move(xy), line_width, closed);
}

void Picture::segments(const std::vector<std::array<double, 4>>& segs, Rgb c, double line_width) {
  if (segs.empty()) return;
  std::vector<double> xy;
  for (const auto& s : segs) xy.insert(xy.end(), s.begin(), s.end());
  add(DrawOp::kSegments, c, std::move(xy), line_width);
}

void Picture::circle(double cx, double cy, double r, Rgb c, double line_width) {
  add(DrawOp::kCircle, c, {cx, cy, r}, line_width);
}

void Picture::triangle(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& d, Rgb c) {
  add(DrawOp::kFill, c, {a.x(), a.y(), b.x(), b.y(), d.x(), d.y()});
}

Box Picture::textBox(const std::string& s, double size, bool bold) {
  const TextMetrics m = cairo().measure(s, size, bold);
  return {0, 0, m.width, m.ascent + m.descent};
}

Box Picture::text(double x, double y, const std::string& s, Rgb c, double size, bool bold) {
  const Box b = textBox(s, size, bold);
  add(DrawOp::kText, c, {x, y});
  list_.ops.back().text = s;
  list_.ops.back().size = size;
  list_.ops.back().bold = bold;
  const Box placed{x, y, x + b.x1, y + b.y1};
  texts_.push_back({s, placed});
  return placed;
}

bool Picture::label(const std::vector<Eigen::Vector2d>& centres, const std::string& s, Rgb c, double size,
                    const Box& bounds, double pad) {
  const Box b = textBox(s, size);
  const double w = b.x1 + 2 * pad, h = b.y1 + 2 * pad;
  for (const Eigen::Vector2d& centre : centres) {
    const Box box{centre.x() - w / 2, centre.y() - h / 2, centre.x() + w / 2, centre.y() + h / 2};
    if (!box.inside(bounds)) continue;
    const auto hits = [&](const Box& o) { return box.intersects(o); };
    if (std::any_of(texts_.begin(), texts_.end(), [&](const PlacedText& t) { return hits(t.box); })) continue;
    if (std::any_of(clear_.begin(), clear_.end(), hits)) continue;
    fillRect(box.x0, box.y0, w, h, {255, 255, 255});
    text(box.x0 + pad, box.y0 + pad, s, c, size);
    texts_.back().box = box;
    return true;
  }
  return false;
}

ImageRgb Picture::toImage() const { return cairo().raster(list_); }

void Picture::save(const std::string& path) const { save(path, pictureFormat(path)); }

void Picture::save(const std::string& path, PictureFormat format, const std::string& name) const {
  try {
    if (format == PictureFormat::kPng) {
      writePngRgb(path, toImage());
    } else {
      writeTextFileAtomically(path, cairo().document(list_, format == PictureFormat::kPdf));
    }
  } catch (const IoError&) {
    throw;
  } catch (const std::runtime_error& e) {
    throw IoError(path, std::string("cannot draw the picture: ") + e.what());
  }
  if (const char* log = std::getenv("MOBMAP_PICTURE_TEXTS"); log && *log) {
    nlohmann::json j{{"picture", name.empty() ? path : name}, {"width", width()}, {"height", height()}, {"texts", nlohmann::json::array()}};
    for (const PlacedText& t : texts_) j["texts"].push_back({{"text", t.text}, {"box", {t.box.x0, t.box.y0, t.box.x1, t.box.y1}}});
    std::ofstream(log, std::ios::app) << j.dump() << '\n';
  }
}

Rgb greyOf(Rgb c) {
  // Luma, ITU-R BT.601 weights, rounded.
  const auto y = static_cast<std::uint8_t>((299 * c[0] + 587 * c[1] + 114 * c[2] + 500) / 1000);
  return {y, y, y};
}

ImageRgb framePicture(int width, int height, const ImageRgb* colour, const std::vector<float>& depth_m) {
  ImageRgb img;
  img.width = width;
  img.height = height;
  img.pixels.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), Rgb{0, 0, 0});
  if (colour && colour->width == width && colour->height == height) {
    for (std::size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = greyOf(colour->pixels[i]);
    return img;
  }
  for (std::size_t i = 0; i < img.pixels.size() && i < depth_m.size(); ++i) {
    if (!(depth_m[i] > 0)) continue;
    const auto g = static_cast<std::uint8_t>(std::clamp(250.0 - 40.0 * depth_m[i], 40.0, 240.0));
    img.pixels[i] = {g, g, g};
  }
  return img;
}

void paintOver(ImageRgb& img, int x, int y, Rgb paint) {
  if (x < 0 || y < 0 || x >= img.width || y >= img.height) return;
  Rgb& base = img.pixels[static_cast<std::size_t>(y) * static_cast<std::size_t>(img.width) + static_cast<std::size_t>(x)];
  for (std::size_t ch = 0; ch < 3; ++ch) base[ch] = static_cast<std::uint8_t>((base[ch] * 2 + paint[ch] * 3) / 5);
}

namespace {
constexpr double kLegendText = 12;
constexpr double kSwatch = 14;
constexpr double kRow = 20;
const Rgb kInk{0, 0, 0};
}  // namespace

double mobilityLegendWidth(const std::vector<std::pair<Rgb, std::string>>& swatches) {
  using P = Picture;
  double w = std::max(P::textBox("mobility", kLegendText, true).x1, kSwatch + 6 + P::textBox("0.5", kLegendText).x1);
  w = std::max(w, kSwatch + 6 + P::textBox("unknown", kLegendText).x1);
  for (const auto& s : swatches) w = std::max(w, kSwatch + 6 + P::textBox(s.second, kLegendText).x1);
  return w;
}

double drawMobilityLegend(Picture& p, double x, double y, double height, ColourScale scale,
                          const std::vector<std::pair<Rgb, std::string>>& swatches, bool unknown) {
  const Box heading = p.text(x, y, "mobility", kInk, kLegendText, true);
  const double top = heading.y1 + 8;
  const double bar_h = std::max(48.0, height);
  ImageRgb bar;
  bar.width = 1;
  bar.height = 256;
  for (int i = 0; i < 256; ++i) bar.pixels.push_back(mobilityColour(1.0 - i / 255.0, scale));
  p.image(bar, x, top, kSwatch, bar_h);
  p.strokeRect(x, top, kSwatch, bar_h, kInk, 1);
  const double tick_h = p.textBox("0", kLegendText).y1;
  for (const double m : {1.0, 0.5, 0.0}) {
    const double ty = top + (1.0 - m) * bar_h;
    p.segments({{x + kSwatch, ty, x + kSwatch + 4, ty}}, kInk, 1);
    p.text(x + kSwatch + 6, ty - tick_h / 2, m == 0.5 ? "0.5" : (m == 1.0 ? "1" : "0"), kInk, kLegendText);
  }
  double row = top + bar_h + tick_h / 2 + 8;
  std::vector<std::pair<Rgb, std::string>> rows;
  if (unknown) rows.emplace_back(unknownColour(scale), "unknown");
  rows.insert(rows.end(), swatches.begin(), swatches.end());
  for (const auto& [colour, text] : rows) {
    p.fillRect(x, row, kSwatch, kSwatch, colour);
    p.strokeRect(x, row, kSwatch, kSwatch, {90, 90, 90}, 0.8);
    p.text(x + kSwatch + 6, row + kSwatch / 2 - tick_h / 2, text, kInk, kLegendText);
    row += kRow;
  }
  return row - y;
}

Picture framePictureWithLegend(const ImageRgb& frame, const std::string& caption, ColourScale scale) {
  // The legend runs along the bottom: the caption, then the colour scale laid flat.
  constexpr double kStrip = 58;
  // As wide as the frame, or as its caption and the scale when they are wider.
  const double needed = std::max(16 + Picture::textBox(caption, kLegendText).x1,
                                  40 + Picture::textBox("mobility 0 1 unknown", kLegendText).x1 + kSwatch +
                                      std::min(200.0, frame.width / 3.0));
  Picture p(std::max(frame.width, static_cast<int>(std::ceil(needed))), frame.height + static_cast<int>(kStrip), {255, 255, 255});
  p.image(frame, 0, 0, 1);
  const double y = frame.height + 6;
  const Box cap = p.text(8, y, caption, kInk, kLegendText);
  // The scale: a bar from 0 to 1 with its ends named, then the unknown swatch.
  const double bar_x = 8, bar_y = cap.y1 + 6, bar_w = std::min(200.0, frame.width / 3.0);
  ImageRgb bar;
  bar.width = 256;
  bar.height = 1;
  for (int i = 0; i < 256; ++i) bar.pixels.push_back(mobilityColour(i / 255.0, scale));
  const Box low = p.text(bar_x, bar_y, "mobility 0", kInk, kLegendText);
  p.image(bar, low.x1 + 6, bar_y + 1, bar_w, kSwatch);
  p.strokeRect(low.x1 + 6, bar_y + 1, bar_w, kSwatch, kInk, 1);
  const Box high = p.text(low.x1 + 12 + bar_w, bar_y, "1", kInk, kLegendText);
  p.fillRect(high.x1 + 18, bar_y + 1, kSwatch, kSwatch, unknownColour(scale));
  p.strokeRect(high.x1 + 18, bar_y + 1, kSwatch, kSwatch, {90, 90, 90}, 0.8);
  p.text(high.x1 + 18 + kSwatch + 6, bar_y, "unknown", kInk, kLegendText);
  return p;
}

}  // namespace mobmap::app
