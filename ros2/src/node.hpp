#pragma once
// mobmap_ros2: the live node on ROS 2 without a ROS 2 client library, a Cyclone DDS
// participant that follows ROS 2's names, types and QoS (docs/ROS.md). The core is the
// ROS 1 node's (live/src/core.hpp).
#include "args.hpp"
#include "dds.hpp"

#include "core.hpp"

#include "mobmap/sources/tf_tree.hpp"

#include <atomic>
#include <condition_variable>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

namespace mobmap::ros2 {

/// What only the DDS front has.
struct DdsParams {
  std::uint32_t domain_id = 0;      ///< ROS_DOMAIN_ID
  bool use_sim_time = false;        ///< the clock from /clock
  double max_sample_mb = 64;        ///< larger samples are refused (DDS drops those over twice this)
  double receive_buffer_mb = 8;     ///< the socket receive buffer asked of the kernel (net.core.rmem_max caps it)
  std::string depth = "/camera/depth/image_rect_raw", camera_info, points = "points", imu = "imu";
};

/// TF as heard on /tf and /tf_static, for the core: 30 s of samples, interpolated as tf2 does.
class TfBuffer : public live::Transforms {
 public:
  /// Adds a TFMessage's transforms; the first error (two parents, a bad rotation) is returned.
  std::string add(const std::vector<sources::ros::Transform>& transforms, bool is_static);
  bool has(const std::string& frame) override;
  std::optional<std::string> root(const std::string& frame) override;
  std::optional<Eigen::Isometry3d> lookup(const std::string& target, const std::string& source, std::int64_t stamp_ns,
                                          std::string* error) override;

 private:
  std::mutex mutex_;
  sources::TfTree tree_;
  std::int64_t newest_ns_ = 0;
  std::size_t added_ = 0;
};

class Node {
 public:
  /// Reads the parameters and joins the domain; std::invalid_argument naming a parameter,
  /// DdsError when DDS cannot start.
  explicit Node(const Args& args);
  ~Node();
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;
  /// Receives until `stop` is set (or the core gives up), then stops cleanly; false when
  /// mapping could not start.
  bool run(const std::atomic<bool>& stop);

 private:
  void receive(const RawReader& reader, const std::uint8_t* data, std::size_t size,
               const std::function<void(const std::uint8_t*, std::size_t)>& handle);
  void onPublication(const Publication& p);
  void serve();
  void publishLoop();
  void publishCloud();
  void publishOccupancy();
  void publishGridMap();
  void publishOctomap();
  void publishStatus();
  [[nodiscard]] std::int64_t now() const;

  Args args_;
  DdsParams dp_;
  std::string node_fq_;
  TfBuffer tf_;
  std::unique_ptr<live::Core> core_;
  std::unique_ptr<Participant> participant_;
  std::vector<std::unique_ptr<RawReader>> readers_;
  std::unique_ptr<PublicationWatch> watch_;
  std::unique_ptr<Writer> cloud_, occupancy_, grid_map_, octomap_, status_, tf_static_;
  std::unique_ptr<Writer> save_reply_, clear_reply_;
  dds_entity_t save_request_ = 0, clear_request_ = 0, save_condition_ = 0, clear_condition_ = 0;
  std::unique_ptr<WaitSet> waitset_;
  std::atomic<std::int64_t> clock_ns_{0};
  std::atomic<bool> failed_{false};

  std::mutex publish_mutex_;
  std::condition_variable publish_wake_;
  bool publish_stop_ = false;
  std::thread publisher_;
  std::mutex seen_mutex_;
  std::set<std::string> wrong_types_;
  std::uint64_t publications_seen_ = 0, publications_gone_ = 0;
};

}  // namespace mobmap::ros2
