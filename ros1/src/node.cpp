// mobmap_node: images in, LiveMapper in the middle, map messages out.
#include "node.hpp"

#include "outputs.hpp"

#include "depth_decode.hpp"
#include "undistort.hpp"

#include "mobmap/builder/config.hpp"
#include "mobmap/builder/files.hpp"
#include "mobmap/mapping/layers.hpp"
#include "mobmap/util/field_error.hpp"
#include "serve/api.hpp"
#include "serve/http_server.hpp"

#include <geometry_msgs/TransformStamped.h>
#include <std_msgs/String.h>
#include <tf2/exceptions.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>

namespace mobmap::ros1 {
namespace {

Eigen::Isometry3d toEigen(const geometry_msgs::Transform& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(t.rotation.w, t.rotation.x, t.rotation.y, t.rotation.z).normalized().toRotationMatrix();
  T.translation() = Eigen::Vector3d(t.translation.x, t.translation.y, t.translation.z);
  return T;
}

std::int64_t nanoseconds(const ::ros::Time& t) { return static_cast<std::int64_t>(t.toNSec()); }

template <typename T>
void param(const ::ros::NodeHandle& pnh, const std::string& name, T& value) {
  pnh.param(name, value, value);
}

void positive(double v, const std::string& name, bool zero_ok = false) {
  if (!std::isfinite(v) || v < 0 || (!zero_ok && v == 0)) {
    throw std::invalid_argument("~" + name + " must be a finite number " + (zero_ok ? "of at least 0" : "above 0") +
                                ", got " + std::to_string(v));
  }
}

}  // namespace

double Node::Gauge::quantile(double q) const {
  if (ms.empty()) return std::nan("");
  std::vector<double> v(ms.begin(), ms.end());
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

NodeParams readParams(const ::ros::NodeHandle& pnh) {
  NodeParams p;
  param(pnh, "world_frame", p.world_frame);
  param(pnh, "base_frame", p.base_frame);
  param(pnh, "map_frame", p.map_frame);
  param(pnh, "compressed", p.compressed);
  param(pnh, "use_points", p.use_points);
  param(pnh, "use_imu", p.use_imu);
  param(pnh, "gravity", p.gravity);
  param(pnh, "resolution", p.resolution);
  param(pnh, "max_range", p.max_range);
  param(pnh, "config", p.config);
  param(pnh, "threads", p.threads);
  param(pnh, "tf_wait", p.tf_wait);
  param(pnh, "max_pose_gap", p.max_pose_gap);
  param(pnh, "warn_period", p.warn_period);
  param(pnh, "cloud_rate", p.cloud_rate);
  param(pnh, "occupancy_rate", p.occupancy_rate);
  param(pnh, "grid_map_rate", p.grid_map_rate);
  param(pnh, "octomap_rate", p.octomap_rate);
  param(pnh, "status_rate", p.status_rate);
  param(pnh, "grid_map_size", p.grid_map_size);
  param(pnh, "grid_map_resolution", p.grid_map_resolution);
  param(pnh, "clearance", p.clearance);
  param(pnh, "occupancy_cell", p.occupancy_cell);
  param(pnh, "save_path", p.save_path);
  param(pnh, "save_on_exit", p.save_on_exit);
  param(pnh, "http_port", p.http_port);
  param(pnh, "http_address", p.http_address);
  mapping::RobotParams& r = p.reach.robot;
  param(pnh, "sole_length", r.sole_length_m);
  param(pnh, "sole_width", r.sole_width_m);
  param(pnh, "min_mobility", r.min_mobility);
  param(pnh, "max_tilt", r.max_tilt_deg);
  param(pnh, "max_step", r.max_step_m);
  param(pnh, "max_stride", r.max_stride_m);
  param(pnh, "swing_clearance", r.swing_clearance_m);
  param(pnh, "max_gap", r.max_gap_m);
  param(pnh, "stance_width", r.stance_width_m);
  p.reach.start_rule = mapping::ReachParams::Start::kLargestLevel;
  for (const auto& [v, name] : std::vector<std::pair<double, const char*>>{
           {p.resolution, "resolution"}, {p.max_range, "max_range"}, {p.grid_map_size, "grid_map_size"},
           {p.grid_map_resolution, "grid_map_resolution"}, {p.clearance, "clearance"}, {p.occupancy_cell, "occupancy_cell"}}) {
    positive(v, name);
  }
  for (const auto& [v, name] : std::vector<std::pair<double, const char*>>{
           {p.tf_wait, "tf_wait"}, {p.max_pose_gap, "max_pose_gap"}, {p.warn_period, "warn_period"}, {p.cloud_rate, "cloud_rate"},
           {p.occupancy_rate, "occupancy_rate"}, {p.grid_map_rate, "grid_map_rate"}, {p.octomap_rate, "octomap_rate"},
           {p.status_rate, "status_rate"}}) {
    positive(v, name, true);
  }
  if (p.grid_map_size / p.grid_map_resolution > 2000) throw std::invalid_argument("~grid_map_size / ~grid_map_resolution: at most 2000 cells a side");
  if (!p.gravity.empty() && p.gravity.size() != 3) throw std::invalid_argument("~gravity must be 3 numbers (down, world frame)");
  if (p.threads < 0 || p.threads > mapping::LiveMapper::kMaxPerceptionThreads) throw std::invalid_argument("~threads must be 0 to 256");
  if (p.http_port > 65535) throw std::invalid_argument("~http_port must be at most 65535");
  try {
    mapping::validate(p.reach);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("robot limits: ") + e.what());
  }
  return p;
}

Node::Node(::ros::NodeHandle nh, ::ros::NodeHandle pnh, NodeParams params)
    : nh_(std::move(nh)), pnh_(std::move(pnh)), p_(std::move(params)), mapper_config_(mapperConfig(p_)),
      tf_(::ros::Duration(30.0)), tf_listener_(tf_, nh_), it_(nh_) {
  world_frame_ = p_.world_frame;
  // Depth as the usual camera drivers name it unless remapped (depth:=...).
  const bool depth_remapped = ::ros::names::resolve("depth") != ::ros::names::resolve("depth", false);
  const std::string depth = depth_remapped ? std::string("depth") : std::string("/camera/depth/image_rect_raw");
  const std::string depth_resolved = ::ros::names::resolve(depth);
  const bool info_remapped = ::ros::names::resolve("camera_info") != ::ros::names::resolve("camera_info", false);
  // The camera_info beside the depth topic, as the bag reader chooses it.
  const std::string info = info_remapped ? std::string("camera_info")
                                         : depth_resolved.substr(0, depth_resolved.rfind('/')) + "/camera_info";
  info_sub_ = nh_.subscribe(info, 2, &Node::onInfo, this);
  if (p_.compressed) {
    compressed_sub_ = nh_.subscribe(depth_resolved + "/compressedDepth", 5, &Node::onCompressed, this);
  } else {
    image_sub_ = it_.subscribe(depth, 5, &Node::onImage, this);
  }
  if (p_.use_points) points_sub_ = nh_.subscribe("points", 5, &Node::onPoints, this);
  if (p_.use_imu) imu_sub_ = nh_.subscribe("imu", 50, &Node::onImu, this);
  ROS_INFO("mobmap: depth from %s%s, camera_info from %s", depth_resolved.c_str(), p_.compressed ? "/compressedDepth" : "",
           ::ros::names::resolve(info).c_str());

  cloud_pub_ = pnh_.advertise<sensor_msgs::PointCloud2>("mobility_cloud", 1, true);
  occupancy_pub_ = pnh_.advertise<nav_msgs::OccupancyGrid>("occupancy", 1, true);
  grid_map_pub_ = pnh_.advertise<msg::GridMap>("elevation_map", 1, true);
  octomap_pub_ = pnh_.advertise<msg::Octomap>("octomap_binary", 1, true);
  status_pub_ = pnh_.advertise<std_msgs::String>("status", 10, true);
  save_srv_ = pnh_.advertiseService("save_map", &Node::onSave, this);
  clear_srv_ = pnh_.advertiseService("clear_map", &Node::onClear, this);
  const auto every = [&](double rate, void (Node::*publish)()) {
    if (rate > 0) timers_.push_back(nh_.createWallTimer(::ros::WallDuration(1.0 / rate), [this, publish](const ::ros::WallTimerEvent&) { (this->*publish)(); }));
  };
  every(p_.cloud_rate, &Node::publishCloud);
  every(p_.occupancy_rate, &Node::publishOccupancy);
  every(p_.grid_map_rate, &Node::publishGridMap);
  every(p_.octomap_rate, &Node::publishOctomap);
  every(p_.status_rate, &Node::publishStatus);
  if (p_.http_port >= 0) {
    app::serve::ServedMap first;
    first.map = std::make_shared<mapping::MobilityMap>();
    first.building = true;
    served_ = std::make_unique<app::serve::MapSource>(std::move(first));
    api_ = std::make_unique<app::serve::Api>("live: " + depth_resolved, *served_);
    http_ = std::make_unique<app::serve::HttpServer>(*api_);
    const int port = http_->bind(p_.http_address, p_.http_port);
    http_thread_ = std::thread([this] { http_->run(); });
    ROS_INFO("mobmap: HTTP API on http://%s:%d", p_.http_address.c_str(), port);
    pnh_.setParam("http_port_bound", port);
    every(2.0, &Node::publishServed);
  }
  feeder_ = std::thread([this] { feed(); });
}

Node::~Node() {
  shutdown();
  if (http_) http_->stop();
  if (http_thread_.joinable()) http_thread_.join();
}

void Node::warn(const std::string& key, const std::string& text) {
  const ::ros::WallTime now = ::ros::WallTime::now();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = warned_.find(key);
    if (it != warned_.end() && (now - it->second).toSec() < p_.warn_period) return;
    warned_[key] = now;
  }
  ROS_WARN("mobmap: %s", text.c_str());
}

void Node::onInfo(const sensor_msgs::CameraInfoConstPtr& m) {
  std::lock_guard<std::mutex> lock(mutex_);
  info_ = *m;
}

void Node::takeDepth(const std_msgs::Header& header, double units_per_m,
                     const std::function<perception::DepthImage()>& decode) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++received_;
  }
  Pending p;
  try {
    p.depth = decode();
  } catch (const std::exception& e) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      ++unreadable_;
    }
    warn("unreadable", e.what());
    return;
  }
  p.units_per_m = units_per_m;
  p.frame_id = header.frame_id;
  p.stamp = header.stamp;
  offer(std::move(p));
}

void Node::onImage(const sensor_msgs::ImageConstPtr& m) {
  sources::ros::Image img;
  img.header.stamp_ns = nanoseconds(m->header.stamp);
  img.header.frame_id = m->header.frame_id;
  img.height = m->height;
  img.width = m->width;
  img.encoding = m->encoding;
  img.big_endian = m->is_bigendian != 0;
  img.step = m->step;
  img.data = m->data.data();
  img.data_size = m->data.size();
  takeDepth(m->header, m->encoding == "32FC1" ? 1.0 : 1000.0,
            [&] { return sources::depthFromImage(img, "image on " + image_sub_.getTopic()); });
}

void Node::onCompressed(const sensor_msgs::CompressedImageConstPtr& m) {
  sources::ros::CompressedImage img;
  img.header.stamp_ns = nanoseconds(m->header.stamp);
  img.header.frame_id = m->header.frame_id;
  img.format = m->format;
  img.data = m->data.data();
  img.data_size = m->data.size();
  takeDepth(m->header, sources::compressedDepthEncoding(m->format) == "32FC1" ? 1.0 : 1000.0,
            [&] { return sources::depthFromCompressed(img, "image on " + compressed_sub_.getTopic()); });
}

void Node::onPoints(const sensor_msgs::PointCloud2ConstPtr& m) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++received_;
  }
  int offsets[3] = {-1, -1, -1};
  for (const auto& f : m->fields) {
    const int axis = f.name == "x" ? 0 : f.name == "y" ? 1 : f.name == "z" ? 2 : -1;
    if (axis >= 0 && f.datatype == sensor_msgs::PointField::FLOAT32 && f.count == 1) offsets[axis] = static_cast<int>(f.offset);
  }
  const std::size_t n = static_cast<std::size_t>(m->width) * m->height;
  if (offsets[0] < 0 || offsets[1] < 0 || offsets[2] < 0 || m->is_bigendian || m->point_step < 12 ||
      m->row_step < m->point_step * m->width || m->data.size() < static_cast<std::size_t>(m->row_step) * m->height ||
      offsets[0] + 4 > static_cast<int>(m->point_step) || offsets[1] + 4 > static_cast<int>(m->point_step) ||
      offsets[2] + 4 > static_cast<int>(m->point_step)) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      ++unreadable_;
    }
    warn("points", "a PointCloud2 on " + points_sub_.getTopic() +
                       " is not read: it needs little-endian float32 x, y, z fields within its points and rows");
    return;
  }
  Pending p;
  p.cloud = true;
  p.points.reserve(n);
  for (std::uint32_t r = 0; r < m->height; ++r) {
    for (std::uint32_t c = 0; c < m->width; ++c) {
      const std::uint8_t* at = m->data.data() + static_cast<std::size_t>(r) * m->row_step + static_cast<std::size_t>(c) * m->point_step;
      float v[3];
      for (int k = 0; k < 3; ++k) std::memcpy(&v[k], at + offsets[k], 4);
      p.points.emplace_back(v[0], v[1], v[2]);
    }
  }
  p.width = static_cast<int>(m->width);
  p.height = static_cast<int>(m->height);
  p.frame_id = m->header.frame_id;
  p.stamp = m->header.stamp;
  offer(std::move(p));
}

void Node::onImu(const sensor_msgs::ImuConstPtr& m) {
  std::string error;
  std::string world;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (mapper_ || world_frame_.empty() || imu_down_.size() >= 50) return;
    world = world_frame_;
  }
  const auto T = lookup(world, m->header.frame_id, m->header.stamp, 0.0, &error);
  if (!T) return;
  // At rest an accelerometer reads the reaction to gravity: up.
  const Eigen::Vector3d a(m->linear_acceleration.x, m->linear_acceleration.y, m->linear_acceleration.z);
  if (!a.allFinite() || a.norm() < 5.0 || a.norm() > 15.0) return;  // moving, or not m/s^2
  std::lock_guard<std::mutex> lock(mutex_);
  imu_down_.push_back(-(T->linear() * a).normalized());
}

void Node::offer(Pending&& p) {
  p.arrived = ::ros::WallTime::now();
  std::lock_guard<std::mutex> lock(mutex_);
  if (stopping_) return;
  if (pending_) ++replaced_;  // the feeder is busy: the newest is kept
  pending_ = std::move(p);
  wake_.notify_one();
}

std::optional<Eigen::Isometry3d> Node::lookup(const std::string& target, const std::string& source, const ::ros::Time& t,
                                              double wait_s, std::string* error) {
  // Waits on the wall clock: under simulated time a clock that stops (a bag's end) must
  // not hold a frame forever, as tf2's own timeout would.
  const ::ros::WallTime until = ::ros::WallTime::now() + ::ros::WallDuration(wait_s);
  try {
    for (;;) {
      if (tf_.tf2::BufferCore::canTransform(target, source, t, error)) {
        return toEigen(tf_.lookupTransform(target, source, t).transform);
      }
      if (::ros::WallTime::now() >= until) return std::nullopt;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        if (stopping_) return std::nullopt;
      }
      ::ros::WallDuration(0.002).sleep();
    }
  } catch (const tf2::TransformException& e) {
    if (error) *error = e.what();
    return std::nullopt;
  }
}

bool Node::chooseWorldFrame(const std::string& camera_frame) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!world_frame_.empty()) return true;
  // As the bag reader chooses: map when TF has it, else odom, else the camera's root.
  for (const char* f : {"map", "odom"}) {
    if (tf_._frameExists(f)) {
      world_frame_ = f;
      break;
    }
  }
  if (world_frame_.empty()) {
    std::string frame = camera_frame, parent;
    for (int depth = 0; depth < 100 && tf_._getParent(frame, ::ros::Time(0), parent); ++depth) frame = parent;
    if (frame == camera_frame && !tf_._frameExists(camera_frame)) return false;
    world_frame_ = frame;
  }
  ROS_INFO("mobmap: world frame %s", world_frame_.c_str());
  return true;
}

std::optional<Eigen::Vector3d> Node::gravityDown() {
  if (p_.gravity.size() == 3) return Eigen::Vector3d(p_.gravity[0], p_.gravity[1], p_.gravity[2]).normalized();
  std::lock_guard<std::mutex> lock(mutex_);
  if (world_frame_ == "map" || world_frame_ == "odom") return Eigen::Vector3d(0, 0, -1);  // REP 105: z up
  if (imu_down_.size() >= 30) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const auto& d : imu_down_) sum += d;
    return sum.normalized();
  }
  return std::nullopt;
}

mapping::LiveMapper::Config Node::mapperConfig(const NodeParams& p) {
  mapping::LiveMapper::Config c;
  builder::Config config = p.config.empty() ? builder::Config{} : builder::loadConfig(p.config);
  if (p.config.empty() || !config.mapping_max_range_set) config.perception.max_range_m = p.max_range;
  config.mapping.resolution_m = p.resolution;
  config.mapping.max_range_m = config.perception.max_range_m;
  mapping::validate(config.mapping);
  c.map = config.mapping;
  c.perception = config.perception;
  c.model = builder::makeModel(config);
  const unsigned cores = std::max(2u, std::thread::hardware_concurrency());
  c.perception_threads = p.threads > 0 ? p.threads : static_cast<int>(cores - 1);
  c.queue_capacity = 1;
  c.when_busy = mapping::LiveMapper::WhenBusy::kKeepNewest;
  c.serve_snapshots = true;
  return c;
}

void Node::startMapper(const Eigen::Vector3d& down) {
  mapping::LiveMapper::Config c = mapper_config_;
  c.gravity_down_world = down;
  const std::uint64_t generation = ++mapper_generation_;
  c.on_frame = [this, generation](const mapping::FrameReport& r) {
    if (generation == mapper_generation_.load()) onFrame(r);
  };
  mapper_ = std::make_unique<mapping::LiveMapper>(std::move(c));
  ROS_INFO("mobmap: mapping in %s at %.3f m, gravity (%.3f, %.3f, %.3f), %d perception threads", world_frame_.c_str(),
           mapper_config_.map.resolution_m, down.x(), down.y(), down.z(), mapper_config_.perception_threads);
}

void Node::feed() {
  for (;;) {
    Pending p;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stopping_ || pending_.has_value(); });
      if (stopping_) return;
      p = std::move(*pending_);
      pending_.reset();
    }
    if (!chooseWorldFrame(p.frame_id)) {
      warn("world", "no TF yet for the camera frame " + p.frame_id + ": waiting for /tf and /tf_static");
      std::lock_guard<std::mutex> lock(mutex_);
      ++late_;
      continue;
    }
    std::string error;
    std::string world;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      world = world_frame_;
    }
    const auto T = lookup(world, p.frame_id, p.stamp, p_.tf_wait, &error);
    if (!T) {
      warn("tf", "no pose for an image of " + p.frame_id + " in " + world + " within " + std::to_string(p_.tf_wait) +
                     " s of its stamp: " + error);
      std::lock_guard<std::mutex> lock(mutex_);
      ++late_;
      continue;
    }
    const std::optional<Eigen::Vector3d> down = gravityDown();
    if (!down) {
      warn("gravity", "waiting for gravity: the world frame " + world +
                          " does not say where down is; set ~gravity or ~use_imu with an imu topic");
      std::lock_guard<std::mutex> lock(mutex_);
      ++late_;
      continue;
    }
    std::optional<sensor_msgs::CameraInfo> info;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      info = info_;
      if (!mapper_) {
        try {
          startMapper(*down);
        } catch (const std::exception& e) {
          ROS_ERROR("mobmap: cannot start mapping: %s", e.what());
          stopping_ = true;
          ::ros::requestShutdown();
          return;
        }
      }
    }
    try {
      if (p.cloud) {
        mapping::CloudFrame f;
        f.points = std::move(p.points);
        f.width = p.width;
        f.height = p.height;
        f.T_world_camera = *T;
        f.stamp_s = p.stamp.toSec();
        std::lock_guard<std::mutex> lock(mutex_);
        unit_ = {1.0, true};
        trajectory_world_.push_back(T->translation());
        mapper_->push(std::move(f));
      } else {
        if (!info) {
          warn("camera_info", "no camera_info yet: images wait for one");
          std::lock_guard<std::mutex> lock(mutex_);
          ++late_;
          continue;
        }
        if (static_cast<int>(info->width) != p.depth.width || static_cast<int>(info->height) != p.depth.height) {
          warn("size", "images are " + std::to_string(p.depth.width) + " x " + std::to_string(p.depth.height) +
                           " but the camera_info says " + std::to_string(info->width) + " x " + std::to_string(info->height));
          std::lock_guard<std::mutex> lock(mutex_);
          ++unreadable_;
          continue;
        }
        mapping::DepthFrame f;
        f.intrinsics = {static_cast<int>(info->width), static_cast<int>(info->height), info->K[0], info->K[4], info->K[2], info->K[5]};
        const bool distorted = std::any_of(info->D.begin(), info->D.end(), [](double d) { return d != 0.0; });
        if (distorted && info->D.size() >= 4 && info->distortion_model == "plumb_bob") {
          f.depth = sources::Undistorter(f.intrinsics, std::vector<double>(info->D.begin(), info->D.end())).apply(p.depth);
        } else {
          if (distorted) {
            warn("distortion", "the camera_info's " + info->distortion_model +
                                   " distortion is not undone (plumb_bob is): the images are mapped as they are");
          }
          f.depth = std::move(p.depth);
        }
        f.T_world_camera = *T;
        f.stamp_s = p.stamp.toSec();
        std::lock_guard<std::mutex> lock(mutex_);
        unit_ = {p.units_per_m, false};
        arrival_.add((::ros::WallTime::now() - p.arrived).toSec() * 1e3);
        trajectory_world_.push_back(T->translation());
        mapper_->push(std::move(f));
      }
    } catch (const std::exception& e) {
      warn("push", std::string("a frame was refused: ") + e.what());
      std::lock_guard<std::mutex> lock(mutex_);
      ++unreadable_;
    }
  }
}

void Node::onFrame(const mapping::FrameReport& r) {
  // On LiveMapper's fusion thread.
  const double latency_ms = (::ros::Time::now().toSec() - r.stamp_s) * 1e3;
  std::vector<std::string> said;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!r.fused) {
      ++unreadable_;
    } else {
      map_stamp_.fromSec(r.stamp_s);
      latency_.add(latency_ms);
      perception_.add(r.perception_ms);
      fusion_.add(r.fusion_ms);
      if (!r.ground_found) ++no_ground_;
      said = checks_.add("frame at " + std::to_string(r.stamp_s), r.range,
                         r.ground_found ? std::optional<double>(r.ground_distance_m) : std::nullopt, unit_);
    }
  }
  if (!r.fused) warn("perception", "a frame failed perception: " + r.error);
  for (const std::string& s : said) warn("check:" + s.substr(0, 40), s);
  if (r.fused && !r.ground_found) {
    warn("ground", "no ground found in a frame: it is mapped, but its mobility may be poor (is the camera's pose right?)");
  }
}

std::shared_ptr<const mapping::MobilityMap> Node::snapshot(::ros::Time* stamp) const {
  // The stamp first: a frame's stamp is set after its map is published, so the map taken
  // holds at least the frame the stamp names.
  std::lock_guard<std::mutex> lock(mutex_);
  if (!mapper_ || map_stamp_.isZero()) return nullptr;
  if (stamp) *stamp = map_stamp_;
  return mapper_->snapshot();
}

std::optional<Eigen::Vector3d> Node::baseInMap(const mapping::MobilityMap& map) {
  std::string world, error;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    world = world_frame_;
  }
  const auto T = lookup(world, p_.base_frame, ::ros::Time(0), 0.0, &error);
  if (!T) {
    warn("base", "no pose of the base frame " + p_.base_frame + " in " + world + ": " + error);
    return std::nullopt;
  }
  return map.worldToMap(T->translation());
}

void Node::publishCloud() {
  if (cloud_pub_.getNumSubscribers() == 0) return;
  ::ros::Time stamp;
  const auto map = snapshot(&stamp);
  if (!map || stamp == published_[0]) return;
  published_[0] = stamp;
  cloud_pub_.publish(mobilityCloud(*map, world_frame_, stamp));
}

void Node::publishOccupancy() {
  if (occupancy_pub_.getNumSubscribers() == 0) return;
  ::ros::Time stamp;
  const auto map = snapshot(&stamp);
  if (!map || stamp == published_[1]) return;
  const auto base = baseInMap(*map);
  if (!base) return;
  try {
    const auto columns = map->surfaceColumns();
    const mapping::Reachability reach = mapping::computeReachability(columns, *base, p_.reach);
    const std::vector<mapping::LayerLevel> levels = mapping::layerLevels(*columns, p_.clearance);
    if (levels.empty()) return;
    // The level the walk starts on: the robot's.
    const std::size_t chosen = mapping::nearestLevel(levels, mapping::startHeight(reach).value_or(base->z()));
    const double cell = std::max(p_.occupancy_cell, map->tree().getResolution());
    const mapping::LevelLayers layers = mapping::levelLayers(*columns, levels[chosen], cell, &reach);
    occupancy_pub_.publish(occupancyGrid(*map, layers, world_frame_, stamp));
    published_[1] = stamp;
  } catch (const std::exception& e) {
    warn("occupancy", std::string("no occupancy grid: ") + e.what());
  }
}

void Node::publishGridMap() {
  if (grid_map_pub_.getNumSubscribers() == 0) return;
  ::ros::Time stamp;
  const auto map = snapshot(&stamp);
  if (!map) return;
  const auto base = baseInMap(*map);
  if (!base) return;
  try {
    const double cell = std::max(p_.grid_map_resolution, map->tree().getResolution());
    const int n = std::max(1, static_cast<int>(std::lround(p_.grid_map_size / cell)));
    // On the world's grid of cells (as elevation_mapping moves its map by whole cells).
    mapping::LayerWindow w;
    w.cols = w.rows = n;
    w.x_min = std::floor(base->x() / cell - 0.5 * n + 0.5) * cell;
    w.y_min = std::floor(base->y() / cell - 0.5 * n + 0.5) * cell;
    mapping::LayerLevel around;
    around.z_m = base->z();
    around.min_top_m = -std::numeric_limits<double>::infinity();
    around.max_bottom_m = base->z() + p_.clearance;  // what lies wholly above is overhead
    const ::ros::WallTime start = ::ros::WallTime::now();
    const mapping::LevelLayers layers = mapping::levelLayers(*map->surfaceColumns(), around, cell, w);
    grid_map_pub_.publish(gridMap(*map, layers, world_frame_, stamp));
    const double ms = (::ros::WallTime::now() - start).toSec() * 1e3;
    std::lock_guard<std::mutex> lock(mutex_);
    grid_map_.add(ms);
  } catch (const std::exception& e) {
    warn("grid_map", std::string("no elevation map: ") + e.what());
  }
}

void Node::publishOctomap() {
  if (octomap_pub_.getNumSubscribers() == 0) return;
  ::ros::Time stamp;
  const auto map = snapshot(&stamp);
  if (!map || stamp == published_[3]) return;
  published_[3] = stamp;
  // The map frame under the world frame, for the octree's voxels.
  geometry_msgs::TransformStamped t;
  t.header.stamp = stamp;
  t.header.frame_id = world_frame_;
  t.child_frame_id = p_.map_frame;
  const Eigen::Vector3d o = map->mapToWorld(Eigen::Vector3d::Zero());
  const Eigen::Quaterniond q(map->rotationMapWorld().transpose());
  t.transform.translation.x = o.x();
  t.transform.translation.y = o.y();
  t.transform.translation.z = o.z();
  t.transform.rotation.x = q.x();
  t.transform.rotation.y = q.y();
  t.transform.rotation.z = q.z();
  t.transform.rotation.w = q.w();
  static_tf_.sendTransform(t);
  octomap_pub_.publish(octomapMessage(*map, p_.map_frame, stamp));
}

void Node::publishStatus() {
  nlohmann::json s;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const mapping::LiveMapper::Stats st = mapper_ ? mapper_->stats() : mapping::LiveMapper::Stats{};
    s["world_frame"] = world_frame_;
    s["received"] = received_;
    s["fused"] = fused_before_ + st.fused;
    s["dropped"] = replaced_ + dropped_before_ + st.dropped;
    s["dropped_before_perception"] = replaced_;
    s["late"] = late_;
    s["unreadable"] = unreadable_ + st.failed;
    s["no_ground"] = no_ground_;
    s["mapping"] = static_cast<bool>(mapper_);
    s["map_stamp_ns"] = map_stamp_.toNSec();
    s["map_frames"] = mapper_ ? mapper_->snapshot()->framesIntegrated() : 0;
    const auto ms = [](double v) { return std::isfinite(v) ? nlohmann::json(std::round(v * 10) / 10) : nlohmann::json(); };
    s["latency_ms"] = {{"median", ms(latency_.quantile(0.5))}, {"p95", ms(latency_.quantile(0.95))}};
    s["wait_ms"] = {{"median", ms(arrival_.quantile(0.5))}, {"p95", ms(arrival_.quantile(0.95))}};
    s["perception_ms"] = {{"median", ms(perception_.quantile(0.5))}, {"p95", ms(perception_.quantile(0.95))}};
    s["fusion_ms"] = {{"median", ms(fusion_.quantile(0.5))}, {"p95", ms(fusion_.quantile(0.95))}};
    s["grid_map_ms"] = {{"median", ms(grid_map_.quantile(0.5))}, {"p95", ms(grid_map_.quantile(0.95))}};
  }
  std_msgs::String m;
  m.data = s.dump();
  status_pub_.publish(m);
  ROS_DEBUG("mobmap: %s", m.data.c_str());
  static int ticks = 0;
  if (++ticks % std::max(1, static_cast<int>(std::lround(10 * p_.status_rate))) == 0) ROS_INFO("mobmap: %s", m.data.c_str());
}

void Node::publishServed() {
  ::ros::Time stamp;
  const auto map = snapshot(&stamp);
  if (!map || !served_ || stamp == published_[4]) return;
  published_[4] = stamp;
  app::serve::ServedMap next;
  next.map = map;
  next.frames = map->framesIntegrated();
  next.building = true;
  served_->publish(std::move(next));
}

bool Node::save(const std::string& path, std::string* said) {
  const auto map = snapshot();
  if (!map) {
    *said = "nothing to save: no frame was fused yet";
    return false;
  }
  try {
    mapping::MobilityMap copy(*map);
    copy.finalize();
    mapping::MapMetadata meta;
    mapping::MapRun& run = meta.latest;
    run.format = "mobmap-map-metadata";
    run.tool = std::string("mobmap_node ") + MOBMAP_VERSION_STRING;
    run.tree_type = mapping::MobilityOcTree::kTreeType;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      run.input = "ROS 1 topic " + (p_.compressed ? compressed_sub_.getTopic() : image_sub_.getTopic());
      run.world_frame = world_frame_;
      for (const Eigen::Vector3d& c : trajectory_world_) meta.trajectory_map.push_back(copy.worldToMap(c));
    }
    const int frames = map->framesIntegrated();
    meta.frames = frames;
    run.frames_in_run = frames;
    run.resolution_m = copy.tree().getResolution();
    run.R_map_world = copy.rotationMapWorld();
    run.origin_world = copy.originWorld();
    run.gravity_down_world = copy.rotationMapWorld().transpose() * Eigen::Vector3d(0, 0, -1);
    run.gravity_source = world_frame_ == "map" || world_frame_ == "odom" ? "the world frame (REP 105: z up)" : "`gravity` or the IMU";
    run.max_pose_gap_s = p_.max_pose_gap;
    const std::string stem = mapping::mapFileStem(path);
    builder::checkWritable(path);
    const mapping::MobilityOcTree& tree = copy.tree();
    const std::string meta_text = mapping::formatMapMetadata(meta);
    builder::writeFilesTogether({{path, [&](const std::string& tmp) { mapping::saveMobilityMap(tree, tmp); }},
                                 {stem + ".bt", [&](const std::string& tmp) { mapping::saveOccupancyBt(tree, tmp); }},
                                 {stem + ".octovis.ot", [&](const std::string& tmp) { mapping::saveOctovisColorTree(tree, tmp); }},
                                 {stem + ".json", [&](const std::string& tmp) { builder::writeTextFileAtomically(tmp, meta_text); }}});
    *said = "saved " + std::to_string(frames) + " frames to " + path;
    return true;
  } catch (const std::exception& e) {
    *said = std::string("not saved: ") + e.what();
    return false;
  }
}

bool Node::onSave(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  std::string path = p_.save_path;
  pnh_.getParam("save_path", path);  // may change while the node runs
  res.success = save(path, &res.message);
  if (res.success) {
    ROS_INFO("mobmap: %s", res.message.c_str());
  } else {
    ROS_ERROR("mobmap: %s", res.message.c_str());
  }
  return true;
}

bool Node::onClear(std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
  std::unique_ptr<mapping::LiveMapper> old;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (mapper_) {
      const auto st = mapper_->stats();
      fused_before_ += st.fused;
      dropped_before_ += st.dropped;
    }
    old = std::move(mapper_);
    ++mapper_generation_;
    trajectory_world_.clear();
    map_stamp_ = ::ros::Time();
    std::fill(std::begin(published_), std::end(published_), ::ros::Time());
  }
  old.reset();  // joins its threads; its frames not yet fused are dropped
  ROS_INFO("mobmap: map cleared");
  return true;
}

void Node::shutdown() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopping_) return;
    stopping_ = true;
    wake_.notify_all();
  }
  timers_.clear();
  image_sub_.shutdown();
  compressed_sub_.shutdown();
  points_sub_.shutdown();
  if (feeder_.joinable()) feeder_.join();
  {
    std::unique_lock<std::mutex> lock(mutex_);
    if (mapper_) {
      mapping::LiveMapper* m = mapper_.get();
      lock.unlock();
      m->finish();
    }
  }
  if (!p_.save_on_exit.empty()) {
    std::string said;
    const bool ok = save(p_.save_on_exit, &said);
    if (ok) {
      ROS_INFO("mobmap: %s", said.c_str());
    } else {
      ROS_ERROR("mobmap: %s", said.c_str());
    }
  }
}

}  // namespace mobmap::ros1
