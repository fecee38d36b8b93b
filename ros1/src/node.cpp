// mobmap_node: ROS 1 messages to the live core and its outputs back to ROS 1.
#include "node.hpp"

#include "outputs.hpp"

#include <geometry_msgs/TransformStamped.h>
#include <std_msgs/String.h>
#include <tf2/exceptions.h>

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

::ros::Time rosTime(std::int64_t ns) {
  ::ros::Time t;
  t.fromNSec(static_cast<std::uint64_t>(ns));
  return t;
}

sources::ros::Header header(const std_msgs::Header& h) { return {nanoseconds(h.stamp), h.frame_id}; }

/// An XmlRpc value as the text live::setParam reads.
std::string text(XmlRpc::XmlRpcValue& v) {
  switch (v.getType()) {
    case XmlRpc::XmlRpcValue::TypeBoolean: return static_cast<bool>(v) ? "true" : "false";
    case XmlRpc::XmlRpcValue::TypeInt: return std::to_string(static_cast<int>(v));
    case XmlRpc::XmlRpcValue::TypeDouble: {
      std::ostringstream s;
      s.precision(17);
      s << static_cast<double>(v);
      return s.str();
    }
    case XmlRpc::XmlRpcValue::TypeString: return static_cast<std::string>(v);
    case XmlRpc::XmlRpcValue::TypeArray: {
      std::string out = "[";
      for (int i = 0; i < v.size(); ++i) out += (i ? ", " : "") + text(v[i]);
      return out + "]";
    }
    default: throw std::invalid_argument("a parameter of a type mobmap does not read");
  }
}

}  // namespace

live::Params readParams(const ::ros::NodeHandle& pnh) {
  live::Params p;
  for (const std::string& name : live::paramNames()) {
    XmlRpc::XmlRpcValue v;
    if (!pnh.getParam(name, v)) continue;
    try {
      live::setParam(p, name, text(v), "~");
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(std::string(e.what()).find('~') != std::string::npos ? e.what() : "~" + name + ": " + e.what());
    }
  }
  live::validate(p, "~");
  return p;
}

Node::Node(::ros::NodeHandle nh, ::ros::NodeHandle pnh, live::Params params)
    : nh_(std::move(nh)), pnh_(std::move(pnh)), tf_(::ros::Duration(30.0)), tf_listener_(tf_, nh_), it_(nh_) {
  // Depth as the usual camera drivers name it unless remapped (depth:=...).
  const bool depth_remapped = ::ros::names::resolve("depth") != ::ros::names::resolve("depth", false);
  const std::string depth = depth_remapped ? std::string("depth") : std::string("/camera/depth/image_rect_raw");
  const std::string depth_resolved = ::ros::names::resolve(depth);
  const bool info_remapped = ::ros::names::resolve("camera_info") != ::ros::names::resolve("camera_info", false);
  // The camera_info beside the depth topic, as the bag reader chooses it.
  const std::string info = info_remapped ? std::string("camera_info")
                                         : depth_resolved.substr(0, depth_resolved.rfind('/')) + "/camera_info";
  live::Hooks hooks;
  hooks.now_ns = [] { return nanoseconds(::ros::Time::now()); };
  hooks.log = [](live::Level level, const std::string& s) {
    switch (level) {
      case live::Level::kDebug: ROS_DEBUG("mobmap: %s", s.c_str()); break;
      case live::Level::kInfo: ROS_INFO("mobmap: %s", s.c_str()); break;
      case live::Level::kWarn: ROS_WARN("mobmap: %s", s.c_str()); break;
      case live::Level::kError: ROS_ERROR("mobmap: %s", s.c_str()); break;
    }
  };
  hooks.fatal = [] { ::ros::requestShutdown(); };
  const std::string input = "ROS 1 topic " + depth_resolved + (params.compressed ? "/compressedDepth" : "");
  core_ = std::make_unique<live::Core>(std::move(params), *this, std::move(hooks), input);
  const live::Params& p = core_->params();

  info_sub_ = nh_.subscribe(info, 2, &Node::onInfo, this);
  if (p.compressed) {
    compressed_sub_ = nh_.subscribe(depth_resolved + "/compressedDepth", 5, &Node::onCompressed, this);
  } else {
    image_sub_ = it_.subscribe(depth, 5, &Node::onImage, this);
  }
  if (p.use_points) points_sub_ = nh_.subscribe("points", 5, &Node::onPoints, this);
  if (p.use_imu) imu_sub_ = nh_.subscribe("imu", 50, &Node::onImu, this);
  ROS_INFO("mobmap: depth from %s%s, camera_info from %s", depth_resolved.c_str(), p.compressed ? "/compressedDepth" : "",
           ::ros::names::resolve(info).c_str());

  cloud_pub_ = pnh_.advertise<sensor_msgs::PointCloud2>("mobility_cloud", 1, true);
  occupancy_pub_ = pnh_.advertise<nav_msgs::OccupancyGrid>("occupancy", 1, true);
  grid_map_pub_ = pnh_.advertise<msg::GridMap>("elevation_map", 1, true);
  octomap_pub_ = pnh_.advertise<msg::Octomap>("octomap_binary", 1, true);
  status_pub_ = pnh_.advertise<std_msgs::String>("status", 10, true);
  save_srv_ = pnh_.advertiseService("save_map", &Node::onSave, this);
  clear_srv_ = pnh_.advertiseService("clear_map", &Node::onClear, this);
  const auto every = [&](double rate, const std::function<void()>& publish) {
    if (rate > 0) timers_.push_back(nh_.createWallTimer(::ros::WallDuration(1.0 / rate), [publish](const ::ros::WallTimerEvent&) { publish(); }));
  };
  every(p.cloud_rate, [this] { publishCloud(); });
  every(p.occupancy_rate, [this] { publishOccupancy(); });
  every(p.grid_map_rate, [this] { publishGridMap(); });
  every(p.octomap_rate, [this] { publishOctomap(); });
  every(p.status_rate, [this] { publishStatus(); });
  if (core_->httpPort() >= 0) {
    pnh_.setParam("http_port_bound", core_->httpPort());
    every(2.0, [this] { core_->publishServed(); });
  }
}

Node::~Node() { shutdown(); }

bool Node::has(const std::string& frame) { return tf_._frameExists(frame); }

std::optional<std::string> Node::root(const std::string& frame) {
  if (!tf_._frameExists(frame)) return std::nullopt;
  std::string f = frame, parent;
  for (int depth = 0; depth < 100 && tf_._getParent(f, ::ros::Time(0), parent); ++depth) f = parent;
  return f;
}

std::optional<Eigen::Isometry3d> Node::lookup(const std::string& target, const std::string& source, std::int64_t stamp_ns,
                                              std::string* error) {
  try {
    const ::ros::Time t = rosTime(stamp_ns);
    if (!tf_.tf2::BufferCore::canTransform(target, source, t, error)) return std::nullopt;
    return toEigen(tf_.lookupTransform(target, source, t).transform);
  } catch (const tf2::TransformException& e) {
    if (error) *error = e.what();
    return std::nullopt;
  }
}

void Node::onInfo(const sensor_msgs::CameraInfoConstPtr& m) {
  sources::ros::CameraInfo c;
  c.header = header(m->header);
  c.width = m->width;
  c.height = m->height;
  c.distortion_model = m->distortion_model;
  c.d.assign(m->D.begin(), m->D.end());
  std::copy(m->K.begin(), m->K.end(), c.k.begin());
  core_->cameraInfo(c);
}

void Node::onImage(const sensor_msgs::ImageConstPtr& m) {
  sources::ros::Image img;
  img.header = header(m->header);
  img.height = m->height;
  img.width = m->width;
  img.encoding = m->encoding;
  img.big_endian = m->is_bigendian != 0;
  img.step = m->step;
  img.data = m->data.data();
  img.data_size = m->data.size();
  core_->image(img, image_sub_.getTopic());
}

void Node::onCompressed(const sensor_msgs::CompressedImageConstPtr& m) {
  sources::ros::CompressedImage img;
  img.header = header(m->header);
  img.format = m->format;
  img.data = m->data.data();
  img.data_size = m->data.size();
  core_->compressedImage(img, compressed_sub_.getTopic());
}

void Node::onPoints(const sensor_msgs::PointCloud2ConstPtr& m) {
  sources::ros::PointCloud2 c;
  c.header = header(m->header);
  c.height = m->height;
  c.width = m->width;
  for (const auto& f : m->fields) c.fields.push_back({f.name, f.offset, f.datatype, f.count});
  c.big_endian = m->is_bigendian != 0;
  c.point_step = m->point_step;
  c.row_step = m->row_step;
  c.data = m->data.data();
  c.data_size = m->data.size();
  c.dense = m->is_dense != 0;
  core_->points(c, points_sub_.getTopic());
}

void Node::onImu(const sensor_msgs::ImuConstPtr& m) {
  sources::ros::Imu imu;
  imu.header = header(m->header);
  imu.linear_acceleration = {m->linear_acceleration.x, m->linear_acceleration.y, m->linear_acceleration.z};
  core_->imu(imu);
}

void Node::publishCloud() {
  if (cloud_pub_.getNumSubscribers() == 0) return;
  const auto s = core_->newSnapshot(live::Core::kCloud);
  if (s) cloud_pub_.publish(mobilityCloud(*s->map, core_->worldFrame(), rosTime(s->stamp_ns)));
}

void Node::publishOccupancy() {
  if (occupancy_pub_.getNumSubscribers() == 0) return;
  const auto s = core_->snapshot();
  if (!s || !core_->isNew(live::Core::kOccupancy, s->stamp_ns)) return;
  const auto layers = core_->occupancyLayers(*s->map, s->stamp_ns);
  if (!layers) return;
  occupancy_pub_.publish(occupancyGrid(live::occupancy(*s->map, *layers), core_->worldFrame(), rosTime(s->stamp_ns)));
  core_->markPublished(live::Core::kOccupancy, s->stamp_ns);
}

void Node::publishGridMap() {
  if (grid_map_pub_.getNumSubscribers() == 0) return;
  const auto s = core_->snapshot();
  if (!s) return;
  const auto layers = core_->gridMapLayers(*s->map, s->stamp_ns);
  if (layers) grid_map_pub_.publish(gridMap(live::gridMapData(*s->map, *layers), core_->worldFrame(), rosTime(s->stamp_ns)));
}

void Node::publishOctomap() {
  if (octomap_pub_.getNumSubscribers() == 0) return;
  const auto s = core_->newSnapshot(live::Core::kOctomap);
  if (!s) return;
  // The map frame under the world frame, for the octree's voxels.
  const live::WorldPose w = live::Core::mapFrame(*s->map);
  geometry_msgs::TransformStamped t;
  t.header.stamp = rosTime(s->stamp_ns);
  t.header.frame_id = core_->worldFrame();
  t.child_frame_id = core_->params().map_frame;
  t.transform.translation.x = w.position.x();
  t.transform.translation.y = w.position.y();
  t.transform.translation.z = w.position.z();
  t.transform.rotation.x = w.orientation.x();
  t.transform.rotation.y = w.orientation.y();
  t.transform.rotation.z = w.orientation.z();
  t.transform.rotation.w = w.orientation.w();
  static_tf_.sendTransform(t);
  octomap_pub_.publish(octomapMessage(*s->map, core_->params().map_frame, rosTime(s->stamp_ns)));
}

void Node::publishStatus() {
  std_msgs::String m;
  m.data = core_->status();
  status_pub_.publish(m);
  ROS_DEBUG("mobmap: %s", m.data.c_str());
  if (core_->logStatusNow()) ROS_INFO("mobmap: %s", m.data.c_str());
}

bool Node::onSave(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  std::string path = core_->params().save_path;
  pnh_.getParam("save_path", path);  // may change while the node runs
  res.success = core_->save(path, &res.message);
  if (res.success) {
    ROS_INFO("mobmap: %s", res.message.c_str());
  } else {
    ROS_ERROR("mobmap: %s", res.message.c_str());
  }
  return true;
}

bool Node::onClear(std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
  core_->clear();
  return true;
}

void Node::shutdown() {
  timers_.clear();
  image_sub_.shutdown();
  compressed_sub_.shutdown();
  points_sub_.shutdown();
  core_->shutdown();
}

}  // namespace mobmap::ros1
