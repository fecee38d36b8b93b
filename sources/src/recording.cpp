#include "mobmap/sources/recording.hpp"

#include "container.hpp"
#include "depth_decode.hpp"
#include "ros_messages.hpp"
#include "undistort.hpp"
#include "words.hpp"

#include "mobmap/sources/io_error.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>

namespace mobmap::sources {
namespace {

namespace fs = std::filesystem;

constexpr const char* kImage = "sensor_msgs/Image";
constexpr const char* kCompressed = "sensor_msgs/CompressedImage";
constexpr const char* kCameraInfo = "sensor_msgs/CameraInfo";
constexpr const char* kTf = "tf2_msgs/TFMessage";
// The pre-tf2 type (ROS 1 bags before Hydro's tf2, the TUM RGB-D dataset's): the same fields.
constexpr const char* kTfOld = "tf/tfMessage";
constexpr const char* kImu = "sensor_msgs/Imu";
constexpr double kGravity = 9.80665;

struct ImuReading {
  std::int64_t stamp_ns;
  std::uint32_t frame_id;
  Eigen::Vector3d acceleration;
};

std::string namespaceOf(const std::string& topic) {
  const auto slash = topic.find_last_of('/');
  return slash == std::string::npos ? std::string() : topic.substr(0, slash);
}

struct TopicStats {
  std::size_t count = 0;
  std::int64_t first = 0, last = 0;
  std::string first_encoding;  // an Image topic's first encoding, a CompressedImage topic's first format
};

struct IndexedImage {
  std::int64_t stamp_ns;
  std::size_t order;  // stored order, to keep equal stamps stable
  MessageRef ref;
  std::uint32_t frame_id;
  std::uint64_t bytes;  // the message's size as stored
};

class BagRecording : public Recording {
 public:
  BagRecording(const std::string& path, const RecordingOptions& options) : path_(path), options_(options) {
    std::error_code ec;
    const fs::path p(path);
    if (fs::is_directory(p, ec)) {
      if (!fs::exists(p / "metadata.yaml", ec) && !isBagFolderWithoutMetadata(path)) {
        throw IoError(path, "a folder without metadata.yaml or .db3 / .mcap files is not a ROS 2 bag");
      }
      container_ = openBagFolder(path);
    } else if (p.extension() == ".mcap") {
      container_ = openMcap(path);
    } else if (p.extension() == ".db3") {
      container_ = openDb3(path);
    } else if (p.extension() == ".bag" || isActiveRos1Bag(path)) {
      container_ = openRos1Bag(path);
    } else {
      throw IoError(path, "not a recording mobmap reads (a ROS 2 bag folder, .db3 or .mcap, or a ROS 1 .bag)");
    }
    const auto files = container_->files();
    const bool mcap = std::all_of(files.begin(), files.end(), [](const std::string& f) { return fs::path(f).extension() == ".mcap"; });
    const bool ros1 = p.extension() == ".bag" || isActiveRos1Bag(path);
    format_ = ros1 ? "ROS 1 bag" : mcap ? "ROS 2 bag (MCAP)" : "ROS 2 bag (sqlite3)";
    for (const std::string& f : files) {
      const auto n = fs::file_size(f, ec);
      if (!ec) file_bytes_ += n;
    }
    index();
    try {
      chooseTopics();
      poseImages();
      imuGravity();
      imus_.clear();  // what gravity needed of them is kept
    } catch (const IoError& e) {
      imus_.clear();
      // What the pass did not reach may be what is missing: said with the error.
      if (!options_.describe_only && !fault_.empty()) throw IoError(e.path(), e.reason() + "; the recording ends early (" + fault_ + ")");
      if (!options_.describe_only) throw;
      problem_ = e.reason();
      images_.clear();
      poses_.clear();
      posed_.clear();
    }
  }

  const std::string& path() const override { return path_; }
  std::string format() const override { return format_; }
  const std::vector<TopicSummary>& topics() const override { return summaries_; }
  const TfTree& tf() const override { return tf_; }
  const std::string& depthTopic() const override { return depth_topic_; }
  const std::string& cameraInfoTopic() const override { return camera_info_topic_; }
  const std::string& worldFrame() const override { return world_frame_; }
  const std::string& cameraFrame() const override { return camera_frame_; }
  const perception::PinholeIntrinsics& intrinsics() const override { return intrinsics_; }
  const std::string& distortionNote() const override { return distortion_note_; }
  double depthUnitsPerMetre() const override { return units_per_m_; }
  std::optional<Eigen::Vector3d> gravityDown() const override {
    if (imu_down_) return imu_down_;
    if (!options_.poses && (world_frame_ == "map" || world_frame_ == "odom")) return Eigen::Vector3d(0, 0, -1);
    return std::nullopt;
  }
  std::string gravitySource() const override {
    if (imu_down_) return imu_source_;
    return gravityDown() ? "the world frame " + world_frame_ + "'s -z (REP 105)" : std::string();
  }
  int imageCount() const override { return static_cast<int>(images_.size()); }
  const std::vector<int>& frames() const override { return posed_; }
  std::optional<Eigen::Isometry3d> pose(int n) const override { return poses_.at(static_cast<std::size_t>(n)); }
  std::int64_t stamp(int n) const override { return images_.at(static_cast<std::size_t>(n)).stamp_ns; }
  std::string skipped() const override { return skipped_; }
  const std::string& fault() const override { return fault_; }
  std::string recovered() const override { return container_->recovered(); }
  const std::string& problem() const override { return problem_; }
  std::vector<std::string> files() const override { return container_->files(); }
  std::size_t memoryBytes() const override {
    return images_.capacity() * sizeof(IndexedImage) + poses_.capacity() * sizeof(std::optional<Eigen::Isometry3d>) +
           tf_.memoryBytes() + posed_.capacity() * sizeof(int);
  }

  RecordingFrame load(int n) const override {
    const IndexedImage& img = images_.at(static_cast<std::size_t>(n));
    RecordingFrame f;
    f.number = n;
    f.stamp_ns = img.stamp_ns;
    f.frame_id = frame_ids_[img.frame_id];
    f.depth = decodeDepth(n);
    checkSize(f.depth, n);
    if (undistort_) f.depth = undistort_->apply(f.depth);
    f.T_world_camera = poses_[static_cast<std::size_t>(n)];
    return f;
  }

 private:
  std::string imageLabel(int n) const {
    return path_ + ": depth image " + std::to_string(n) + " on " + depth_topic_ + " (stamp " +
           seconds(images_[static_cast<std::size_t>(n)].stamp_ns) + ")";
  }

  // One pass: topic counts, the TF tree, every camera_info's first message, and where
  // each image of every image topic lies with its stamp (the depth topic is chosen after).
  void index() {
    std::map<int, std::vector<IndexedImage>> images;  // by container topic
    std::map<int, ros::CameraInfo> infos;
    std::map<std::string, std::uint32_t> frame_ids;
    std::vector<TopicStats> stats;
    std::size_t order = 0;
    // What the index may hold: 64 MiB + 16 times the files' sizes. A recorder's messages
    // are larger than what the index keeps of them (an image's place, a transform), so
    // only a hostile file (millions of tiny messages in chunks that expand a
    // thousand-fold) reaches it; the pass ends there as at a fault.
    const std::uint64_t most = (64ULL << 20) + 16 * file_bytes_;
    std::uint64_t held = 0;
    struct IndexFull {};
    const auto hold = [&](std::uint64_t bytes) {
      held += bytes;
      if (held > most) throw IndexFull{};
    };
    const auto frameId = [&](const std::string& name) {
      const auto id = frame_ids.emplace(name, static_cast<std::uint32_t>(frame_ids.size()));
      if (id.second) hold(name.size() + 64);
      return id.first->second;
    };
    std::optional<ContainerFault> fault;
    try {
      fault = container_->scan([&](const RawMessage& m) {
        const auto& topics = container_->topics();
        while (stats.size() < topics.size()) {
          hold(topics[stats.size()].name.size() + topics[stats.size()].type.size() + 128);
          stats.emplace_back();
        }
        const ContainerTopic& topic = topics[static_cast<std::size_t>(m.topic)];
        TopicStats& s = stats[static_cast<std::size_t>(m.topic)];
        if (s.count == 0) s.first = m.log_time_ns;
        s.last = m.log_time_ns;
        ++s.count;
        ros::Wire wire;
        if (!wireOf(topic.encoding, &wire)) return;
        try {
          if (topic.type == kTf || topic.type == kTfOld) {
            // /tf_static, or a robot's namespaced one (/robot1/tf_static).
            const bool is_static = topic.name.size() >= 10 && topic.name.compare(topic.name.size() - 10, 10, "/tf_static") == 0;
            for (const auto& t : ros::decodeTfMessage(m.data, m.size, wire)) {
              hold(64 + t.header.frame_id.size() + t.child_frame_id.size());
              const Eigen::Quaterniond q(t.rotation_xyzw[3], t.rotation_xyzw[0], t.rotation_xyzw[1], t.rotation_xyzw[2]);
              tf_.add(strip(t.header.frame_id), strip(t.child_frame_id), t.header.stamp_ns,
                      Eigen::Vector3d(t.translation[0], t.translation[1], t.translation[2]), q, is_static);
            }
          } else if (topic.type == kImu) {
            const ros::Imu imu = ros::decodeImu(m.data, m.size, wire);
            hold(sizeof(ImuReading));
            imus_[m.topic].push_back({imu.header.stamp_ns, frameId(strip(imu.header.frame_id)),
                                      Eigen::Vector3d(imu.linear_acceleration[0], imu.linear_acceleration[1], imu.linear_acceleration[2])});
          } else if (topic.type == kCameraInfo) {
            if (!infos.count(m.topic)) {
              infos[m.topic] = ros::decodeCameraInfo(m.data, m.size, wire);
              hold(sizeof(ros::CameraInfo) + 8 * infos[m.topic].d.size() + infos[m.topic].distortion_model.size());
            }
          } else if (topic.type == kImage || topic.type == kCompressed) {
            IndexedImage img;
            if (s.count == 1) {
              s.first_encoding = topic.type == kImage ? ros::decodeImage(m.data, m.size, wire).encoding
                                                      : ros::decodeCompressedImage(m.data, m.size, wire).format;
            }
            const ros::Header h = ros::decodeHeader(m.data, m.size, wire);
            img.stamp_ns = h.stamp_ns;
            img.order = order++;
            img.ref = m.ref;
            img.bytes = m.size;
            hold(sizeof(IndexedImage));
            img.frame_id = frameId(strip(h.frame_id));
            images[m.topic].push_back(img);
          }
        } catch (const ros::MessageError& e) {
          throw IoError(path_, "a " + topic.type + " message on " + topic.name + " cannot be decoded: " + e.what());
        } catch (const TfError& e) {
          throw IoError(path_, e.what());
        }
      });
    } catch (const IndexFull&) {
      fault = ContainerFault{path_ + ": indexing it would hold more than " + std::to_string(most >> 20) + " MiB (64 MiB + 16 times its " +
                             std::to_string(file_bytes_) + " bytes): far more, or far smaller, messages than a recorder writes"};
    }
    if (fault) fault_ = fault->what;
    tf_.sortSamples();
    const auto& topics = container_->topics();
    stats.resize(topics.size());
    frame_ids_.resize(frame_ids.size());
    for (const auto& [name, id] : frame_ids) frame_ids_[id] = name;
    for (std::size_t i = 0; i < topics.size(); ++i) {
      TopicSummary t{topics[i].name, topics[i].type, stats[i].count, 0.0};
      if (stats[i].count > 1 && stats[i].last > stats[i].first) {
        t.rate_hz = static_cast<double>(stats[i].count - 1) / ((static_cast<double>(stats[i].last) - static_cast<double>(stats[i].first)) * 1e-9);
      }
      summaries_.push_back(t);
    }
    all_images_ = std::move(images);
    infos_ = std::move(infos);
    stats_ = std::move(stats);
  }

  // tf2 frame names carry no leading slash; ROS 1 recordings sometimes do.
  static std::string strip(const std::string& frame) { return !frame.empty() && frame[0] == '/' ? frame.substr(1) : frame; }

  bool isDepthTopic(int t) const {
    const auto& topic = container_->topics()[static_cast<std::size_t>(t)];
    const std::string& first = stats_[static_cast<std::size_t>(t)].first_encoding;
    if (topic.type == kImage) return isDepthEncoding(first);
    return !compressedDepthEncoding(first).empty();
  }

  void chooseTopics() {
    const auto& topics = container_->topics();
    int depth = -1;
    if (!options_.depth_topic.empty()) {
      std::vector<std::string> images;
      for (const auto& [t, list] : all_images_) {
        images.push_back(topics[static_cast<std::size_t>(t)].name);
        if (images.back() == options_.depth_topic) depth = t;
      }
      if (depth < 0) {
        throw IoError(path_, "has no image topic " + options_.depth_topic + " (its image topics: " + listed(images) + ")");
      }
      if (!isDepthTopic(depth)) {
        const auto& s = stats_[static_cast<std::size_t>(depth)];
        throw IoError(path_, options_.depth_topic + " holds " +
                                 (topics[static_cast<std::size_t>(depth)].type == kImage ? "\"" + s.first_encoding + "\" images"
                                                                                       : "\"" + s.first_encoding + "\" compressed images") +
                                 ", not depth (mobmap reads 16UC1 millimetres, 32FC1 metres, or either as compressedDepth)");
      }
    } else {
      std::vector<int> candidates;
      std::vector<std::string> names, others;
      for (const auto& [t, list] : all_images_) {
        if (isDepthTopic(t)) {
          candidates.push_back(t);
          names.push_back(topics[static_cast<std::size_t>(t)].name);
        } else {
          others.push_back(topics[static_cast<std::size_t>(t)].name + " (" + stats_[static_cast<std::size_t>(t)].first_encoding + ")");
        }
      }
      // A camera's raw depth and its compressedDepth republication are one camera: the raw one is read.
      if (candidates.size() == 2) {
        const auto& a = topics[static_cast<std::size_t>(candidates[0])];
        const auto& b = topics[static_cast<std::size_t>(candidates[1])];
        if (b.name == a.name + "/compressedDepth" && a.type == kImage) candidates.pop_back();
        else if (a.name == b.name + "/compressedDepth" && b.type == kImage) candidates.erase(candidates.begin());
      }
      if (candidates.empty()) {
        throw IoError(path_, "has no depth image topic (16UC1 or 32FC1 sensor_msgs/Image, or compressedDepth); its other image topics: " +
                                 listed(others));
      }
      if (candidates.size() > 1) {
        throw IoError(path_, "has " + std::to_string(candidates.size()) + " depth image topics; choose one with `depth_topic`: " + listed(names));
      }
      depth = candidates.front();
    }
    const ContainerTopic& dt = topics[static_cast<std::size_t>(depth)];
    depth_topic_ = dt.name;
    depth_compressed_ = dt.type == kCompressed;
    wireOf(dt.encoding, &depth_wire_);
    images_ = std::move(all_images_[depth]);
    all_images_.clear();
    std::stable_sort(images_.begin(), images_.end(), [](const IndexedImage& a, const IndexedImage& b) {
      return a.stamp_ns != b.stamp_ns ? a.stamp_ns < b.stamp_ns : a.order < b.order;
    });
    if (images_.empty()) throw IoError(path_, depth_topic_ + " holds no images");
    camera_frame_ = frame_ids_[images_.front().frame_id];

    // The first image, decoded now: a wrong encoding or size stops the run before it starts.
    const perception::DepthImage first = decodeDepth(0, &units_per_m_);
    if (options_.intrinsics) {
      intrinsics_ = options_.intrinsics(first.width, first.height);
    } else {
      chooseCameraInfo();
    }
    checkSize(first, 0);
    camera_known_ = true;
    limitPixels();
  }

  // What decoding the images may cost: at most 16 Mi pixels + 16 a byte of the files
  // (raw depth stores 2 bytes a pixel; compressed, a recorder's depth keeps well under
  // 16 pixels a byte). A hostile file whose chunks or PNGs expand to millions of frames
  // is read up to there, as at a fault.
  void limitPixels() {
    const std::uint64_t most = (16ULL << 20) + 16 * file_bytes_;
    const auto pixels = static_cast<std::uint64_t>(intrinsics_.width) * static_cast<std::uint64_t>(intrinsics_.height);
    if (pixels == 0 || images_.size() * pixels <= most) return;
    const std::size_t keep = static_cast<std::size_t>(std::max<std::uint64_t>(1, most / pixels));
    const std::string why = path_ + ": its " + std::to_string(images_.size()) + " depth images of " + std::to_string(intrinsics_.width) +
                            "x" + std::to_string(intrinsics_.height) + " would decode to more than " + std::to_string(most) +
                            " pixels (16 Mi + 16 a byte of its " + std::to_string(file_bytes_) + " bytes): the first " +
                            std::to_string(keep) + " are read";
    images_.resize(keep);
    fault_ += (fault_.empty() ? "" : "; ") + why;
  }

  perception::DepthImage decodeDepth(int n, double* units_per_m = nullptr) const {
    const IndexedImage& img = images_.at(static_cast<std::size_t>(n));
    const std::string what = imageLabel(n);
    // Once the camera is known, no image is read that is larger than its pixels can need
    // (8 bytes a pixel, rows padded to twice their width, and 1 MiB for the rest): a
    // hostile recording's huge message is refused before it is in memory.
    const auto pixels = static_cast<std::uint64_t>(intrinsics_.width) * static_cast<std::uint64_t>(intrinsics_.height);
    if (camera_known_ && img.bytes > 8 * pixels + (1u << 20)) {
      throw IoError(what, "its message is " + std::to_string(img.bytes) + " bytes, more than a " + std::to_string(intrinsics_.width) +
                              "x" + std::to_string(intrinsics_.height) + " depth image can need");
    }
    const std::vector<std::uint8_t> bytes = container_->read(img.ref);
    try {
      if (depth_compressed_) {
        const auto m = ros::decodeCompressedImage(bytes.data(), bytes.size(), depth_wire_);
        if (units_per_m) *units_per_m = compressedDepthEncoding(m.format) == "32FC1" ? 1.0 : 1000.0;
        return depthFromCompressed(m, what);
      }
      const auto m = ros::decodeImage(bytes.data(), bytes.size(), depth_wire_);
      if (units_per_m) *units_per_m = m.encoding == "32FC1" ? 1.0 : 1000.0;
      return depthFromImage(m, what);
    } catch (const ros::MessageError& e) {
      throw IoError(what, std::string("cannot be decoded: ") + e.what());
    }
  }

  void checkSize(const perception::DepthImage& d, int n) const {
    if (d.width != intrinsics_.width || d.height != intrinsics_.height) {
      throw IoError(imageLabel(n), "the image is " + std::to_string(d.width) + "x" + std::to_string(d.height) + " but " +
                                       (camera_info_topic_.empty() ? std::string("the intrinsics given are for ")
                                                                   : "its camera_info (" + camera_info_topic_ + ") is for ") +
                                       std::to_string(intrinsics_.width) + "x" + std::to_string(intrinsics_.height));
    }
  }

  void chooseCameraInfo() {
    const auto& topics = container_->topics();
    std::vector<std::string> all;
    int chosen = -1;
    std::size_t best = 0;
    // The depth topic's own namespace, with a transport's suffix taken off.
    std::string ns = namespaceOf(depth_topic_);
    if (depth_compressed_ && depth_topic_.size() > 16 && depth_topic_.substr(depth_topic_.size() - 16) == "/compressedDepth") {
      ns = namespaceOf(depth_topic_.substr(0, depth_topic_.size() - 16));
    }
    for (std::size_t t = 0; t < topics.size(); ++t) {
      if (topics[t].type != kCameraInfo) continue;
      all.push_back(topics[t].name);
      if (!options_.camera_info_topic.empty()) {
        if (topics[t].name == options_.camera_info_topic) chosen = static_cast<int>(t);
        continue;
      }
      // The camera_info whose namespace is the depth topic's, or the nearest one above it.
      const std::string its = namespaceOf(topics[t].name);
      if ((ns == its || ns.rfind(its + "/", 0) == 0) && (chosen < 0 || its.size() > best)) {
        chosen = static_cast<int>(t);
        best = its.size();
      }
    }
    if (chosen < 0) {
      if (!options_.camera_info_topic.empty()) {
        throw IoError(path_, "has no camera_info topic " + options_.camera_info_topic + " (its camera_info topics: " + listed(all) + ")");
      }
      throw IoError(path_, "has no camera_info in " + (ns.empty() ? std::string("/") : ns) + " for " + depth_topic_ +
                               "; choose one with `camera_info_topic` (its camera_info topics: " + listed(all) +
                               ") or give `intrinsics`");
    }
    camera_info_topic_ = topics[static_cast<std::size_t>(chosen)].name;
    const auto info = infos_.find(chosen);
    if (info == infos_.end()) throw IoError(path_, camera_info_topic_ + " holds no message");
    const ros::CameraInfo& ci = info->second;
    const std::string what = path_ + ": " + camera_info_topic_;
    perception::PinholeIntrinsics k;
    k.width = static_cast<int>(std::min<std::uint32_t>(ci.width, 1u << 30));
    k.height = static_cast<int>(std::min<std::uint32_t>(ci.height, 1u << 30));
    k.fx = ci.k[0];
    k.fy = ci.k[4];
    k.cx = ci.k[2];
    k.cy = ci.k[5];
    try {
      perception::validate(k);
    } catch (const std::invalid_argument& e) {
      throw IoError(what, std::string("its K does not describe a camera: ") + e.what());
    }
    intrinsics_ = k;
    const bool distorted = std::any_of(ci.d.begin(), ci.d.end(), [](double x) { return x != 0.0; });
    if (!distorted) return;
    if (ci.distortion_model != "plumb_bob" || ci.d.size() < 4) {
      throw IoError(what, "its distortion model \"" + ci.distortion_model + "\" has non-zero coefficients; mobmap undoes plumb_bob "
                          "only (give `intrinsics` to read the images as they are)");
    }
    undistort_ = std::make_unique<Undistorter>(k, ci.d);
    char note[200];
    std::snprintf(note, sizeof note, "plumb_bob distortion (k1 %.4g, k2 %.4g, p1 %.4g, p2 %.4g, k3 %.4g) undone", ci.d[0], ci.d[1], ci.d[2],
                  ci.d[3], ci.d.size() > 4 ? ci.d[4] : 0.0);
    distortion_note_ = note;
  }

  // Gravity from the accelerometer: at rest it reads the reaction to gravity, so down is
  // -a / |a| in the IMU's frame. Readings are kept while the robot is still (|a| within
  // 2 % of g), each taken to the world frame at its stamp, and averaged.
  void imuGravity() {
    if (options_.poses) {
      if (!options_.imu_topic.empty()) {
        throw IoError(path_, "`imu_topic` places the IMU through the TF tree, whose world frame a trajectory given instead has not");
      }
      return;
    }
    const auto& topics = container_->topics();
    int chosen = -1;
    std::vector<std::string> names;
    for (const auto& [t, readings] : imus_) names.push_back(topics[static_cast<std::size_t>(t)].name);
    if (!options_.imu_topic.empty()) {
      for (const auto& [t, readings] : imus_) {
        if (topics[static_cast<std::size_t>(t)].name == options_.imu_topic) chosen = t;
      }
      if (chosen < 0) throw IoError(path_, "has no Imu topic " + options_.imu_topic + " (its Imu topics: " + listed(names) + ")");
    } else {
      if (world_frame_ == "map" || world_frame_ == "odom" || imus_.empty()) return;
      if (imus_.size() > 1) {
        throw IoError(path_, "the world frame " + world_frame_ + " does not say where down is and the recording has " +
                                 std::to_string(imus_.size()) + " Imu topics; choose one with `imu_topic`: " + listed(names));
      }
      chosen = imus_.begin()->first;
    }
    imu_topic_ = topics[static_cast<std::size_t>(chosen)].name;
    const auto gap = static_cast<std::int64_t>(std::llround(options_.max_pose_gap_s * 1e9));
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    std::vector<Eigen::Vector3d> downs;
    const auto& readings = imus_.at(chosen);
    for (const ImuReading& r : readings) {
      const double g = r.acceleration.norm();
      if (!std::isfinite(g) || std::abs(g - kGravity) > 0.02 * kGravity) continue;
      std::optional<Eigen::Isometry3d> T;
      try {
        T = tf_.lookup(world_frame_, frame_ids_[r.frame_id], r.stamp_ns, gap);
      } catch (const TfError& e) {
        throw IoError(path_, std::string(imu_topic_ + "'s frame cannot be placed in " + world_frame_ + ": ") + e.what());
      }
      if (!T) continue;
      const Eigen::Vector3d down = T->linear() * (-r.acceleration / g);
      downs.push_back(down);
      sum += down;
    }
    if (downs.size() < 10 || sum.norm() < 1e-9) {
      throw IoError(path_, imu_topic_ + " has " + std::to_string(downs.size()) + " of " + std::to_string(readings.size()) +
                               " readings taken while still (|a| within 2 % of g) and placed in " + world_frame_ +
                               " through TF; at least 10 are needed to find gravity (or give `gravity`)");
    }
    const Eigen::Vector3d mean = sum.normalized();
    double spread = 0.0;
    for (const auto& d : downs) spread = std::max(spread, std::acos(std::clamp(d.dot(mean), -1.0, 1.0)) * 180.0 / M_PI);
    imu_down_ = mean;
    char text[300];
    std::snprintf(text, sizeof text, "the IMU on %s (%zu of %zu readings taken while still, within %.2f degrees of their mean)",
                  imu_topic_.c_str(), downs.size(), readings.size(), spread);
    imu_source_ = text;
    imus_.clear();
  }

  void poseImages() {
    if (options_.poses) {
      std::size_t unposed = 0;
      poses_.resize(images_.size());
      for (std::size_t i = 0; i < images_.size(); ++i) {
        poses_[i] = options_.poses(images_[i].stamp_ns);
        if (poses_[i]) {
          posed_.push_back(static_cast<int>(i));
        } else {
          ++unposed;
        }
      }
      if (unposed > 0) {
        skipped_ = std::to_string(unposed) + " of " + std::to_string(images_.size()) +
                   " depth images without a pose of the trajectory given near their stamp";
      }
      return;
    }
    if (!options_.world_frame.empty()) {
      world_frame_ = options_.world_frame;
    } else if (tf_.has("map")) {
      world_frame_ = "map";
    } else if (tf_.has("odom")) {
      world_frame_ = "odom";
    } else if (tf_.has(camera_frame_)) {
      try {
        world_frame_ = tf_.chainToRoot(camera_frame_).back();  // the root of the camera's tree
      } catch (const TfError& e) {
        throw IoError(path_, e.what());
      }
    } else {
      throw IoError(path_, "the depth images' frame \"" + camera_frame_ + "\" is not in the TF tree (its frames: " +
                               listed(tf_.frames()) + ")");
    }
    if (!tf_.has(world_frame_)) {
      throw IoError(path_, "`world_frame` " + world_frame_ + " is not in the TF tree (its frames: " + listed(tf_.frames()) + ")");
    }
    const auto gap = static_cast<std::int64_t>(std::llround(options_.max_pose_gap_s * 1e9));
    poses_.resize(images_.size());
    std::size_t unposed = 0;
    std::string first_why;
    for (std::size_t i = 0; i < images_.size(); ++i) {
      std::string why;
      try {
        poses_[i] = tf_.lookup(world_frame_, frame_ids_[images_[i].frame_id], images_[i].stamp_ns, gap, &why);
      } catch (const TfError& e) {
        const bool statics = std::any_of(summaries_.begin(), summaries_.end(), [](const TopicSummary& t) { return t.name == "/tf_static"; });
        throw IoError(path_, std::string(e.what()) + (statics ? "" : "; the recording has no /tf_static, where a robot's fixed transforms (its camera's mounting) are published"));
      }
      if (poses_[i]) {
        posed_.push_back(static_cast<int>(i));
      } else {
        ++unposed;
        if (first_why.empty()) first_why = "image " + std::to_string(i) + ": " + why;
      }
    }
    if (unposed > 0) {
      char gap_text[32];
      std::snprintf(gap_text, sizeof gap_text, "%g", options_.max_pose_gap_s);
      skipped_ = std::to_string(unposed) + " of " + std::to_string(images_.size()) + " depth images without a pose in " + world_frame_ +
                 " within `max_pose_gap_s` " + gap_text + " s (" + first_why + ")";
    }
  }

  std::string path_;
  RecordingOptions options_;
  std::unique_ptr<Container> container_;
  std::uint64_t file_bytes_ = 0;  // the container's files together: what the index and the pixels are bounded by
  std::string format_;
  TfTree tf_;
  std::vector<TopicSummary> summaries_;
  std::vector<TopicStats> stats_;
  std::map<int, std::vector<IndexedImage>> all_images_;
  std::map<int, ros::CameraInfo> infos_;
  std::vector<std::string> frame_ids_;
  std::vector<IndexedImage> images_;
  std::vector<std::optional<Eigen::Isometry3d>> poses_;
  std::vector<int> posed_;
  std::string depth_topic_, camera_info_topic_, world_frame_, camera_frame_, imu_topic_;
  bool depth_compressed_ = false;
  ros::Wire depth_wire_ = ros::Wire::kCdr;
  perception::PinholeIntrinsics intrinsics_;
  bool camera_known_ = false;  // intrinsics_ is the camera's (chooseTopics() done)
  std::unique_ptr<Undistorter> undistort_;
  std::string distortion_note_;
  double units_per_m_ = 1000.0;  // the first image's; every image of a topic has its encoding
  std::string skipped_;
  std::string fault_;
  std::string problem_;
  std::map<int, std::vector<ImuReading>> imus_;  // by container topic
  std::optional<Eigen::Vector3d> imu_down_;
  std::string imu_source_;
};

}  // namespace

bool isRecording(const std::string& path) {
  std::error_code ec;
  const fs::path p(path);
  if (fs::is_directory(p, ec)) return fs::exists(p / "metadata.yaml", ec) || isBagFolderWithoutMetadata(path);
  const auto ext = p.extension();
  return ext == ".mcap" || ext == ".db3" || ext == ".bag" || isActiveRos1Bag(path);
}

std::unique_ptr<Recording> Recording::open(const std::string& path, const RecordingOptions& options) {
  return std::make_unique<BagRecording>(path, options);
}

}  // namespace mobmap::sources
