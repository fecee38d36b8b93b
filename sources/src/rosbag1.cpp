// ROS 1 bags (.bag, format 2.0: uncompressed, bz2 or lz4 chunks) read through Debian's
// rosbag_storage. Messages come out in ROS 1's serialisation and are decoded by
// ros_messages.cpp; no ROS runtime is involved.

#include "container.hpp"

#include "mobmap/sources/io_error.hpp"

#include <rosbag/bag.h>
#include <rosbag/exceptions.h>
#include <rosbag/query.h>
#include <rosbag/view.h>
#include <ros/serialization.h>

#include <fstream>
#include <map>
#include <mutex>

namespace mobmap::sources {
namespace {

std::int64_t nanoseconds(const ::ros::Time& t) { return static_cast<std::int64_t>(t.toNSec()); }

class Ros1Container : public Container {
 public:
  explicit Ros1Container(const std::string& path) : path_(path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(path, "cannot open");
    char magic[13] = {0};
    in.read(magic, sizeof magic);
    const std::string version(magic, static_cast<std::size_t>(in.gcount()));
    if (version.rfind("#ROSBAG V", 0) != 0) throw IoError(path, "not a ROS 1 bag (no #ROSBAG header)");
    if (version != "#ROSBAG V2.0\n") {
      throw IoError(path, "a ROS 1 bag of format " + version.substr(9, 3) + "; mobmap reads format 2.0 (`rosbag fix` converts it)");
    }
    bag_.open(path, rosbag::bagmode::Read);  // openRos1Bag() reads a bag without its index another way
  }

  std::optional<ContainerFault> scan(const std::function<void(const RawMessage&)>& visit) override {
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<std::uint8_t> buffer;
    std::map<std::pair<int, std::int64_t>, std::uint64_t> ordinal;  // (topic, time) -> messages seen
    std::int64_t last = 0;
    try {
      rosbag::View view(bag_);
      for (const rosbag::MessageInstance& m : view) {
        const int topic = topicIndex(m.getTopic(), m.getDataType());
        const std::int64_t t = nanoseconds(m.getTime());
        last = t;
        buffer.resize(m.size());
        ::ros::serialization::OStream out(buffer.data(), static_cast<std::uint32_t>(buffer.size()));
        m.write(out);
        RawMessage raw;
        raw.topic = topic;
        raw.log_time_ns = t;
        raw.data = buffer.data();
        raw.size = buffer.size();
        raw.ref = {0, static_cast<std::uint64_t>(t), static_cast<std::uint64_t>(topic), ordinal[{topic, t}]++};
        visit(raw);
      }
    } catch (const ::ros::Exception& e) {  // rosbag's exceptions among them
      return ContainerFault{path_ + ": its messages after " + std::to_string(static_cast<double>(last) * 1e-9) +
                            " s cannot be read (" + e.what() + ")"};
    }
    return std::nullopt;
  }

  const std::vector<ContainerTopic>& topics() const override { return topics_; }
  std::vector<std::string> files() const override { return {path_}; }

  std::vector<std::uint8_t> read(const MessageRef& ref) const override {
    // b: the topic, a: the time, c: which of the topic's messages at that time.
    std::lock_guard<std::mutex> lock(mutex_);
    const ContainerTopic& topic = topics_.at(static_cast<std::size_t>(ref.b));
    ::ros::Time t;
    t.fromNSec(ref.a);
    try {
      rosbag::View view(bag_, rosbag::TopicQuery(topic.name), t, t);
      std::uint64_t n = 0;
      for (const rosbag::MessageInstance& m : view) {
        if (m.getDataType() != topic.type || n++ != ref.c) continue;
        std::vector<std::uint8_t> bytes(m.size());
        ::ros::serialization::OStream out(bytes.data(), static_cast<std::uint32_t>(bytes.size()));
        m.write(out);
        return bytes;
      }
    } catch (const ::ros::Exception& e) {
      throw IoError(path_, "a message on " + topic.name + " cannot be read (" + e.what() + ")");
    }
    throw IoError(path_, "a message on " + topic.name + " is no longer where the bag's index put it");
  }

 private:
  int topicIndex(const std::string& name, const std::string& type) {
    for (std::size_t i = 0; i < topics_.size(); ++i) {
      if (topics_[i].name == name && topics_[i].type == type) return static_cast<int>(i);
    }
    topics_.push_back({name, type, "ros1"});
    return static_cast<int>(topics_.size() - 1);
  }

  std::string path_;
  mutable rosbag::Bag bag_;
  mutable std::mutex mutex_;
  std::vector<ContainerTopic> topics_;
};

}  // namespace

std::unique_ptr<Container> openRos1Bag(const std::string& path) {
  // A bag without its index (cut short, or its recorder killed before closing it) is
  // read by scanning its chunks, as `rosbag reindex` does.
  if (isActiveRos1Bag(path)) return openRos1Unindexed(path);
  try {
    return std::make_unique<Ros1Container>(path);
  } catch (const rosbag::BagUnindexedException&) {
    return openRos1Unindexed(path);
  } catch (const rosbag::BagIOException&) {
    return openRos1Unindexed(path);
  } catch (const rosbag::BagException& e) {
    throw IoError(path, std::string("not a ROS 1 bag mobmap reads (") + e.what() + ")");
  }
}

}  // namespace mobmap::sources
