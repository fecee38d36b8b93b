#pragma once
// What the reader and writer tests share: scratch folders and the written corridor.
#include "io/dataset.hpp"
#include "io/ground_truth.hpp"
#include "io/files.hpp"
#include "io/frame_source.hpp"
#include "mobmap/sources/pcd.hpp"
#include "io/io_error.hpp"
#include "io/map_files.hpp"
#include "pictures/picture.hpp"
#include "io/png_io.hpp"
#include "io/simulation_writer.hpp"
#include "pictures/top_view.hpp"

#include <Eigen/SVD>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>

#include <unistd.h>

namespace mobmap::app {

namespace fs = std::filesystem;

constexpr double kDeg = 3.14159265358979323846 / 180.0;

class TempDir {
 public:
  TempDir() {
    path_ = fs::temp_directory_path() /
            ("mobmap-test-" + std::to_string(::getpid()) + "-" + std::to_string(counter_++));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  [[nodiscard]] std::string file(const std::string& name) const { return (path_ / name).string(); }
  [[nodiscard]] std::string str() const { return path_.string(); }

 private:
  static inline int counter_ = 0;
  fs::path path_;
};

inline void writeBytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

inline std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const IoError& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace mobmap::app
