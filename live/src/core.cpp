// The live nodes' core: images in, LiveMapper in the middle, map snapshots out.
#include "core.hpp"

#include "depth_decode.hpp"
#include "undistort.hpp"

#include "mobmap/builder/config.hpp"
#include "mobmap/builder/files.hpp"
#include "mobmap/mapping/map_metadata.hpp"
#include "mobmap/mapping/reachability.hpp"
#include "serve/api.hpp"
#include "serve/http_server.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

namespace mobmap::live {
namespace {

using Clock = std::chrono::steady_clock;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

double msSince(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

}  // namespace

// ---- outputs as plain data ----------------------------------------------------------------

std::vector<float> mobilityCloudValues(const mapping::MobilityMap& map) {
  const mapping::MobilityOcTree& tree = map.tree();
  const double res = tree.getResolution();
  std::vector<float> values;
  const auto add = [&](const Eigen::Vector3d& centre_map, const mapping::MobilityOcTreeNode& node) {
    const Eigen::Vector3d p = map.mapToWorld(centre_map);
    values.push_back(static_cast<float>(p.x()));
    values.push_back(static_cast<float>(p.y()));
    values.push_back(static_cast<float>(p.z()));
    values.push_back(node.hasMobility() ? static_cast<float>(node.mobility()) : kNaN);
    values.push_back(node.hasMobility() ? static_cast<float>(node.variance()) : kNaN);
  };
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) {
    if (!tree.isNodeOccupied(*it)) continue;
    const double size = it.getSize();
    const Eigen::Vector3d centre(it.getX(), it.getY(), it.getZ());
    if (size <= res * 1.5) {
      add(centre, *it);
      continue;
    }
    // A pruned block: each of its voxels.
    const int n = static_cast<int>(std::lround(size / res));
    const Eigen::Vector3d corner = centre - Eigen::Vector3d::Constant(size / 2 - res / 2);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j)
        for (int k = 0; k < n; ++k) add(corner + res * Eigen::Vector3d(i, j, k), *it);
  }
  return values;
}

WorldPose poseInWorld(const mapping::MobilityMap& map, const Eigen::Vector3d& p_map) {
  WorldPose w;
  w.position = map.mapToWorld(p_map);
  w.orientation = Eigen::Quaterniond(map.rotationMapWorld().transpose());
  return w;
}

Occupancy occupancy(const mapping::MobilityMap& map, const mapping::LevelLayers& l) {
  Occupancy g;
  g.cell_m = l.cell_m;
  g.cols = l.cols;
  g.rows = l.rows;
  g.origin = poseInWorld(map, Eigen::Vector3d(l.x_min, l.y_min, l.level.z_m));
  g.data.assign(static_cast<std::size_t>(l.cols) * static_cast<std::size_t>(l.rows), -1);
  if (l.traversable.empty()) return g;
  // OccupancyGrid rows run from the origin along +y; the layers' row 0 is the highest y.
  for (int r = 0; r < l.rows; ++r) {
    for (int col = 0; col < l.cols; ++col) {
      const mapping::Traversable t = l.traversable[l.index(l.rows - 1 - r, col)];
      g.data[static_cast<std::size_t>(r) * l.cols + col] =
          t == mapping::Traversable::kFree ? 0 : t == mapping::Traversable::kOccupied ? 100 : -1;
    }
  }
  return g;
}

GridMapData gridMapData(const mapping::MobilityMap& map, const mapping::LevelLayers& l) {
  GridMapData g;
  g.resolution = l.cell_m;
  g.cols = l.cols;
  g.rows = l.rows;
  g.length_x = l.cols * l.cell_m;
  g.length_y = l.rows * l.cell_m;
  g.pose = poseInWorld(map, Eigen::Vector3d(l.x_min + 0.5 * l.cols * l.cell_m, l.y_min + 0.5 * l.rows * l.cell_m, 0.0));
  // Elevation along the world's z (the map's z is gravity's up; the world's is too when
  // the world frame is map or odom).
  const double z0 = map.mapToWorld(Eigen::Vector3d::Zero()).z();
  const std::size_t nx = static_cast<std::size_t>(l.cols), ny = static_cast<std::size_t>(l.rows);
  const auto layer = [&](const std::string& name, const std::vector<float>& values, double offset) {
    std::vector<float> a(nx * ny);
    // grid_map index (i, j): i along -x from the largest x, j along -y from the largest y;
    // column-major (i fastest). The layers' (row 0 = largest y, col 0 = smallest x).
    for (std::size_t j = 0; j < ny; ++j)
      for (std::size_t i = 0; i < nx; ++i) {
        const float v = values[l.index(static_cast<int>(j), static_cast<int>(nx - 1 - i))];
        a[j * nx + i] = std::isnan(v) ? v : static_cast<float>(v + offset);
      }
    g.layers.push_back(name);
    g.data.push_back(std::move(a));
  };
  layer("elevation", l.elevation, z0);
  layer("mobility", l.mobility, 0.0);
  layer("step", l.step, 0.0);
  layer("slope", l.slope_deg, 0.0);
  layer("variance", l.elevation_variance, 0.0);
  return g;
}

std::string octomapBinary(const mapping::MobilityMap& map) {
  std::stringstream s;
  map.tree().writeBinaryData(s);
  return s.str();
}

// ---- the core ------------------------------------------------------------------------------

double Core::Gauge::quantile(double q) const {
  if (ms.empty()) return std::nan("");
  std::vector<double> v(ms.begin(), ms.end());
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

Core::Core(Params p, Transforms& tf, Hooks hooks, std::string input)
    : p_(std::move(p)), tf_(tf), hooks_(std::move(hooks)), input_(std::move(input)), mapper_config_(mapperConfig(p_)) {
  world_frame_ = p_.world_frame;
  if (p_.http_port >= 0) {
    app::serve::ServedMap first;
    first.map = std::make_shared<mapping::MobilityMap>();
    first.building = true;
    served_ = std::make_unique<app::serve::MapSource>(std::move(first));
    api_ = std::make_unique<app::serve::Api>("live: " + input_, *served_);
    http_ = std::make_unique<app::serve::HttpServer>(*api_);
    http_port_ = http_->bind(p_.http_address, p_.http_port);
    http_thread_ = std::thread([this] { http_->run(); });
    log(Level::kInfo, "HTTP API on http://" + p_.http_address + ":" + std::to_string(http_port_));
  }
  feeder_ = std::thread([this] { feed(); });
}

Core::~Core() {
  shutdown();
  if (http_) http_->stop();
  if (http_thread_.joinable()) http_thread_.join();
}

void Core::warn(const std::string& key, const std::string& text) {
  const auto now = Clock::now();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = warned_.find(key);
    if (it != warned_.end() && std::chrono::duration<double>(now - it->second).count() < p_.warn_period) return;
    warned_[key] = now;
  }
  log(Level::kWarn, text);
}

void Core::cameraInfo(const sources::ros::CameraInfo& m) {
  std::lock_guard<std::mutex> lock(mutex_);
  info_ = m;
}

void Core::unreadable(const std::string& key, const std::string& why) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++received_;
    ++unreadable_;
  }
  warn("unreadable:" + key, why);
}

void Core::depth(const sources::ros::Header& header, double units_per_m, const std::function<perception::DepthImage()>& decode) {
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
  p.stamp_ns = header.stamp_ns;
  offer(std::move(p));
}

void Core::image(const sources::ros::Image& m, const std::string& topic) {
  depth(m.header, m.encoding == "32FC1" ? 1.0 : 1000.0, [&] { return sources::depthFromImage(m, "image on " + topic); });
}

void Core::compressedImage(const sources::ros::CompressedImage& m, const std::string& topic) {
  depth(m.header, sources::compressedDepthEncoding(m.format) == "32FC1" ? 1.0 : 1000.0,
        [&] { return sources::depthFromCompressed(m, "image on " + topic); });
}

void Core::points(const sources::ros::PointCloud2& m, const std::string& topic) {
  std::vector<std::array<float, 3>> xyz;
  try {
    xyz = sources::ros::cloudXyz(m);
  } catch (const sources::ros::MessageError& e) {
    unreadable("points", "a PointCloud2 on " + topic + " is not read: " + e.what());
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++received_;
  }
  Pending p;
  p.cloud = true;
  p.points.reserve(xyz.size());
  for (const auto& v : xyz) p.points.emplace_back(v[0], v[1], v[2]);
  p.width = static_cast<int>(m.width);
  p.height = static_cast<int>(m.height);
  p.frame_id = m.header.frame_id;
  p.stamp_ns = m.header.stamp_ns;
  offer(std::move(p));
}

void Core::imu(const sources::ros::Imu& m) {
  std::string error, world;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (mapper_ || world_frame_.empty() || imu_down_.size() >= 50) return;
    world = world_frame_;
  }
  const auto T = tf_.lookup(world, m.header.frame_id, m.header.stamp_ns, &error);
  if (!T) return;
  // At rest an accelerometer reads the reaction to gravity: up.
  const Eigen::Vector3d a(m.linear_acceleration[0], m.linear_acceleration[1], m.linear_acceleration[2]);
  if (!a.allFinite() || a.norm() < 5.0 || a.norm() > 15.0) return;  // moving, or not m/s^2
  std::lock_guard<std::mutex> lock(mutex_);
  imu_down_.push_back(-(T->linear() * a).normalized());
}

void Core::offer(Pending&& p) {
  p.arrived = Clock::now();
  std::lock_guard<std::mutex> lock(mutex_);
  if (stopping_) return;
  if (pending_) ++replaced_;  // the feeder is busy: the newest is kept
  pending_ = std::move(p);
  wake_.notify_one();
}

std::optional<Eigen::Isometry3d> Core::lookup(const std::string& target, const std::string& source, std::int64_t stamp_ns,
                                              double wait_s, std::string* error) {
  // Waits on the wall clock: under simulated time a clock that stops (a recording's end)
  // must not hold a frame forever.
  const auto until = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(wait_s));
  for (;;) {
    if (auto T = tf_.lookup(target, source, stamp_ns, error)) return T;
    if (Clock::now() >= until) return std::nullopt;
    std::unique_lock<std::mutex> lock(mutex_);
    if (wake_.wait_for(lock, std::chrono::milliseconds(2), [&] { return stopping_; })) return std::nullopt;
  }
}

bool Core::chooseWorldFrame(const std::string& camera_frame) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!world_frame_.empty()) return true;
  }
  // As the bag readers choose: map when TF has it, else odom, else the camera's root.
  std::string chosen;
  for (const char* f : {"map", "odom"}) {
    if (tf_.has(f)) {
      chosen = f;
      break;
    }
  }
  if (chosen.empty()) {
    const std::optional<std::string> root = tf_.root(camera_frame);
    if (!root) return false;
    // /tf_static may arrive before /tf (its publisher latches; odometry starts later, or
    // its subscription connects later): a root chosen then would be the robot's base for
    // good. The root is taken only once kRootAfterFrames frames found neither map nor odom.
    if (++frames_without_world_ < kRootAfterFrames) {
      warn("world", "TF names neither map nor odom yet: the camera's root " + *root + " becomes the world frame if " +
                        std::to_string(kRootAfterFrames) + " frames find neither");
      return false;
    }
    chosen = *root;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    world_frame_ = chosen;
  }
  log(Level::kInfo, "world frame " + chosen);
  return true;
}

std::optional<Eigen::Vector3d> Core::gravityDown() {
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

mapping::LiveMapper::Config Core::mapperConfig(const Params& p) {
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

void Core::startMapper(const Eigen::Vector3d& down) {
  mapping::LiveMapper::Config c = mapper_config_;
  c.gravity_down_world = down;
  const std::uint64_t generation = ++mapper_generation_;
  c.on_frame = [this, generation](const mapping::FrameReport& r) {
    if (generation == mapper_generation_.load()) onFrame(r);
  };
  mapper_ = std::make_unique<mapping::LiveMapper>(std::move(c));
  char text[256];
  std::snprintf(text, sizeof text, "mapping in %s at %.3f m, gravity (%.3f, %.3f, %.3f), %d perception threads",
                world_frame_.c_str(), mapper_config_.map.resolution_m, down.x(), down.y(), down.z(),
                mapper_config_.perception_threads);
  log(Level::kInfo, text);
}

void Core::feed() {
  for (;;) {
    Pending p;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stopping_ || pending_.has_value(); });
      if (stopping_) return;
      p = std::move(*pending_);
      pending_.reset();
    }
    const auto late = [&] {
      std::lock_guard<std::mutex> lock(mutex_);
      ++late_;
    };
    if (!chooseWorldFrame(p.frame_id)) {
      warn("world", "no TF yet for the camera frame " + p.frame_id + ": waiting for /tf and /tf_static");
      late();
      continue;
    }
    std::string error;
    const std::string world = worldFrame();
    const auto T = lookup(world, p.frame_id, p.stamp_ns, p_.tf_wait, &error);
    if (!T) {
      warn("tf", "no pose for an image of " + p.frame_id + " in " + world + " within " + std::to_string(p_.tf_wait) +
                     " s of its stamp: " + error);
      late();
      continue;
    }
    const std::optional<Eigen::Vector3d> down = gravityDown();
    if (!down) {
      warn("gravity", "waiting for gravity: the world frame " + world +
                          " does not say where down is; set gravity, or use_imu with an imu topic");
      late();
      continue;
    }
    std::optional<sources::ros::CameraInfo> info;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      info = info_;
      if (!mapper_) {
        try {
          startMapper(*down);
        } catch (const std::exception& e) {
          log(Level::kError, std::string("cannot start mapping: ") + e.what());
          stopping_ = true;
          if (hooks_.fatal) hooks_.fatal();
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
        f.stamp_s = static_cast<double>(p.stamp_ns) * 1e-9;
        std::lock_guard<std::mutex> lock(mutex_);
        remember(f.stamp_s, p.stamp_ns);
        unit_ = {1.0, true};
        trajectory_world_.push_back(T->translation());
        mapper_->push(std::move(f));
      } else {
        if (!info) {
          warn("camera_info", "no camera_info yet: images wait for one");
          late();
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
        f.intrinsics = {static_cast<int>(info->width), static_cast<int>(info->height), info->k[0], info->k[4], info->k[2], info->k[5]};
        const bool distorted = std::any_of(info->d.begin(), info->d.end(), [](double d) { return d != 0.0; });
        if (distorted && info->d.size() >= 4 && info->distortion_model == "plumb_bob") {
          f.depth = sources::Undistorter(f.intrinsics, info->d).apply(p.depth);
        } else {
          if (distorted) {
            warn("distortion", "the camera_info's " + info->distortion_model +
                                   " distortion is not undone (plumb_bob is): the images are mapped as they are");
          }
          f.depth = std::move(p.depth);
        }
        f.T_world_camera = *T;
        f.stamp_s = static_cast<double>(p.stamp_ns) * 1e-9;
        std::lock_guard<std::mutex> lock(mutex_);
        remember(f.stamp_s, p.stamp_ns);
        unit_ = {p.units_per_m, false};
        arrival_.add(msSince(p.arrived));
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

void Core::remember(double stamp_s, std::int64_t stamp_ns) {
  stamps_.emplace_back(stamp_s, stamp_ns);
  if (stamps_.size() > 64) stamps_.pop_front();
}

void Core::onFrame(const mapping::FrameReport& r) {
  // On LiveMapper's fusion thread.
  const double now_s = hooks_.now_ns ? static_cast<double>(hooks_.now_ns()) * 1e-9 : r.stamp_s;
  const double latency_ms = (now_s - r.stamp_s) * 1e3;
  std::vector<std::string> said;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!r.fused) {
      ++unreadable_;
    } else {
      // The frame's exact stamp (seconds in a double lose the nanoseconds).
      map_stamp_ns_ = static_cast<std::int64_t>(std::llround(r.stamp_s * 1e9));
      for (const auto& [s, ns] : stamps_) {
        if (s == r.stamp_s) map_stamp_ns_ = ns;
      }
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

std::optional<Core::Snapshot> Core::snapshot() const {
  // The stamp first: a frame's stamp is set after its map is published, so the map taken
  // holds at least the frame the stamp names.
  std::lock_guard<std::mutex> lock(mutex_);
  if (!mapper_ || map_stamp_ns_ == 0) return std::nullopt;
  return Snapshot{mapper_->snapshot(), map_stamp_ns_};
}

std::optional<Core::Snapshot> Core::newSnapshot(Output output) {
  auto s = snapshot();
  if (!s) return std::nullopt;
  std::lock_guard<std::mutex> lock(mutex_);
  if (published_[output] == s->stamp_ns) return std::nullopt;
  published_[output] = s->stamp_ns;
  return s;
}

bool Core::isNew(Output output, std::int64_t stamp_ns) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return published_[output] != stamp_ns;
}

void Core::markPublished(Output output, std::int64_t stamp_ns) {
  std::lock_guard<std::mutex> lock(mutex_);
  published_[output] = stamp_ns;
}

std::string Core::worldFrame() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return world_frame_;
}

std::optional<Eigen::Vector3d> Core::baseInMap(const mapping::MobilityMap& map, std::int64_t stamp_ns) {
  std::string error;
  const std::string world = worldFrame();
  // Where the base was at the newest frame fused: TF surely had its pose then.
  const auto T = tf_.lookup(world, p_.base_frame, stamp_ns, &error);
  if (!T) {
    warn("base", "no pose of the base frame " + p_.base_frame + " in " + world + ": " + error);
    return std::nullopt;
  }
  return map.worldToMap(T->translation());
}

std::optional<mapping::LevelLayers> Core::occupancyLayers(const mapping::MobilityMap& map, std::int64_t stamp_ns) {
  const auto base = baseInMap(map, stamp_ns);
  if (!base) return std::nullopt;
  try {
    const auto columns = map.surfaceColumns();
    const mapping::Reachability reach = mapping::computeReachability(columns, *base, p_.reach);
    const std::vector<mapping::LayerLevel> levels = mapping::layerLevels(*columns, p_.clearance);
    if (levels.empty()) return std::nullopt;
    // The level the walk starts on: the robot's.
    const std::size_t chosen = mapping::nearestLevel(levels, mapping::startHeight(reach).value_or(base->z()));
    const double cell = std::max(p_.occupancy_cell, map.tree().getResolution());
    return mapping::levelLayers(*columns, levels[chosen], cell, &reach);
  } catch (const std::exception& e) {
    warn("occupancy", std::string("no occupancy grid: ") + e.what());
    return std::nullopt;
  }
}

std::optional<mapping::LevelLayers> Core::gridMapLayers(const mapping::MobilityMap& map, std::int64_t stamp_ns) {
  const auto base = baseInMap(map, stamp_ns);
  if (!base) return std::nullopt;
  try {
    const double cell = std::max(p_.grid_map_resolution, map.tree().getResolution());
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
    const auto start = Clock::now();
    mapping::LevelLayers layers = mapping::levelLayers(*map.surfaceColumns(), around, cell, w);
    const double ms = msSince(start);
    std::lock_guard<std::mutex> lock(mutex_);
    grid_map_.add(ms);
    return layers;
  } catch (const std::exception& e) {
    warn("grid_map", std::string("no elevation map: ") + e.what());
    return std::nullopt;
  }
}

WorldPose Core::mapFrame(const mapping::MobilityMap& map) { return poseInWorld(map, Eigen::Vector3d::Zero()); }

std::string Core::status(const std::map<std::string, double>& extra) const {
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
    s["map_stamp_ns"] = map_stamp_ns_;
    s["map_frames"] = mapper_ ? mapper_->snapshot()->framesIntegrated() : 0;
    const auto ms = [](double v) { return std::isfinite(v) ? nlohmann::json(std::round(v * 10) / 10) : nlohmann::json(); };
    s["latency_ms"] = {{"median", ms(latency_.quantile(0.5))}, {"p95", ms(latency_.quantile(0.95))}};
    s["wait_ms"] = {{"median", ms(arrival_.quantile(0.5))}, {"p95", ms(arrival_.quantile(0.95))}};
    s["perception_ms"] = {{"median", ms(perception_.quantile(0.5))}, {"p95", ms(perception_.quantile(0.95))}};
    s["fusion_ms"] = {{"median", ms(fusion_.quantile(0.5))}, {"p95", ms(fusion_.quantile(0.95))}};
    s["grid_map_ms"] = {{"median", ms(grid_map_.quantile(0.5))}, {"p95", ms(grid_map_.quantile(0.95))}};
  }
  for (const auto& [k, v] : extra) s[k] = v;
  return s.dump();
}

bool Core::logStatusNow() {
  std::lock_guard<std::mutex> lock(mutex_);
  return ++status_ticks_ % std::max(1, static_cast<int>(std::lround(10 * p_.status_rate))) == 0;
}

void Core::publishServed() {
  if (!served_) return;
  const auto s = newSnapshot(kServed);
  if (!s) return;
  app::serve::ServedMap next;
  next.map = s->map;
  next.frames = s->map->framesIntegrated();
  next.building = true;
  served_->publish(std::move(next));
}

bool Core::save(const std::string& path, std::string* said) {
  const auto s = snapshot();
  if (!s) {
    *said = "nothing to save: no frame was fused yet";
    return false;
  }
  try {
    mapping::MobilityMap copy(*s->map);
    copy.finalize();
    mapping::MapMetadata meta;
    mapping::MapRun& run = meta.latest;
    run.format = "mobmap-map-metadata";
    run.tool = std::string("mobmap live node ") + MOBMAP_VERSION_STRING;
    run.tree_type = mapping::MobilityOcTree::kTreeType;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      run.input = input_;
      run.world_frame = world_frame_;
      for (const Eigen::Vector3d& c : trajectory_world_) meta.trajectory_map.push_back(copy.worldToMap(c));
    }
    const int frames = s->map->framesIntegrated();
    meta.frames = frames;
    run.frames_in_run = frames;
    run.resolution_m = copy.tree().getResolution();
    run.R_map_world = copy.rotationMapWorld();
    run.origin_world = copy.originWorld();
    run.gravity_down_world = copy.rotationMapWorld().transpose() * Eigen::Vector3d(0, 0, -1);
    run.gravity_source = run.world_frame == "map" || run.world_frame == "odom" ? "the world frame (REP 105: z up)"
                                                                               : "`gravity` or the IMU";
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

void Core::clear() {
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
    map_stamp_ns_ = 0;
    std::fill(std::begin(published_), std::end(published_), 0);
  }
  old.reset();  // joins its threads; its frames not yet fused are dropped
  log(Level::kInfo, "map cleared");
}

void Core::shutdown() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (shut_down_) return;
    shut_down_ = stopping_ = true;
    wake_.notify_all();
  }
  if (feeder_.joinable()) feeder_.join();
  mapping::LiveMapper* m = nullptr;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    m = mapper_.get();
  }
  if (m) m->finish();
  if (!p_.save_on_exit.empty()) {
    std::string said;
    const bool ok = save(p_.save_on_exit, &said);
    log(ok ? Level::kInfo : Level::kError, said);
  }
}

}  // namespace mobmap::live
