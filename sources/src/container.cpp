#include "container.hpp"

namespace mobmap::sources {
namespace {

// The files of one ROS 2 bag, one after another; a message's ref names its file.
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

std::unique_ptr<Container> openChain(std::vector<std::unique_ptr<Container>> parts) {
  return std::make_unique<Chain>(std::move(parts));
}

}  // namespace mobmap::sources
