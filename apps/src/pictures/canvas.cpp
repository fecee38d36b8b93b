#include "pictures/canvas.hpp"

#include "mobmap/mapping/mobility_map.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>

namespace mobmap::app {
namespace {

// 5x7 glyphs, row by row, '1' = ink.
struct Glyph {
  char c;
  const char* rows;  // 35 characters
};
constexpr Glyph kFont[] = {
    {'0', "01110100011001110101110011000101110"}, {'1', "00100011000010000100001000010001110"},
    {'2', "01110100010000100010001000100011111"}, {'3', "11111000100010000010000011000101110"},
    {'4', "00010001100101010010111110001000010"}, {'5', "11111100001111000001000011000101110"},
    {'6', "00110010001000011110100011000101110"}, {'7', "11111000010001000100010000100001000"},
    {'8', "01110100011000101110100011000101110"}, {'9', "01110100011000101111000010001001100"},
    {'A', "01110100011000111111100011000110001"}, {'B', "11110100011000111110100011000111110"},
    {'C', "01110100011000010000100001000101110"}, {'D', "11100100101000110001100011001011100"},
    {'E', "11111100001000011110100001000011111"}, {'F', "11111100001000011110100001000010000"},
    {'G', "01110100011000010111100011000101111"}, {'H', "10001100011000111111100011000110001"},
    {'I', "01110001000010000100001000010001110"}, {'J', "00111000100001000010000101001001100"},
    {'K', "10001100101010011000101001001010001"}, {'L', "10000100001000010000100001000011111"},
    {'M', "10001110111010110101100011000110001"}, {'N', "10001100011100110101100111000110001"},
    {'O', "01110100011000110001100011000101110"}, {'P', "11110100011000111110100001000010000"},
    {'Q', "01110100011000110001101011001001101"}, {'R', "11110100011000111110101001001010001"},
    {'S', "01111100001000001110000010000111110"}, {'T', "11111001000010000100001000010000100"},
    {'U', "10001100011000110001100011000101110"}, {'V', "10001100011000110001100010101000100"},
    {'W', "10001100011000110101101011010101010"}, {'X', "10001100010101000100010101000110001"},
    {'Y', "10001100011000101010001000010000100"}, {'Z', "11111000010001000100010001000011111"},
    {' ', "00000000000000000000000000000000000"}, {'.', "00000000000000000000000000110001100"},
    {',', "00000000000000000000011000010001000"}, {'-', "00000000000000011111000000000000000"},
    {':', "00000011000110000000011000110000000"}, {'(', "00010001000100001000010000010000010"},
    {')', "01000001000001000010000100010001000"}, {'/', "00000000010001000100010001000000000"},
    {'%', "11000110010001000100010001001100011"}, {'=', "00000000001111100000111110000000000"},
    {'+', "00000001000010011111001000010000000"}, {'>', "01000001000001000001000100010001000"},
    {'<', "00010001000100010000010000010000010"}, {'\'', "00100001000100000000000000000000000"},
    {'_', "00000000000000000000000000000011111"}, {'[', "01110010000100001000010000100001110"},
    {']', "01110000100001000010000100001001110"}, {'*', "00000001001010101110101010010000000"},
    {'?', "01110100010000100010001000000000100"},
};

const Glyph& glyphFor(char c) {
  const char up = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  for (const Glyph& g : kFont) {
    if (g.c == up) return g;
  }
  return kFont[sizeof(kFont) / sizeof(kFont[0]) - 1];  // '?'
}

}  // namespace

Rgb mobilityColour(double m) {
  if (!std::isfinite(m)) return {128, 128, 128};
  return mapping::mobilityRgb(m);
}

Rgb greyOf(Rgb c) {
  // Luma, ITU-R BT.601 weights, rounded.
  const auto y = static_cast<std::uint8_t>((299 * c[0] + 587 * c[1] + 114 * c[2] + 500) / 1000);
  return {y, y, y};
}

Canvas framePicture(int width, int height, const ImageRgb* colour, const std::vector<float>& depth_m) {
  Canvas c(width, height, {0, 0, 0});
  if (colour && colour->width == width && colour->height == height) {
    for (int v = 0; v < height; ++v) {
      for (int u = 0; u < width; ++u) c.set(u, v, greyOf(colour->pixels[static_cast<std::size_t>(v) * width + u]));
    }
    return c;
  }
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * width + u;
      if (i >= depth_m.size() || !(depth_m[i] > 0)) continue;
      const auto g = static_cast<std::uint8_t>(std::clamp(250.0 - 40.0 * depth_m[i], 40.0, 240.0));
      c.set(u, v, {g, g, g});
    }
  }
  return c;
}

void paintOver(Canvas& c, int x, int y, Rgb paint) {
  const Rgb base = c.get(x, y);
  Rgb out;
  for (std::size_t ch = 0; ch < 3; ++ch) out[ch] = static_cast<std::uint8_t>((base[ch] * 2 + paint[ch] * 3) / 5);
  c.set(x, y, out);
}

Canvas::Canvas(int width, int height, Rgb background) {
  image_.width = width;
  image_.height = height;
  image_.pixels.assign(static_cast<std::size_t>(width) * height, background);
}

void Canvas::set(int x, int y, Rgb c) {
  if (x < 0 || y < 0 || x >= image_.width || y >= image_.height) return;
  image_.pixels[static_cast<std::size_t>(y) * image_.width + x] = c;
}

Rgb Canvas::get(int x, int y) const {
  return image_.pixels[static_cast<std::size_t>(y) * image_.width + x];
}

void Canvas::fillRect(int x0, int y0, int x1, int y1, Rgb c) {
  for (int y = std::max(0, std::min(y0, y1)); y <= std::min(image_.height - 1, std::max(y0, y1)); ++y) {
    for (int x = std::max(0, std::min(x0, x1)); x <= std::min(image_.width - 1, std::max(x0, x1)); ++x) {
      image_.pixels[static_cast<std::size_t>(y) * image_.width + x] = c;
    }
  }
}

void Canvas::rect(int x0, int y0, int x1, int y1, Rgb c) {
  line(x0, y0, x1, y0, c);
  line(x1, y0, x1, y1, c);
  line(x1, y1, x0, y1, c);
  line(x0, y1, x0, y0, c);
}

void Canvas::line(int x0, int y0, int x1, int y1, Rgb c) {
  // Bresenham.
  const int dx = std::abs(x1 - x0), sx = x0 < x1 ? 1 : -1;
  const int dy = -std::abs(y1 - y0), sy = y0 < y1 ? 1 : -1;
  int err = dx + dy;
  for (;;) {
    set(x0, y0, c);
    if (x0 == x1 && y0 == y1) break;
    const int e2 = 2 * err;
    if (e2 >= dy) {
      err += dy;
      x0 += sx;
    }
    if (e2 <= dx) {
      err += dx;
      y0 += sy;
    }
  }
}

void Canvas::text(int x, int y, const std::string& s, Rgb c, int scale) {
  for (std::size_t i = 0; i < s.size(); ++i) {
    const Glyph& g = glyphFor(s[i]);
    const int gx = x + static_cast<int>(i) * 6 * scale;
    for (int row = 0; row < 7; ++row) {
      for (int col = 0; col < 5; ++col) {
        if (g.rows[row * 5 + col] == '1') {
          fillRect(gx + col * scale, y + row * scale, gx + col * scale + scale - 1,
                   y + row * scale + scale - 1, c);
        }
      }
    }
  }
}

}  // namespace mobmap::app
