// libmobmap_cairo.so: draws a picture's operations with Cairo (cairo_adapter.hpp).
#include "pictures/cairo_adapter.hpp"

#include <cairo-pdf.h>
#include <cairo-svg.h>
#include <cairo.h>

#include <cmath>
#include <stdexcept>

namespace mobmap::app {
namespace {

// The pictures' font: fontconfig's match for DejaVu Sans (setup.sh installs it).
constexpr const char* kFont = "DejaVu Sans";

void setFont(cairo_t* cr, double size, bool bold) {
  cairo_select_font_face(cr, kFont, CAIRO_FONT_SLANT_NORMAL, bold ? CAIRO_FONT_WEIGHT_BOLD : CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, size);
}

TextMetrics measure(const std::string& text, double size, bool bold) {
  // One scratch context per thread, kept: text is measured many times per picture.
  struct Scratch {
    cairo_surface_t* surface = cairo_image_surface_create(CAIRO_FORMAT_RGB24, 1, 1);
    cairo_t* cr = cairo_create(surface);
    ~Scratch() {
      cairo_destroy(cr);
      cairo_surface_destroy(surface);
    }
  };
  thread_local Scratch scratch;
  setFont(scratch.cr, size, bold);
  cairo_font_extents_t fe;
  cairo_font_extents(scratch.cr, &fe);
  cairo_text_extents_t te;
  cairo_text_extents(scratch.cr, text.c_str(), &te);
  return {te.x_advance, fe.ascent, fe.descent};
}

cairo_surface_t* imageSurface(const ImageRgb& img) {
  cairo_surface_t* s = cairo_image_surface_create(CAIRO_FORMAT_RGB24, img.width, img.height);
  cairo_surface_flush(s);
  unsigned char* data = cairo_image_surface_get_data(s);
  const int stride = cairo_image_surface_get_stride(s);
  for (int v = 0; v < img.height; ++v) {
    auto* row = reinterpret_cast<std::uint32_t*>(data + static_cast<std::ptrdiff_t>(v) * stride);
    for (int u = 0; u < img.width; ++u) {
      const auto& p = img.pixels[static_cast<std::size_t>(v) * static_cast<std::size_t>(img.width) + static_cast<std::size_t>(u)];
      row[u] = (std::uint32_t{p[0]} << 16) | (std::uint32_t{p[1]} << 8) | std::uint32_t{p[2]};
    }
  }
  cairo_surface_mark_dirty(s);
  return s;
}

void draw(cairo_t* cr, const DrawList& list) {
  std::vector<cairo_surface_t*> images;
  for (const ImageRgb& img : list.images) images.push_back(img.width > 0 && img.height > 0 ? imageSurface(img) : nullptr);
  for (const DrawOp& op : list.ops) {
    const auto& p = op.points;
    cairo_set_source_rgb(cr, op.colour[0] / 255.0, op.colour[1] / 255.0, op.colour[2] / 255.0);
    switch (op.kind) {
      case DrawOp::kFill:
      case DrawOp::kStroke:
        if (p.size() < 4) break;
        cairo_move_to(cr, p[0], p[1]);
        for (std::size_t i = 2; i + 1 < p.size(); i += 2) cairo_line_to(cr, p[i], p[i + 1]);
        if (op.kind == DrawOp::kFill) {
          cairo_close_path(cr);
          cairo_fill(cr);
        } else {
          if (op.closed) cairo_close_path(cr);
          cairo_set_line_width(cr, op.width);
          cairo_set_line_join(cr, CAIRO_LINE_JOIN_ROUND);
          cairo_set_line_cap(cr, CAIRO_LINE_CAP_ROUND);
          cairo_stroke(cr);
        }
        break;
      case DrawOp::kSegments:
        for (std::size_t i = 0; i + 3 < p.size(); i += 4) {
          cairo_move_to(cr, p[i], p[i + 1]);
          cairo_line_to(cr, p[i + 2], p[i + 3]);
        }
        cairo_set_line_width(cr, op.width);
        cairo_set_line_cap(cr, CAIRO_LINE_CAP_SQUARE);
        cairo_stroke(cr);
        break;
      case DrawOp::kCircle:
        if (p.size() < 3) break;
        cairo_new_sub_path(cr);
        cairo_arc(cr, p[0], p[1], p[2], 0, 2 * M_PI);
        cairo_set_line_width(cr, op.width);
        cairo_stroke(cr);
        break;
      case DrawOp::kImage: {
        if (p.size() < 4 || op.image >= images.size() || !images[op.image]) break;
        const ImageRgb& img = list.images[op.image];
        cairo_save(cr);
        cairo_translate(cr, p[0], p[1]);
        cairo_scale(cr, p[2] / img.width, p[3] / img.height);
        cairo_set_source_surface(cr, images[op.image], 0, 0);
        cairo_pattern_set_filter(cairo_get_source(cr), CAIRO_FILTER_NEAREST);
        cairo_rectangle(cr, 0, 0, img.width, img.height);
        cairo_fill(cr);
        cairo_restore(cr);
        break;
      }
      case DrawOp::kText: {
        if (p.size() < 2) break;
        setFont(cr, op.size, op.bold);
        cairo_font_extents_t fe;
        cairo_font_extents(cr, &fe);
        cairo_move_to(cr, p[0], p[1] + fe.ascent);
        cairo_show_text(cr, op.text.c_str());
        cairo_new_path(cr);
        break;
      }
    }
  }
  for (cairo_surface_t* s : images) {
    if (s) cairo_surface_destroy(s);
  }
}

ImageRgb raster(const DrawList& list) {
  cairo_surface_t* target = cairo_image_surface_create(CAIRO_FORMAT_RGB24, list.width, list.height);
  cairo_t* cr = cairo_create(target);
  draw(cr, list);
  cairo_destroy(cr);
  cairo_surface_flush(target);
  const unsigned char* data = cairo_image_surface_get_data(target);
  const int stride = cairo_image_surface_get_stride(target);
  ImageRgb out;
  out.width = list.width;
  out.height = list.height;
  out.pixels.resize(static_cast<std::size_t>(list.width) * static_cast<std::size_t>(list.height));
  for (int v = 0; v < list.height; ++v) {
    const auto* row = reinterpret_cast<const std::uint32_t*>(data + static_cast<std::ptrdiff_t>(v) * stride);
    for (int u = 0; u < list.width; ++u) {
      const std::uint32_t px = row[u];
      out.pixels[static_cast<std::size_t>(v) * static_cast<std::size_t>(list.width) + static_cast<std::size_t>(u)] = {
          static_cast<std::uint8_t>(px >> 16), static_cast<std::uint8_t>(px >> 8), static_cast<std::uint8_t>(px)};
    }
  }
  cairo_surface_destroy(target);
  return out;
}

cairo_status_t append(void* closure, const unsigned char* data, unsigned int length) {
  static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
  return CAIRO_STATUS_SUCCESS;
}

std::string document(const DrawList& list, bool pdf) {
  std::string bytes;
  cairo_surface_t* target = pdf ? cairo_pdf_surface_create_for_stream(append, &bytes, list.width, list.height)
                                : cairo_svg_surface_create_for_stream(append, &bytes, list.width, list.height);
  cairo_t* cr = cairo_create(target);
  draw(cr, list);
  cairo_destroy(cr);
  cairo_surface_finish(target);
  const cairo_status_t status = cairo_surface_status(target);
  cairo_surface_destroy(target);
  if (status != CAIRO_STATUS_SUCCESS) throw std::runtime_error(std::string("Cairo: ") + cairo_status_to_string(status));
  return bytes;
}

const CairoAdapter kAdapter{kCairoAdapterVersion, &measure, &raster, &document};

}  // namespace
}  // namespace mobmap::app

extern "C" const mobmap::app::CairoAdapter* mobmap_cairo_adapter() { return &mobmap::app::kAdapter; }
