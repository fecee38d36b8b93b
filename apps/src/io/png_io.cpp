#include "io/png_io.hpp"

#include "io/files.hpp"
#include "io/io_error.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>

namespace mobmap::app {
namespace {

// The encoded bytes to `path`, atomically (temporary file + rename).
void writeBytes(const std::string& path, const std::function<std::vector<std::uint8_t>()>& encode) {
  std::vector<std::uint8_t> bytes;
  try {
    bytes = encode();
  } catch (const std::invalid_argument& e) {
    throw IoError(path, e.what());
  } catch (const std::runtime_error& e) {
    throw IoError(path, e.what());
  }
  writeAtomically(path, [&](const std::string& tmp) {
    std::unique_ptr<FILE, int (*)(FILE*)> fp(std::fopen(tmp.c_str(), "wb"), &std::fclose);
    if (!fp) throw IoError(path, std::string("cannot write: ") + std::strerror(errno));
    if (std::fwrite(bytes.data(), 1, bytes.size(), fp.get()) != bytes.size() || std::fflush(fp.get()) != 0) {
      throw IoError(path, "write failed (disk full?)");
    }
  });
}

}  // namespace

void writePng16(const std::string& path, const Image16& image) {
  writeBytes(path, [&] { return sources::encodePng16(image); });
}

void writePngRgb(const std::string& path, const ImageRgb& image) {
  writeBytes(path, [&] { return sources::encodePngRgb(image); });
}

}  // namespace mobmap::app
