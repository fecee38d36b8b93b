#include "mobmap/sources/text.hpp"

#include "mobmap/sources/io_error.hpp"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace mobmap::sources {

std::string readTextFile(const std::string& path, std::size_t max_bytes) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw IoError(path, "no such file");
  if (std::filesystem::is_directory(path, ec)) throw IoError(path, "is a directory, expected a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path, std::string("cannot open: ") + std::strerror(errno));
  const auto size = std::filesystem::file_size(path, ec);
  if (!ec && size > max_bytes) {
    throw IoError(path, "file is " + std::to_string(size) + " bytes, more than the " +
                            std::to_string(max_bytes) + " expected");
  }
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::optional<double> parseFiniteNumber(const std::string& token) {
  std::size_t used = 0;
  double v = 0.0;
  try {
    v = std::stod(token, &used);
  } catch (const std::exception&) {
    return std::nullopt;
  }
  if (used == 0 || used != token.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::vector<double> splitNumbers(const std::string& spec) {
  std::vector<double> out;
  std::stringstream in(spec);
  std::string cell;
  while (std::getline(in, cell, ',')) {
    const auto v = parseFiniteNumber(cell);
    if (!v) return {};
    out.push_back(*v);
  }
  return out;
}

}  // namespace mobmap::sources
