// The live nodes' core (live/src/core.cpp) with a TF of the test's own: which world
// frame it maps in when TF's parts arrive in either order.
#include "core.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <map>
#include <mutex>
#include <thread>

namespace mobmap::live {
namespace {

// A TF tree of parent links, every transform the identity.
class TreeTf : public Transforms {
 public:
  void link(const std::string& parent, const std::string& child) {
    std::lock_guard<std::mutex> lock(mutex_);
    parent_[child] = parent;
  }
  bool has(const std::string& frame) override {
    std::lock_guard<std::mutex> lock(mutex_);
    if (parent_.count(frame)) return true;
    for (const auto& [child, parent] : parent_) {
      if (parent == frame) return true;
    }
    return false;
  }
  std::optional<std::string> root(const std::string& frame) override {
    if (!has(frame)) return std::nullopt;
    std::lock_guard<std::mutex> lock(mutex_);
    std::string f = frame;
    for (auto it = parent_.find(f); it != parent_.end(); it = parent_.find(f)) f = it->second;
    return f;
  }
  std::optional<Eigen::Isometry3d> lookup(const std::string& target, const std::string& source, std::int64_t,
                                          std::string* error) override {
    if (root(source) && root(source) == root(target)) return Eigen::Isometry3d::Identity();
    if (error) *error = "not connected";
    return std::nullopt;
  }

 private:
  std::mutex mutex_;
  std::map<std::string, std::string> parent_;
};

// Feeds one 4 x 3 depth image of `frame` and waits until the core has accounted for it
// (fused, dropped, late or unreadable), as its status says.
void feedOne(Core& core, std::uint64_t n) {
  sources::ros::Header h;
  h.frame_id = "camera";
  h.stamp_ns = static_cast<std::int64_t>(n) * 33'000'000;
  core.depth(h, 1000.0, [] {
    perception::DepthImage d;
    d.width = 4;
    d.height = 3;
    d.depth_m.assign(12, 1.0f);
    return d;
  });
  for (;;) {
    const auto s = nlohmann::json::parse(core.status());
    const auto done = s["fused"].get<std::uint64_t>() + s["dropped"].get<std::uint64_t>() + s["late"].get<std::uint64_t>() +
                      s["unreadable"].get<std::uint64_t>();
    if (done >= n) return;
    std::this_thread::yield();
  }
}

Hooks quietHooks() {
  Hooks h;
  h.now_ns = [] { return std::int64_t{0}; };
  return h;
}

// /tf_static (base_link -> camera) heard before /tf (map -> odom -> base_link): the
// first images wait instead of making base_link the world frame, and once the robot's
// odometry and map are heard the node maps in `map`.
TEST(LiveCore, AStaticTfHeardBeforeTheRobotsTfDoesNotChooseTheWorldFrame) {
  TreeTf tf;
  tf.link("base_link", "camera");
  Params p;
  Core core(p, tf, quietHooks(), "/camera/depth");
  feedOne(core, 1);
  feedOne(core, 2);
  EXPECT_EQ(core.worldFrame(), "");
  tf.link("odom", "base_link");
  tf.link("map", "odom");
  feedOne(core, 3);
  EXPECT_EQ(core.worldFrame(), "map");
}

// A camera on a robot with no odometry at all: after ten images that found neither map
// nor odom, the root of its tree is the world frame.
TEST(LiveCore, WithoutMapOrOdomTheCamerasRootIsTakenAfterTenImages) {
  TreeTf tf;
  tf.link("base_link", "camera");
  Params p;
  Core core(p, tf, quietHooks(), "/camera/depth");
  for (std::uint64_t n = 1; n < 10; ++n) {
    feedOne(core, n);
    EXPECT_EQ(core.worldFrame(), "") << n;
  }
  feedOne(core, 10);
  EXPECT_EQ(core.worldFrame(), "base_link");
}

}  // namespace
}  // namespace mobmap::live
