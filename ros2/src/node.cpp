// mobmap_ros2: ROS 2 samples over DDS to the live core, its outputs back as ROS 2 types.
#include "node.hpp"

#include "ros2_messages.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <stdexcept>

namespace mobmap::ros2 {
namespace {

using Clock = std::chrono::steady_clock;
constexpr std::int64_t kTfBufferNs = 30'000'000'000LL;  // as tf2's default buffer

template <typename Seq, typename T>
void view(Seq& s, T* data, std::size_t n) {
  s._maximum = s._length = static_cast<std::uint32_t>(n);
  s._buffer = n > 0 ? data : nullptr;
  s._release = false;
}

builtin_interfaces_msg_dds__Time_ rosTime(std::int64_t ns) {
  builtin_interfaces_msg_dds__Time_ t;
  std::int64_t sec = ns / 1'000'000'000;
  std::int64_t rem = ns % 1'000'000'000;
  if (rem < 0) {
    rem += 1'000'000'000;
    --sec;
  }
  t.sec = static_cast<std::int32_t>(sec);
  t.nanosec = static_cast<std::uint32_t>(rem);
  return t;
}

std_msgs_msg_dds__Header_ header(std::int64_t stamp_ns, const std::string& frame) {
  std_msgs_msg_dds__Header_ h;
  h.stamp = rosTime(stamp_ns);
  h.frame_id = const_cast<char*>(frame.c_str());
  return h;
}

geometry_msgs_msg_dds__Pose_ pose(const live::WorldPose& w) {
  geometry_msgs_msg_dds__Pose_ p;
  p.position = {w.position.x(), w.position.y(), w.position.z()};
  p.orientation = {w.orientation.x(), w.orientation.y(), w.orientation.z(), w.orientation.w()};
  return p;
}

double number(const std::string& name, const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(v)) {
    throw std::invalid_argument(name + " must be a number, got \"" + text + "\"");
  }
  return v;
}

bool flag(const std::string& name, const std::string& text) {
  if (text == "true" || text == "True" || text == "1") return true;
  if (text == "false" || text == "False" || text == "0") return false;
  throw std::invalid_argument(name + " must be true or false, got \"" + text + "\"");
}

/// Cyclone's configuration: ours first (socket buffer, sample size), then the user's
/// CYCLONEDDS_URI, whose settings win.
std::string cycloneConfig(const DdsParams& dp) {
  char text[512];
  std::snprintf(text, sizeof text,
                "<Internal><SocketReceiveBufferSize max=\"%lldB\"/><MaxSampleSize>%lldB</MaxSampleSize></Internal>",
                static_cast<long long>(dp.receive_buffer_mb * 1048576.0), static_cast<long long>(2 * dp.max_sample_mb * 1048576.0));
  std::string config = text;
  if (const char* uri = std::getenv("CYCLONEDDS_URI"); uri && *uri) config += std::string(",") + uri;
  return config;
}

}  // namespace

// ---- TF ----------------------------------------------------------------------------------

std::string TfBuffer::add(const std::vector<sources::ros::Transform>& transforms, bool is_static) {
  std::lock_guard<std::mutex> lock(mutex_);
  std::string first_error;
  for (const auto& t : transforms) {
    try {
      const Eigen::Quaterniond q(t.rotation_xyzw[3], t.rotation_xyzw[0], t.rotation_xyzw[1], t.rotation_xyzw[2]);
      tree_.add(t.header.frame_id, t.child_frame_id, t.header.stamp_ns,
                Eigen::Vector3d(t.translation[0], t.translation[1], t.translation[2]), q, is_static);
      if (!is_static) newest_ns_ = std::max(newest_ns_, t.header.stamp_ns);
    } catch (const sources::TfError& e) {
      if (first_error.empty()) first_error = e.what();
    }
  }
  if (++added_ % 256 == 0) {  // bounded: 30 s of samples
    tree_.sortSamples();
    tree_.forgetBefore(newest_ns_ - kTfBufferNs);
  }
  return first_error;
}

bool TfBuffer::has(const std::string& frame) {
  std::lock_guard<std::mutex> lock(mutex_);
  return tree_.has(frame);
}

std::optional<std::string> TfBuffer::root(const std::string& frame) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!tree_.has(frame)) return std::nullopt;
  try {
    return tree_.chainToRoot(frame).back();
  } catch (const sources::TfError&) {
    return std::nullopt;
  }
}

std::optional<Eigen::Isometry3d> TfBuffer::lookup(const std::string& target, const std::string& source, std::int64_t stamp_ns,
                                                  std::string* error) {
  std::lock_guard<std::mutex> lock(mutex_);
  try {
    tree_.sortSamples();
    if (!tree_.has(target) || !tree_.has(source)) {
      if (error) *error = "TF has no frame " + (tree_.has(target) ? source : target) + " yet";
      return std::nullopt;
    }
    return tree_.lookup(target, source, stamp_ns, kTfBufferNs, error);
  } catch (const sources::TfError& e) {
    if (error) *error = e.what();
    return std::nullopt;
  }
}

// ---- the node --------------------------------------------------------------------------------

Node::Node(const Args& args) : args_(args) {
  live::Params p;
  if (const char* id = std::getenv("ROS_DOMAIN_ID"); id && *id) {
    const double v = number("ROS_DOMAIN_ID", id);
    if (v < 0 || v > 232 || v != std::floor(v)) throw std::invalid_argument("ROS_DOMAIN_ID must be 0 to 232, got " + std::string(id));
    dp_.domain_id = static_cast<std::uint32_t>(v);
  }
  for (const auto& [name, value] : args_.params) {
    if (name == "use_sim_time") {
      dp_.use_sim_time = flag(name, value);
    } else if (name == "max_sample_mb") {
      dp_.max_sample_mb = number(name, value);
      if (dp_.max_sample_mb <= 0 || dp_.max_sample_mb > 1024) throw std::invalid_argument("max_sample_mb must be above 0 and at most 1024");
    } else if (name == "receive_buffer_mb") {
      dp_.receive_buffer_mb = number(name, value);
      if (dp_.receive_buffer_mb <= 0 || dp_.receive_buffer_mb > 1024) throw std::invalid_argument("receive_buffer_mb must be above 0 and at most 1024");
    } else {
      live::setParam(p, name, value);
    }
  }
  live::validate(p);
  node_fq_ = resolveName("~/x", args_.ns, args_.node);
  node_fq_ = node_fq_.substr(0, node_fq_.size() - 2);
  const auto topic = [&](const std::string& name, const std::string& fallback) {
    // ROS 2's remapping: by the name the node uses, or by its resolved name.
    const std::string used = fallback.empty() ? name : fallback;
    for (const std::string& key : {name, resolveName(used, args_.ns, args_.node)}) {
      auto it = args_.remaps.find(key);
      if (it != args_.remaps.end()) return resolveName(it->second, args_.ns, args_.node);
    }
    return resolveName(used, args_.ns, args_.node);
  };
  dp_.depth = topic("depth", "/camera/depth/image_rect_raw");
  // The camera_info beside the depth topic, as the bag readers choose it.
  dp_.camera_info = topic("camera_info", dp_.depth.substr(0, dp_.depth.rfind('/')) + "/camera_info");
  dp_.points = topic("points", "");
  dp_.imu = topic("imu", "");

  live::Hooks hooks;
  hooks.now_ns = [this] { return now(); };
  const int verbosity = args_.log_level == "debug" ? 0 : args_.log_level == "warn" ? 2 : args_.log_level == "error" ? 3 : 1;
  hooks.log = [verbosity](live::Level level, const std::string& s) {
    static const char* names[] = {"DEBUG", "INFO", "WARN", "ERROR"};
    if (static_cast<int>(level) < verbosity) return;
    std::fprintf(stderr, "[%s] [mobmap]: %s\n", names[static_cast<int>(level)], s.c_str());
    std::fflush(stderr);
  };
  hooks.fatal = [this] { failed_ = true; };
  const std::string input = "ROS 2 topic " + dp_.depth + (p.compressed ? "/compressedDepth" : "");
  core_ = std::make_unique<live::Core>(std::move(p), tf_, std::move(hooks), input);
  const live::Params& lp = core_->params();

  participant_ = std::make_unique<Participant>(dp_.domain_id, cycloneConfig(dp_));
  waitset_ = std::make_unique<WaitSet>(*participant_);
  using sources::ros::Wire;
  const auto add = [&](const dds_topic_descriptor_t* type, const std::string& ros_topic, const Qos& qos,
                       std::function<void(const std::uint8_t*, std::size_t)> handle) {
    auto reader = std::make_unique<RawReader>(
        *participant_, type, ddsTopic(ros_topic), qos,
        [this, handle](const RawReader& r, const std::uint8_t* d, std::size_t n) { receive(r, d, n, handle); });
    waitset_->attach(reader->condition());
    readers_.push_back(std::move(reader));
  };
  if (lp.compressed) {
    const std::string t = dp_.depth + "/compressedDepth";
    add(&sensor_msgs_msg_dds__CompressedImage__desc, t, sensorQos(), [this, t](const std::uint8_t* d, std::size_t n) {
      core_->compressedImage(sources::ros::decodeCompressedImage(d, n, Wire::kCdr), t);
    });
  } else {
    add(&sensor_msgs_msg_dds__Image__desc, dp_.depth, sensorQos(), [this](const std::uint8_t* d, std::size_t n) {
      core_->image(sources::ros::decodeImage(d, n, Wire::kCdr), dp_.depth);
    });
  }
  add(&sensor_msgs_msg_dds__CameraInfo__desc, dp_.camera_info, sensorQos(), [this](const std::uint8_t* d, std::size_t n) {
    core_->cameraInfo(sources::ros::decodeCameraInfo(d, n, Wire::kCdr));
  });
  for (const bool is_static : {false, true}) {
    add(&tf2_msgs_msg_dds__TFMessage__desc, is_static ? "/tf_static" : "/tf", is_static ? tfStaticQos() : tfQos(),
        [this, is_static](const std::uint8_t* d, std::size_t n) {
          const std::string error = tf_.add(sources::ros::decodeTfMessage(d, n, Wire::kCdr, 10000), is_static);
          if (!error.empty()) core_->warn("tf-tree", std::string("a transform is not used: ") + error);
        });
  }
  if (lp.use_points) {
    add(&sensor_msgs_msg_dds__PointCloud2__desc, dp_.points, sensorQos(), [this](const std::uint8_t* d, std::size_t n) {
      core_->points(sources::ros::decodePointCloud2(d, n, Wire::kCdr), dp_.points);
    });
  }
  if (lp.use_imu) {
    add(&sensor_msgs_msg_dds__Imu__desc, dp_.imu, sensorQos(), [this](const std::uint8_t* d, std::size_t n) {
      core_->imu(sources::ros::decodeImu(d, n, Wire::kCdr));
    });
  }
  if (dp_.use_sim_time) {
    add(&rosgraph_msgs_msg_dds__Clock__desc, "/clock", Qos{false, false, 1}, [this](const std::uint8_t* d, std::size_t n) {
      clock_ns_ = sources::ros::decodeClock(d, n, Wire::kCdr);
    });
  }
  watch_ = std::make_unique<PublicationWatch>(*participant_, [this](const Publication& pub) { onPublication(pub); });
  waitset_->attach(watch_->condition());

  const auto out = [&](const dds_topic_descriptor_t* type, const std::string& name, const Qos& qos) {
    return std::make_unique<Writer>(*participant_, type, ddsTopic(resolveName(name, args_.ns, args_.node)), qos);
  };
  cloud_ = out(&sensor_msgs_msg_dds__PointCloud2__desc, "~/mobility_cloud", latchedQos());
  occupancy_ = out(&nav_msgs_msg_dds__OccupancyGrid__desc, "~/occupancy", latchedQos());
  grid_map_ = out(&grid_map_msgs_msg_dds__GridMap__desc, "~/elevation_map", latchedQos());
  octomap_ = out(&octomap_msgs_msg_dds__Octomap__desc, "~/octomap_binary", latchedQos());
  status_ = out(&std_msgs_msg_dds__String__desc, "~/status", latchedQos());
  tf_static_ = out(&tf2_msgs_msg_dds__TFMessage__desc, "/tf_static", Qos{true, true, 1});

  // Services as rmw_cyclonedds names and frames them.
  const std::string save = node_fq_.substr(1) + "/save_map", clear = node_fq_.substr(1) + "/clear_map";
  const auto request = [&](const dds_topic_descriptor_t* type, const std::string& dds, dds_entity_t* condition) {
    dds_qos_t* q = dds_create_qos();
    dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 10);
    const dds_entity_t r = dds_create_reader(participant_->handle(), participant_->topic(type, dds), q, nullptr);
    dds_delete_qos(q);
    if (r < 0) throw DdsError("cannot read " + dds + ": " + dds_strretcode(r));
    *condition = dds_create_readcondition(r, DDS_ANY_STATE);
    waitset_->attach(*condition);
    return r;
  };
  save_request_ = request(&std_srvs_srv_dds__Trigger_Request__desc, "rq/" + save + "Request", &save_condition_);
  clear_request_ = request(&std_srvs_srv_dds__Empty_Request__desc, "rq/" + clear + "Request", &clear_condition_);
  save_reply_ = std::make_unique<Writer>(*participant_, &std_srvs_srv_dds__Trigger_Response__desc, "rr/" + save + "Reply", serviceQos());
  clear_reply_ = std::make_unique<Writer>(*participant_, &std_srvs_srv_dds__Empty_Response__desc, "rr/" + clear + "Reply", serviceQos());

  core_->log(live::Level::kInfo, "domain " + std::to_string(dp_.domain_id) + ", depth from " + dp_.depth +
                                     (lp.compressed ? "/compressedDepth" : "") + ", camera_info from " + dp_.camera_info +
                                     ", outputs under " + node_fq_);
  publisher_ = std::thread([this] { publishLoop(); });
}

Node::~Node() {
  {
    std::lock_guard<std::mutex> lock(publish_mutex_);
    publish_stop_ = true;
  }
  publish_wake_.notify_all();
  if (publisher_.joinable()) publisher_.join();
  core_->shutdown();
  readers_.clear();
  watch_.reset();
  cloud_.reset();
  occupancy_.reset();
  grid_map_.reset();
  octomap_.reset();
  status_.reset();
  tf_static_.reset();
  save_reply_.reset();
  clear_reply_.reset();
  waitset_.reset();
  participant_.reset();
}

std::int64_t Node::now() const {
  if (dp_.use_sim_time) return clock_ns_.load();
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

void Node::receive(const RawReader& reader, const std::uint8_t* data, std::size_t size,
                   const std::function<void(const std::uint8_t*, std::size_t)>& handle) {
  const std::string topic = reader.topic().substr(2);
  if (static_cast<double>(size) > dp_.max_sample_mb * 1048576.0) {
    core_->unreadable("size:" + topic, "a sample of " + std::to_string(size >> 20) + " MiB on " + topic +
                                           " is refused: larger than max_sample_mb (" + std::to_string(dp_.max_sample_mb) + ")");
    return;
  }
  try {
    handle(data, size);
  } catch (const std::exception& e) {
    core_->unreadable("decode:" + topic, "a sample on " + topic + " (" + reader.typeName() + ") is not read: " + e.what());
  }
}

void Node::onPublication(const Publication& pub) {
  std::lock_guard<std::mutex> lock(seen_mutex_);
  if (!pub.alive) {
    ++publications_gone_;
    return;
  }
  ++publications_seen_;
  for (const auto& r : readers_) {
    if (r->topic() == pub.topic && r->typeName() != pub.type && wrong_types_.insert(pub.topic + " " + pub.type).second) {
      core_->warn("type:" + pub.topic + pub.type, "a publisher on " + pub.topic.substr(2) + " sends " + pub.type + ", but mobmap reads " +
                                                      r->typeName() + " there: its samples are not received");
    }
  }
}

namespace {

/// Takes each request on `reader` and writes `answer`'s reply with the request's client id
/// and sequence number (rmw_cyclonedds's framing).
template <typename Request, typename Response>
void answerAll(dds_entity_t reader, Writer& writer, live::Core& core, const std::function<void(Response&)>& answer) {
  for (;;) {
    void* samples[1] = {nullptr};
    dds_sample_info_t info;
    if (dds_take(reader, samples, &info, 1, 1) <= 0) return;
    const auto* req = static_cast<const Request*>(samples[0]);
    Response res{};
    res.client_id = req->client_id;
    res.sequence_number = req->sequence_number;
    const bool valid = info.valid_data;
    dds_return_loan(reader, samples, 1);
    if (!valid) continue;
    answer(res);
    try {
      writer.write(&res);
    } catch (const DdsError& e) {
      core.warn("reply", e.what());
    }
  }
}

}  // namespace

void Node::serve() {
  std::string said;
  answerAll<std_srvs_srv_dds__Trigger_Request_, std_srvs_srv_dds__Trigger_Response_>(
      save_request_, *save_reply_, *core_, [&](std_srvs_srv_dds__Trigger_Response_& res) {
        res.success = core_->save(core_->params().save_path, &said);
        core_->log(res.success ? live::Level::kInfo : live::Level::kError, said);
        res.message = const_cast<char*>(said.c_str());
      });
  answerAll<std_srvs_srv_dds__Empty_Request_, std_srvs_srv_dds__Empty_Response_>(
      clear_request_, *clear_reply_, *core_, [&](std_srvs_srv_dds__Empty_Response_&) { core_->clear(); });
}

bool Node::run(const std::atomic<bool>& stop) {
  while (!stop.load() && !failed_.load()) {
    if (!waitset_->wait(100)) continue;
    for (const auto& r : readers_) r->takeAll();
    watch_->takeAll();
    serve();
  }
  core_->log(failed_ ? live::Level::kError : live::Level::kInfo, failed_ ? "stopping: mapping could not start" : "stopping");
  return !failed_;
}

void Node::publishLoop() {
  const live::Params& p = core_->params();
  struct Due {
    double rate;
    void (Node::*publish)();
    Clock::time_point next;
  };
  std::vector<Due> due = {{p.cloud_rate, &Node::publishCloud, {}},     {p.occupancy_rate, &Node::publishOccupancy, {}},
                          {p.grid_map_rate, &Node::publishGridMap, {}}, {p.octomap_rate, &Node::publishOctomap, {}},
                          {p.status_rate, &Node::publishStatus, {}}};
  if (core_->httpPort() >= 0) due.push_back({2.0, nullptr, {}});
  const auto start = Clock::now();
  for (auto& d : due) d.next = start;
  for (;;) {
    Clock::time_point next = start + std::chrono::hours(24);
    for (auto& d : due) {
      if (d.rate <= 0) continue;
      if (Clock::now() >= d.next) {
        try {
          if (d.publish) {
            (this->*d.publish)();
          } else {
            core_->publishServed();
          }
        } catch (const std::exception& e) {
          core_->warn("publish", std::string("an output was not published: ") + e.what());
        }
        d.next += std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / d.rate));
        if (d.next < Clock::now()) d.next = Clock::now();
      }
      next = std::min(next, d.next);
    }
    std::unique_lock<std::mutex> lock(publish_mutex_);
    if (publish_wake_.wait_until(lock, next, [&] { return publish_stop_; })) return;
  }
}

void Node::publishCloud() {
  if (cloud_->matched() == 0) return;
  const auto s = core_->newSnapshot(live::Core::kCloud);
  if (!s) return;
  std::vector<float> values = live::mobilityCloudValues(*s->map);
  const std::string frame = core_->worldFrame();
  static const char* names[] = {"x", "y", "z", "mobility", "variance"};
  sensor_msgs_msg_dds__PointField_ fields[5];
  for (std::uint32_t k = 0; k < 5; ++k) fields[k] = {const_cast<char*>(names[k]), 4 * k, 7, 1};
  sensor_msgs_msg_dds__PointCloud2_ m{};
  m.header = header(s->stamp_ns, frame);
  m.height = 1;
  m.width = static_cast<std::uint32_t>(values.size() / 5);
  view(m.fields, fields, 5);
  m.is_bigendian = false;
  m.point_step = 20;
  m.row_step = 20 * m.width;
  view(m.data, reinterpret_cast<std::uint8_t*>(values.data()), values.size() * sizeof(float));
  m.is_dense = false;
  cloud_->write(&m);
}

void Node::publishOccupancy() {
  if (occupancy_->matched() == 0) return;
  const auto s = core_->snapshot();
  if (!s || !core_->isNew(live::Core::kOccupancy, s->stamp_ns)) return;
  const auto layers = core_->occupancyLayers(*s->map, s->stamp_ns);
  if (!layers) return;
  live::Occupancy o = live::occupancy(*s->map, *layers);
  const std::string frame = core_->worldFrame();
  nav_msgs_msg_dds__OccupancyGrid_ m{};
  m.header = header(s->stamp_ns, frame);
  m.info.map_load_time = rosTime(s->stamp_ns);
  m.info.resolution = static_cast<float>(o.cell_m);
  m.info.width = static_cast<std::uint32_t>(o.cols);
  m.info.height = static_cast<std::uint32_t>(o.rows);
  m.info.origin = pose(o.origin);
  view(m.data, reinterpret_cast<std::uint8_t*>(o.data.data()), o.data.size());
  occupancy_->write(&m);
  core_->markPublished(live::Core::kOccupancy, s->stamp_ns);
}

void Node::publishGridMap() {
  if (grid_map_->matched() == 0) return;
  const auto s = core_->snapshot();
  if (!s) return;
  const auto layers = core_->gridMapLayers(*s->map, s->stamp_ns);
  if (!layers) return;
  live::GridMapData d = live::gridMapData(*s->map, *layers);
  const std::string frame = core_->worldFrame();
  grid_map_msgs_msg_dds__GridMap_ m{};
  m.header = header(s->stamp_ns, frame);
  m.info.resolution = d.resolution;
  m.info.length_x = d.length_x;
  m.info.length_y = d.length_y;
  m.info.pose = pose(d.pose);
  std::vector<char*> names;
  for (auto& n : d.layers) names.push_back(const_cast<char*>(n.c_str()));
  char elevation[] = "elevation";
  char* basic[] = {elevation};
  view(m.layers, names.data(), names.size());
  view(m.basic_layers, basic, 1);
  const auto nx = static_cast<std::uint32_t>(d.cols), ny = static_cast<std::uint32_t>(d.rows);
  char column[] = "column_index", row[] = "row_index";
  std_msgs_msg_dds__MultiArrayDimension_ dims[2] = {{column, ny, nx * ny}, {row, nx, nx}};
  std::vector<std_msgs_msg_dds__Float32MultiArray_> arrays(d.layers.size());
  for (std::size_t k = 0; k < arrays.size(); ++k) {
    view(arrays[k].layout.dim, dims, 2);
    arrays[k].layout.data_offset = 0;
    view(arrays[k].data, d.data[k].data(), d.data[k].size());
  }
  view(m.data, arrays.data(), arrays.size());
  m.outer_start_index = 0;
  m.inner_start_index = 0;
  grid_map_->write(&m);
}

void Node::publishOctomap() {
  if (octomap_->matched() == 0) return;
  const auto s = core_->newSnapshot(live::Core::kOctomap);
  if (!s) return;
  const std::string world = core_->worldFrame();
  const std::string& map_frame = core_->params().map_frame;
  // The map frame under the world frame, for the octree's voxels.
  const live::WorldPose w = live::Core::mapFrame(*s->map);
  geometry_msgs_msg_dds__TransformStamped_ t{};
  t.header = header(s->stamp_ns, world);
  t.child_frame_id = const_cast<char*>(map_frame.c_str());
  t.transform.translation = {w.position.x(), w.position.y(), w.position.z()};
  t.transform.rotation = {w.orientation.x(), w.orientation.y(), w.orientation.z(), w.orientation.w()};
  tf2_msgs_msg_dds__TFMessage_ tf{};
  view(tf.transforms, &t, 1);
  tf_static_->write(&tf);
  std::string bytes = live::octomapBinary(*s->map);
  octomap_msgs_msg_dds__Octomap_ m{};
  m.header = header(s->stamp_ns, map_frame);
  m.binary = true;
  char id[] = "OcTree";
  m.id = id;
  m.resolution = s->map->tree().getResolution();
  view(m.data, reinterpret_cast<std::uint8_t*>(bytes.data()), bytes.size());
  octomap_->write(&m);
}

void Node::publishStatus() {
  std::map<std::string, double> extra;
  double lost = 0, incompatible = 0;
  for (const auto& r : readers_) {
    lost += r->lost();
    incompatible += r->incompatible();
  }
  extra["dds_lost"] = lost;
  extra["dds_incompatible_qos"] = incompatible;
  extra["depth_publishers"] = readers_.empty() ? 0 : readers_.front()->matched();
  {
    std::lock_guard<std::mutex> lock(seen_mutex_);
    extra["dds_wrong_type"] = static_cast<double>(wrong_types_.size());
    extra["dds_publications_seen"] = static_cast<double>(publications_seen_);
    extra["dds_publications_gone"] = static_cast<double>(publications_gone_);
  }
  std::string json = core_->status(extra);
  std_msgs_msg_dds__String_ m{};
  m.data = json.data();
  status_->write(&m);
  if (core_->logStatusNow()) core_->log(live::Level::kInfo, json);
}

}  // namespace mobmap::ros2
