#include "mobmap/sources/png.hpp"

#include "mobmap/sources/io_error.hpp"

#include <png.h>

#include <algorithm>
#include <cerrno>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <memory>
#include <new>
#include <stdexcept>

namespace mobmap::sources {
namespace {

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

enum class Want { kGrey16, kRgb8 };

struct Decoded {
  int width = 0, height = 0, channels = 0, bit_depth = 0, colour_type = 0;
  std::vector<png_byte> bytes;
};

// Bytes in memory, read by libpng through readFromMemory.
struct MemoryInput {
  const png_byte* data = nullptr;
  std::size_t size = 0;
  std::size_t at = 0;
};

void readFromMemory(png_structp png, png_bytep out, png_size_t n) {
  auto* in = static_cast<MemoryInput*>(png_get_io_ptr(png));
  if (n > in->size - in->at) png_error(png, "the PNG ends early");
  std::memcpy(out, in->data + in->at, n);
  in->at += n;
}

// Returns an empty string on success, else the reason. Reads from `fp`, or from `mem`
// when `fp` is null.
std::string decode(FILE* fp, MemoryInput* mem, Want want, Decoded* out) {
  ErrorSink sink;
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &sink, onError, onWarning);
  if (!png) return "out of memory";
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_read_struct(&png, nullptr, nullptr);
    return "out of memory";
  }
  std::vector<png_bytep>* rows = new std::vector<png_bytep>();  // freed on both paths
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    delete rows;
    return std::string("corrupt or truncated PNG (") + sink.message + ")";
  }
  // Any size the format allows is read from the header, so that too large a frame is
  // reported as that (libpng's own limit reads as a corrupt file), before any pixel is.
  png_set_user_limits(png, 0x7fffffff, 0x7fffffff);
  if (fp) {
    png_init_io(png, fp);
  } else {
    png_set_read_fn(png, mem, readFromMemory);
  }
  png_read_info(png, info);
  const png_uint_32 w = png_get_image_width(png, info), h = png_get_image_height(png, info);
  if (w > static_cast<png_uint_32>(kMaxFrameSide) || h > static_cast<png_uint_32>(kMaxFrameSide) ||
      static_cast<long long>(w) * h > kMaxFramePixels) {
    png_destroy_read_struct(&png, &info, nullptr);
    delete rows;
    return "the image is " + std::to_string(w) + "x" + std::to_string(h) + " pixels, larger than mobmap reads (at most " +
           std::to_string(kMaxFrameSide) + " pixels a side and " + std::to_string(kMaxFramePixels) + " pixels in all)";
  }
  out->width = static_cast<int>(w);
  out->height = static_cast<int>(h);
  out->bit_depth = png_get_bit_depth(png, info);
  out->colour_type = png_get_color_type(png, info);
  if (want == Want::kGrey16) {
    if (out->bit_depth != 16 || out->colour_type != PNG_COLOR_TYPE_GRAY) {
      png_destroy_read_struct(&png, &info, nullptr);
      delete rows;
      return "not a 16-bit greyscale PNG (bit depth " + std::to_string(out->bit_depth) +
             ", colour type " + std::to_string(out->colour_type) + ")";
    }
    out->channels = 1;
  } else {
    if (out->bit_depth == 16) png_set_strip_16(png);
    if (out->colour_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if (out->colour_type == PNG_COLOR_TYPE_GRAY && out->bit_depth < 8) png_set_expand_gray_1_2_4_to_8(png);
    if (out->colour_type == PNG_COLOR_TYPE_GRAY || out->colour_type == PNG_COLOR_TYPE_GRAY_ALPHA) png_set_gray_to_rgb(png);
    if (png_get_valid(png, info, PNG_INFO_tRNS)) png_set_tRNS_to_alpha(png);
    png_set_strip_alpha(png);
    out->channels = 3;
  }
  png_read_update_info(png, info);
  const std::size_t stride = png_get_rowbytes(png, info);
  out->bytes.resize(stride * static_cast<std::size_t>(out->height));
  rows->resize(static_cast<std::size_t>(out->height));
  for (int y = 0; y < out->height; ++y) (*rows)[static_cast<std::size_t>(y)] = out->bytes.data() + stride * static_cast<std::size_t>(y);
  png_read_image(png, rows->data());
  png_read_end(png, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  delete rows;
  return {};
}

FilePtr openForReading(const std::string& path) {
  FilePtr fp(std::fopen(path.c_str(), "rb"));
  if (!fp) throw IoError(path, std::string("cannot open: ") + std::strerror(errno));
  unsigned char sig[8] = {0};
  const std::size_t n = std::fread(sig, 1, 8, fp.get());
  if (n < 8 || png_sig_cmp(sig, 0, 8) != 0) throw IoError(path, "not a PNG file");
  std::rewind(fp.get());
  return fp;
}

// Appends what libpng writes to a byte vector.
void writeToMemory(png_structp png, png_bytep data, png_size_t n) {
  auto* out = static_cast<std::vector<std::uint8_t>*>(png_get_io_ptr(png));
  out->insert(out->end(), data, data + n);
}

void flushNothing(png_structp) {}

std::vector<std::uint8_t> encode(int width, int height, int bit_depth, int colour_type, std::vector<png_byte> bytes,
                                 std::size_t stride) {
  if (width <= 0 || height <= 0 || width > kMaxFrameSide || height > kMaxFrameSide) {
    throw std::invalid_argument("cannot write a " + std::to_string(width) + "x" + std::to_string(height) + " image");
  }
  std::vector<png_bytep> rows(static_cast<std::size_t>(height));
  for (int y = 0; y < height; ++y) rows[static_cast<std::size_t>(y)] = bytes.data() + stride * static_cast<std::size_t>(y);
  std::vector<std::uint8_t> out;
  ErrorSink sink;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &sink, onError, onWarning);
  if (!png) throw std::bad_alloc();
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    throw std::bad_alloc();
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    throw std::runtime_error(std::string("PNG encoding failed (") + sink.message + ")");
  }
  png_set_write_fn(png, &out, writeToMemory, flushNothing);
  png_set_compression_level(png, 3);
  png_set_IHDR(png, info, static_cast<png_uint_32>(width), static_cast<png_uint_32>(height), bit_depth, colour_type,
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  png_write_image(png, rows.data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return out;
}

}  // namespace

std::vector<std::uint8_t> encodePng16(const Image16& image) {
  if (image.pixels.size() != static_cast<std::size_t>(image.width) * image.height) {
    throw std::invalid_argument("the image buffer does not match its size");
  }
  std::vector<png_byte> bytes(image.pixels.size() * 2);
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    bytes[2 * i] = static_cast<png_byte>(image.pixels[i] >> 8);
    bytes[2 * i + 1] = static_cast<png_byte>(image.pixels[i] & 0xff);
  }
  return encode(image.width, image.height, 16, PNG_COLOR_TYPE_GRAY, std::move(bytes), static_cast<std::size_t>(image.width) * 2);
}

std::vector<std::uint8_t> encodePngRgb(const ImageRgb& image) {
  if (image.pixels.size() != static_cast<std::size_t>(image.width) * image.height) {
    throw std::invalid_argument("the image buffer does not match its size");
  }
  std::vector<png_byte> bytes(image.pixels.size() * 3);
  if (!bytes.empty()) std::memcpy(bytes.data(), image.pixels.data(), bytes.size());
  return encode(image.width, image.height, 8, PNG_COLOR_TYPE_RGB, std::move(bytes), static_cast<std::size_t>(image.width) * 3);
}

void checkPngComplete(const std::string& path) {
  const FilePtr fp = openForReading(path);
  // The IEND chunk is the last 12 bytes; a little slack for writers that append padding.
  long size = -1;
  if (std::fseek(fp.get(), 0, SEEK_END) == 0) size = std::ftell(fp.get());
  if (size < 0) throw IoError(path, std::string("cannot read: ") + std::strerror(errno));
  const long tail = std::min(size, 4096L);
  std::string bytes(static_cast<std::size_t>(tail), '\0');
  if (std::fseek(fp.get(), size - tail, SEEK_SET) != 0 || std::fread(bytes.data(), 1, bytes.size(), fp.get()) != bytes.size()) {
    throw IoError(path, std::string("cannot read: ") + std::strerror(errno));
  }
  const std::size_t iend = bytes.rfind("IEND");  // the chunk type, then its 4-byte CRC
  if (iend == std::string::npos || bytes.size() - iend < 8) {
    throw IoError(path, "truncated PNG: " + std::to_string(size) + " bytes, and no complete IEND chunk at its end");
  }
}

namespace {

Image16 toImage16(const Decoded& d) {
  Image16 img;
  img.width = d.width;
  img.height = d.height;
  img.pixels.resize(static_cast<std::size_t>(d.width) * d.height);
  for (std::size_t i = 0; i < img.pixels.size(); ++i) {
    img.pixels[i] = static_cast<std::uint16_t>((d.bytes[2 * i] << 8) | d.bytes[2 * i + 1]);  // PNG is big-endian
  }
  return img;
}

}  // namespace

Image16 readPng16(const std::string& path) {
  FilePtr fp = openForReading(path);
  Decoded d;
  const std::string err = decode(fp.get(), nullptr, Want::kGrey16, &d);
  if (!err.empty()) throw IoError(path, err);
  return toImage16(d);
}

Image16 decodePng16(const std::uint8_t* data, std::size_t size, const std::string& what) {
  if (size < 8 || png_sig_cmp(data, 0, 8) != 0) throw IoError(what, "not a PNG");
  MemoryInput in{data, size, 0};
  Decoded d;
  const std::string err = decode(nullptr, &in, Want::kGrey16, &d);
  if (!err.empty()) throw IoError(what, err);
  return toImage16(d);
}

ImageRgb readPngRgb(const std::string& path) {
  FilePtr fp = openForReading(path);
  Decoded d;
  const std::string err = decode(fp.get(), nullptr, Want::kRgb8, &d);
  if (!err.empty()) throw IoError(path, err);
  ImageRgb img;
  img.width = d.width;
  img.height = d.height;
  img.pixels.resize(static_cast<std::size_t>(d.width) * d.height);
  std::memcpy(img.pixels.data(), d.bytes.data(), img.pixels.size() * 3);
  return img;
}

}  // namespace mobmap::sources
