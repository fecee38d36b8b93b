#include "container.hpp"

#include "mobmap/sources/io_error.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <filesystem>

namespace mobmap::sources {
namespace {

namespace fs = std::filesystem;

// The files of one ROS 2 bag (openBagFolder), one after another; a message's ref names its file.
class Chain : public Container {
 public:
  explicit Chain(std::vector<std::unique_ptr<Container>> parts) : parts_(std::move(parts)) {}

  std::optional<ContainerFault> scan(const std::function<void(const RawMessage&)>& visit) override {
    for (std::size_t i = 0; i < parts_.size(); ++i) {
      std::vector<int> index;  // the part's topic -> the chain's
      auto fault = parts_[i]->scan([&](const RawMessage& m) {
        const auto& own = parts_[i]->topics();
        while (index.size() < own.size()) index.push_back(topicIndex(own[index.size()]));
        RawMessage out = m;
        out.topic = index[static_cast<std::size_t>(m.topic)];
        out.ref.file = static_cast<std::uint32_t>(i);
        visit(out);
      });
      const auto& own = parts_[i]->topics();
      while (index.size() < own.size()) index.push_back(topicIndex(own[index.size()]));
      if (fault) return fault;
    }
    return std::nullopt;
  }
  const std::vector<ContainerTopic>& topics() const override { return topics_; }
  std::vector<std::uint8_t> read(const MessageRef& ref) const override { return parts_.at(ref.file)->read(ref); }
  std::vector<std::string> files() const override {
    std::vector<std::string> out;
    for (const auto& p : parts_) {
      for (auto& f : p->files()) out.push_back(f);
    }
    return out;
  }
  std::string recovered() const override {
    std::string out = note_;
    for (const auto& p : parts_) {
      const std::string r = p->recovered();
      if (!r.empty()) out += (out.empty() ? "" : "; ") + r;
    }
    return out;
  }
  std::string note_;  // the folder's own (no metadata.yaml)

 private:
  int topicIndex(const ContainerTopic& t) {
    for (std::size_t i = 0; i < topics_.size(); ++i) {
      if (topics_[i].name == t.name && topics_[i].type == t.type) return static_cast<int>(i);
    }
    topics_.push_back(t);
    return static_cast<int>(topics_.size() - 1);
  }

  std::vector<std::unique_ptr<Container>> parts_;
  std::vector<ContainerTopic> topics_;
};

}  // namespace

std::string normaliseType(const std::string& type) {
  const auto at = type.find("/msg/");
  if (at == std::string::npos) return type;
  return type.substr(0, at) + "/" + type.substr(at + 5);
}

bool wireOf(const std::string& encoding, ros::Wire* wire) {
  if (encoding == "cdr") {
    *wire = ros::Wire::kCdr;
    return true;
  }
  if (encoding == "ros1") {
    *wire = ros::Wire::kRos1;
    return true;
  }
  return false;
}


// The .db3 and .mcap files of a folder, in rosbag2's order.
static std::vector<std::string> bagFiles(const std::string& dir) {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const auto ext = e.path().extension();
    if ((ext == ".db3" || ext == ".mcap") && e.is_regular_file(ec)) names.push_back(e.path().filename().string());
  }
  // rosbag2 numbers its files NAME_0, NAME_1, ... NAME_10: in that order, not the text's.
  std::sort(names.begin(), names.end(), [](const std::string& a, const std::string& b) {
    const auto number = [](const std::string& n, std::string* stem) {
      const std::string base = fs::path(n).stem().string();
      const auto us = base.find_last_of('_');
      if (us == std::string::npos || us + 1 == base.size() || base.find_first_not_of("0123456789", us + 1) != std::string::npos ||
          base.size() - us > 10) {
        *stem = base;
        return -1L;
      }
      *stem = base.substr(0, us);
      return std::stol(base.substr(us + 1));
    };
    std::string sa, sb;
    const long na = number(a, &sa), nb = number(b, &sb);
    return sa != sb ? a < b : na != nb ? na < nb : a < b;
  });
  return names;
}

bool isBagFolderWithoutMetadata(const std::string& dir) {
  std::error_code ec;
  return fs::is_directory(dir, ec) && !fs::exists(fs::path(dir) / "metadata.yaml", ec) && !bagFiles(dir).empty();
}

// A ROS 2 bag folder: its files in metadata.yaml's order (every .db3 / .mcap in it
// when metadata.yaml does not list them, or when its recorder died before writing it).
std::unique_ptr<Container> openBagFolder(const std::string& dir) {
  const fs::path meta = fs::path(dir) / "metadata.yaml";
  std::vector<std::string> names;
  std::error_code ec;
  const bool has_meta = fs::exists(meta, ec);
  if (has_meta) {
    try {
      const YAML::Node root = YAML::LoadFile(meta.string());
      const YAML::Node info = root["rosbag2_bagfile_information"];
      if (!info) throw IoError(meta.string(), "has no rosbag2_bagfile_information: not a ROS 2 bag's metadata");
      if (const YAML::Node files = info["relative_file_paths"]) {
        for (const auto& f : files) names.push_back(f.as<std::string>());
      }
    } catch (const YAML::Exception& e) {
      throw IoError(meta.string(), std::string("cannot be read as YAML: ") + e.what());
    }
  }
  if (names.empty()) names = bagFiles(dir);
  if (names.empty()) throw IoError(dir, "a ROS 2 bag folder without .db3 or .mcap files");
  std::vector<std::unique_ptr<Container>> parts;
  for (const auto& name : names) {
    const fs::path p = fs::path(dir) / name;
    const fs::path rel(name);
    if (rel.is_absolute() || rel.empty() || std::any_of(rel.begin(), rel.end(), [](const fs::path& c) { return c == ".."; })) {
      throw IoError(meta.string(), "lists \"" + name + "\", which is not a file inside the bag folder");
    }
    const auto ext = p.extension();
    if (ext == ".db3") {
      parts.push_back(openDb3(p.string()));
    } else if (ext == ".mcap") {
      parts.push_back(openMcap(p.string()));
    } else {
      throw IoError(p.string(), "a bag file mobmap does not read (ROS 2 bags store .db3 or .mcap files)");
    }
  }
  auto chain = std::make_unique<Chain>(std::move(parts));
  if (!has_meta) {
    chain->note_ = dir + ": no metadata.yaml (its recorder did not finish): its " + std::to_string(names.size()) + " bag file" +
                   (names.size() == 1 ? "" : "s") + " read in order, as `ros2 bag reindex` would";
  }
  return chain;
}


}  // namespace mobmap::sources
