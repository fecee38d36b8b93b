#include "mobmap/sources/trajectory_files.hpp"

#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/text.hpp"

#include "mobmap/mapping/gravity.hpp"

#include <cctype>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <sstream>

namespace mobmap::sources {

namespace fs = std::filesystem;

// "timestamp value..." lines; '#' comments. Errors name the file and line.
std::vector<std::pair<double, std::vector<std::string>>> readTimestamped(const std::string& path, std::size_t fields) {
  std::vector<std::pair<double, std::vector<std::string>>> out;
  std::istringstream in(readTextFile(path, 256u << 20));
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream ls(line);
    std::string t_str;
    ls >> t_str;
    std::vector<std::string> rest;
    for (std::string v; ls >> v;) rest.push_back(v);
    const auto t = parseFiniteNumber(t_str);
    if (!t) throw IoError(path, "line " + std::to_string(line_no) + ": '" + t_str + "' is not a timestamp");
    if (rest.size() != fields) {
      throw IoError(path, "line " + std::to_string(line_no) + ": expected " + std::to_string(fields + 1) + " columns, found " +
                              std::to_string(rest.size() + 1));
    }
    out.emplace_back(*t, std::move(rest));
  }
  return out;
}

std::vector<std::pair<double, Eigen::Isometry3d>> readTumPoses(const std::string& path) {
  std::vector<std::pair<double, Eigen::Isometry3d>> out;
  int line = 0;
  for (const auto& [t, v] : readTimestamped(path, 7)) {
    ++line;
    double x[7];
    for (int i = 0; i < 7; ++i) {
      const auto value = parseFiniteNumber(v[static_cast<std::size_t>(i)]);
      if (!value) {
        throw IoError(path, "pose " + std::to_string(line) + ": '" + v[static_cast<std::size_t>(i)] + "' is not a finite number");
      }
      x[i] = *value;
    }
    const Eigen::Quaterniond q(x[6], x[3], x[4], x[5]);  // file order qx qy qz qw
    if (std::abs(q.norm() - 1.0) > 1e-3) {
      throw IoError(path, "pose " + std::to_string(line) + ": quaternion norm " + std::to_string(q.norm()) + " is not 1");
    }
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = q.normalized().toRotationMatrix();
    T.translation() = Eigen::Vector3d(x[0], x[1], x[2]);
    if (auto problem = mapping::checkRigid(T.matrix())) throw IoError(path, "pose " + std::to_string(line) + ": " + *problem);
    out.emplace_back(t, T);
  }
  return out;
}

std::optional<double> timestampFromFileName(const std::string& path) {
  const std::string stem = fs::path(path).stem().string();
  // ISO basic: YYYYMMDDTHHMMSS[.fraction]
  for (std::size_t i = 0; i + 15 <= stem.size(); ++i) {
    if (stem[i + 8] != 'T') continue;
    bool digits = true;
    for (std::size_t j = 0; j < 15 && digits; ++j) {
      if (j != 8) digits = std::isdigit(static_cast<unsigned char>(stem[i + j])) != 0;
    }
    if (!digits) continue;
    auto num = [&](std::size_t at, std::size_t len) { return std::stoi(stem.substr(i + at, len)); };
    std::tm tm{};
    tm.tm_year = num(0, 4) - 1900;
    tm.tm_mon = num(4, 2) - 1;
    tm.tm_mday = num(6, 2);
    tm.tm_hour = num(9, 2);
    tm.tm_min = num(11, 2);
    tm.tm_sec = num(13, 2);
    if (tm.tm_mon > 11 || tm.tm_mday < 1 || tm.tm_mday > 31 || tm.tm_hour > 23 || tm.tm_min > 59 || tm.tm_sec > 60) continue;
    double t = static_cast<double>(timegm(&tm));
    std::size_t end = i + 15;
    if (end < stem.size() && stem[end] == '.') {
      std::size_t k = end + 1;
      while (k < stem.size() && std::isdigit(static_cast<unsigned char>(stem[k]))) ++k;
      if (k > end + 1) t += std::stod("0" + stem.substr(end, k - end));
    }
    return t;
  }
  // A trailing decimal number: 1305031102.175304
  std::size_t b = stem.size();
  while (b > 0 && (std::isdigit(static_cast<unsigned char>(stem[b - 1])) || stem[b - 1] == '.')) --b;
  while (b < stem.size() && stem[b] == '.') ++b;
  if (b == stem.size()) return std::nullopt;
  return parseFiniteNumber(stem.substr(b));
}

}  // namespace mobmap::sources
