#include "io/png_io.hpp"

#include "io/files.hpp"
#include "io/io_error.hpp"

#include <png.h>

#include <cerrno>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <memory>

namespace mobmap::app {
namespace {

constexpr int kMaxSide = kMaxFrameSide;

// libpng reports errors through a callback that must not return: we record the
// message and longjmp back to the setjmp in the calling function. Only trivially
// destructible locals live between setjmp and longjmp.
struct ErrorSink {
  char message[256] = {0};
};

void onError(png_structp png, png_const_charp msg) {
  auto* sink = static_cast<ErrorSink*>(png_get_error_ptr(png));
  std::snprintf(sink->message, sizeof(sink->message), "%s", msg);
  longjmp(png_jmpbuf(png), 1);
}

void onWarning(png_structp, png_const_charp) {}  // the library never prints

struct FileCloser {
  void operator()(FILE* f) const {
    if (f) std::fclose(f);
  }
};
using FilePtr = std::unique_ptr<FILE, FileCloser>;

std::string encode(FILE* fp, int width, int height, int bit_depth, int colour_type,
                   const std::vector<png_bytep>& rows) {
  ErrorSink sink;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &sink, onError, onWarning);
  if (!png) return "out of memory";
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    return "out of memory";
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return std::string("PNG encoding failed (") + sink.message + ")";
  }
  png_init_io(png, fp);
  png_set_compression_level(png, 3);  // depth images: speed matters more than size
  png_set_IHDR(png, info, static_cast<png_uint_32>(width), static_cast<png_uint_32>(height),
               bit_depth, colour_type, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  png_write_image(png, const_cast<png_bytepp>(rows.data()));
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return {};
}

void writeRaw(const std::string& path, int width, int height, int bit_depth, int colour_type,
              std::vector<png_byte> bytes, std::size_t stride) {
  if (width <= 0 || height <= 0 || width > kMaxSide || height > kMaxSide) {
    throw IoError(path, "cannot write a " + std::to_string(width) + "x" + std::to_string(height) + " image");
  }
  std::vector<png_bytep> rows(static_cast<std::size_t>(height));
  for (int y = 0; y < height; ++y) rows[static_cast<std::size_t>(y)] = bytes.data() + stride * static_cast<std::size_t>(y);
  writeAtomically(path, [&](const std::string& tmp) {
    FilePtr fp(std::fopen(tmp.c_str(), "wb"));
    if (!fp) throw IoError(path, std::string("cannot write: ") + std::strerror(errno));
    const std::string err = encode(fp.get(), width, height, bit_depth, colour_type, rows);
    if (!err.empty()) throw IoError(path, err);
    if (std::fflush(fp.get()) != 0) throw IoError(path, "write failed (disk full?)");
  });
}

}  // namespace

void writePng16(const std::string& path, const Image16& image) {
  if (image.pixels.size() != static_cast<std::size_t>(image.width) * image.height) {
    throw IoError(path, "image buffer does not match its size");
  }
  std::vector<png_byte> bytes(image.pixels.size() * 2);
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    bytes[2 * i] = static_cast<png_byte>(image.pixels[i] >> 8);
    bytes[2 * i + 1] = static_cast<png_byte>(image.pixels[i] & 0xff);
  }
  writeRaw(path, image.width, image.height, 16, PNG_COLOR_TYPE_GRAY, std::move(bytes),
           static_cast<std::size_t>(image.width) * 2);
}

void writePngRgb(const std::string& path, const ImageRgb& image) {
  if (image.pixels.size() != static_cast<std::size_t>(image.width) * image.height) {
    throw IoError(path, "image buffer does not match its size");
  }
  std::vector<png_byte> bytes(image.pixels.size() * 3);
  std::memcpy(bytes.data(), image.pixels.data(), bytes.size());
  writeRaw(path, image.width, image.height, 8, PNG_COLOR_TYPE_RGB, std::move(bytes),
           static_cast<std::size_t>(image.width) * 3);
}

}  // namespace mobmap::app
