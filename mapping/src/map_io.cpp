#include "mobmap/mapping/mobility_map.hpp"

#include "atomic_write.hpp"

#include <octomap/ColorOcTree.h>

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

namespace mobmap::mapping {
namespace {

[[noreturn]] void ioFail(const std::string& path, const std::string& reason) { throw MapIoError(path + ": " + reason); }

template <typename Visit>
void forEachOccupiedVoxel(const MobilityOcTree& tree, Visit visit) {
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    if (!tree.isNodeOccupied(*it)) continue;
    visit(it);
  }
}

}  // namespace

void writeAtomically(const std::string& path, const std::function<bool(std::ostream&)>& write) {
  const std::filesystem::path target(path);
  std::error_code ec;
  if (target.has_parent_path()) std::filesystem::create_directories(target.parent_path(), ec);
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) ioFail(path, std::string("cannot write: ") + std::strerror(errno));
    const bool ok = write(out);
    out.flush();
    if (!ok || !out) {
      out.close();
      std::filesystem::remove(tmp, ec);
      ioFail(path, "write failed (disk full?)");
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string reason = std::strerror(errno);
    std::filesystem::remove(tmp, ec);
    ioFail(path, "cannot move the temporary file into place: " + reason);
  }
}

void saveMobilityMap(const MobilityOcTree& tree, const std::string& path) {
  writeAtomically(path, [&](std::ostream& s) { return tree.write(s); });
}

std::unique_ptr<MobilityOcTree> loadMobilityMap(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) ioFail(path, "no such file");
  if (std::filesystem::is_directory(path, ec)) ioFail(path, "is a directory, expected a .ot map");
  const auto file_size = std::filesystem::file_size(path, ec);
  std::ifstream in(path, std::ios::binary);
  if (!in) ioFail(path, std::string("cannot open: ") + std::strerror(errno));
  // Header (OctoMap's .ot layout): "# Octomap OcTree file", comments, then id, size,
  // res, data. Parsed here so every failure gets a clear message.
  std::string line;
  std::getline(in, line);
  if (line.rfind("# Octomap OcTree binary file", 0) == 0) {
    ioFail(path, "is an OctoMap binary (.bt) occupancy map, not a full .ot mobility map");
  }
  if (line.rfind("# Octomap OcTree file", 0) != 0) ioFail(path, "not an OctoMap .ot file (first line is not '# Octomap OcTree file')");
  std::string id;
  std::size_t size = 0;
  std::string size_text, res_text;
  bool have_size = false, have_res = false;
  while (in >> line) {
    if (line == "#") {
      std::getline(in, line);
    } else if (line == "id") {
      in >> id;
    } else if (line == "size") {
      have_size = static_cast<bool>(in >> size_text);
    } else if (line == "res") {
      have_res = static_cast<bool>(in >> res_text);
    } else if (line == "data") {
      std::getline(in, line);  // rest of the "data" line
      break;
    } else if (!line.empty() && line[0] == '#') {
      std::getline(in, line);
    } else {
      ioFail(path, "unexpected header entry '" + line + "'");
    }
  }
  if (!in) ioFail(path, "header ends before 'data' (truncated?)");
  if (id != MobilityOcTree::kTreeType) {
    if (id.rfind("MobilityOcTree", 0) == 0) {
      ioFail(path, "is a " + id + " map, written by another version of mobmap (this one reads " +
                       MobilityOcTree::kTreeType + ")");
    }
    ioFail(path, "holds an OctoMap '" + id + "', not a " + MobilityOcTree::kTreeType + " mobility map");
  }
  if (!have_size) ioFail(path, "header has no 'size' (the number of nodes)");
  if (!have_res) ioFail(path, "header has no 'res' (the voxel size)");
  double res = 0.0;
  {
    // Whole tokens: "nan", "inf" and "12abc" are reported as what they are.
    char* end = nullptr;
    errno = 0;
    const unsigned long long n = std::strtoull(size_text.c_str(), &end, 10);
    if (size_text.empty() || size_text[0] == '-' || *end != '\0' || errno == ERANGE) {
      ioFail(path, "header's size '" + size_text + "' is not a whole number of nodes");
    }
    size = static_cast<std::size_t>(n);
    end = nullptr;
    res = std::strtod(res_text.c_str(), &end);
    if (res_text.empty() || *end != '\0' || !std::isfinite(res)) {
      ioFail(path, "header's res '" + res_text + "' is not a finite number");
    }
    if (!(res >= 0.001 && res <= 10)) {
      ioFail(path, "header's res " + res_text + " m is outside the voxel sizes mobmap maps use (0.001 to 10 m)");
    }
  }
  // Each node takes 4 (occupancy) + 4 (payload) + 1 (children) bytes.
  const auto remaining = static_cast<std::uintmax_t>(file_size) - static_cast<std::uintmax_t>(in.tellg());
  if (size > remaining / 9 + 1) {
    ioFail(path, "header declares " + std::to_string(size) + " nodes but only " + std::to_string(remaining) +
                     " bytes follow (truncated?)");
  }
  auto tree = std::make_unique<MobilityOcTree>(res);
  const std::string error = tree->readDataChecked(in, size);
  if (!error.empty()) ioFail(path, error);
  if (tree->size() != size) {
    ioFail(path, "header declares " + std::to_string(size) + " nodes, the data holds " + std::to_string(tree->size()));
  }
  // Nothing may follow the tree: bytes after it mean a file joined to another or
  // overwritten in part, whose tree cannot be trusted either.
  if (in.peek() != std::char_traits<char>::eof()) {
    const auto at = static_cast<std::uintmax_t>(in.tellg());
    ioFail(path, std::to_string(file_size - at) + " bytes follow the tree's data (at byte " + std::to_string(at) +
                     "): the file is corrupt, or two files were joined");
  }
  if (auto problem = voxelBudgetProblem(*tree)) ioFail(path, *problem + ": not a map mobmap can use");
  return tree;
}

void saveOccupancyBt(const MobilityOcTree& tree, const std::string& path) {
  // OctoMap's binary format stores occupancy only; the header says "OcTree" so any
  // OctoMap tool reads it as a plain occupancy tree.
  writeAtomically(path, [&](std::ostream& s) {
    s << "# Octomap OcTree binary file\n# written by mobmap: occupancy of a MobilityOcTree\n";
    s << "id OcTree\nsize " << tree.size() << "\nres " << tree.getResolution() << "\ndata\n";
    tree.writeBinaryData(s);
    return static_cast<bool>(s);
  });
}

const std::vector<VoxelRgb>& colourStops(ColourScale scale) {
  // viridis at 0, 1/8, ..., 1 (matplotlib's colour map by van der Walt and Smith, as
  // 8-bit sRGB).
  static const std::vector<VoxelRgb> kViridis{{68, 1, 84},    {72, 40, 120},  {62, 73, 137},
                                              {49, 104, 142}, {38, 130, 142}, {31, 158, 137},
                                              {53, 183, 121}, {110, 206, 88}, {253, 231, 37}};
  static const std::vector<VoxelRgb> kRedGreen{{255, 0, 0}, {255, 220, 0}, {0, 220, 0}};
  return scale == ColourScale::kRedGreen ? kRedGreen : kViridis;
}

const char* toString(ColourScale scale) { return scale == ColourScale::kRedGreen ? "red-green" : "viridis"; }

std::optional<ColourScale> colourScaleNamed(const std::string& name) {
  if (name == "viridis") return ColourScale::kViridis;
  if (name == "red-green") return ColourScale::kRedGreen;
  return std::nullopt;
}

VoxelRgb unknownRgb(ColourScale scale) {
  return scale == ColourScale::kRedGreen ? VoxelRgb{140, 140, 140} : VoxelRgb{190, 190, 190};
}

VoxelRgb mobilityRgb(double m, ColourScale scale) {
  if (std::isnan(m)) return unknownRgb(scale);
  const std::vector<VoxelRgb>& stops = colourStops(scale);
  const double at = std::clamp(m, 0.0, 1.0) * static_cast<double>(stops.size() - 1);
  const std::size_t i = std::min(static_cast<std::size_t>(at), stops.size() - 2);
  const double f = at - static_cast<double>(i);
  VoxelRgb out{};
  for (std::size_t c = 0; c < 3; ++c) {
    out[c] = static_cast<std::uint8_t>(std::lround((1 - f) * stops[i][c] + f * stops[i + 1][c]));
  }
  return out;
}

VoxelRgb mobilityRgb(const MobilityOcTreeNode& node, ColourScale scale) {
  return node.hasMobility() ? mobilityRgb(node.mobility(), scale) : unknownRgb(scale);
}

void saveOctovisColorTree(const MobilityOcTree& tree, const std::string& path) {
  saveOctovisColorTree(tree, path, [](const octomap::OcTreeKey&, const MobilityOcTreeNode& node) { return mobilityRgb(node); });
}

void saveOctovisColorTree(const MobilityOcTree& tree, const std::string& path,
                          const std::function<VoxelRgb(const octomap::OcTreeKey&, const MobilityOcTreeNode&)>& colour) {
  octomap::ColorOcTree out(tree.getResolution());
  forEachOccupiedVoxel(tree, [&](const MobilityOcTree::leaf_iterator& it) {
    // A pruned leaf covers 2^(16-depth) voxels per side: write each one.
    const unsigned int depth = it.getDepth();
    const unsigned int span = 1u << (tree.getTreeDepth() - depth);
    const octomap::OcTreeKey base = it.getIndexKey();
    for (unsigned int dx = 0; dx < span; ++dx) {
      for (unsigned int dy = 0; dy < span; ++dy) {
        for (unsigned int dz = 0; dz < span; ++dz) {
          const octomap::OcTreeKey k(static_cast<octomap::key_type>(base[0] + dx), static_cast<octomap::key_type>(base[1] + dy),
                                     static_cast<octomap::key_type>(base[2] + dz));
          const VoxelRgb c = colour(k, *it);
          out.setNodeValue(k, it->getLogOdds(), true);
          out.setNodeColor(k, c[0], c[1], c[2]);
        }
      }
    }
  });
  // ColorOcTree::updateInnerOccupancy() follows the root without checking it: an empty
  // tree (nothing in range in any frame) has none.
  if (out.size() > 0) out.updateInnerOccupancy();
  writeAtomically(path, [&](std::ostream& s) { return out.write(s); });
}

void saveSurfacePcd(const MobilityOcTree& tree, const std::string& path) {
  std::ostringstream body;
  std::size_t n = 0;
  char line[160];
  forEachOccupiedVoxel(tree, [&](const MobilityOcTree::leaf_iterator& it) {
    const bool known = it->hasMobility();
    std::snprintf(line, sizeof(line), "%.4f %.4f %.4f %.5f %.6g %d\n", it.getX(), it.getY(), it.getZ(),
                  known ? it->mobility() : std::nan(""), known ? it->variance() : std::nan(""), it->count());
    body << line;
    ++n;
  });
  writeAtomically(path, [&](std::ostream& s) {
    s << "# .PCD v0.7 - mobmap surface voxels (map frame); mobility nan = unknown\n"
      << "VERSION 0.7\nFIELDS x y z mobility variance count\nSIZE 4 4 4 4 4 4\nTYPE F F F F F I\nCOUNT 1 1 1 1 1 1\n"
      << "WIDTH " << n << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << n << "\nDATA ascii\n"
      << body.str();
    return static_cast<bool>(s);
  });
}

}  // namespace mobmap::mapping
