// Writes a ROS 1 bag of a 7-Scenes layout sequence (mobmap simulate's) with Debian's
// rosbag_storage and the sensor_msgs / tf2_msgs message types, so that mobmap's ROS 1
// reading is checked against ROS's own serialisation.
//
//   write_bag1 --seq DIR --out FILE.bag [--compression none|bz2|lz4] [--layout camera|base]
//              [--world map|odom] [--frames N] [--tf tf2|old] [--killed-after N] [--chunk-kb K]
//
// The layouts are write_bag.mjs's: camera (map -> optical frame on /tf) or base (map ->
// odom, odom -> base_link sampled 5 ms either side of each image, the mounting on
// /tf_static). `--tf old` writes TF as the pre-tf2 type tf/tfMessage (the layout and MD5 of
// tf2_msgs/TFMessage under the name older bags carry). `--killed-after N` ends the
// process after the N-th image without closing the bag, as a killed `rosbag record`
// leaves it (no index; what rosbag had not handed to the OS is lost).
#include "mobmap/sources/png.hpp"

#include <Eigen/Geometry>
#include <rosbag/bag.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

// tf/tfMessage: tf2_msgs/TFMessage's fields and MD5 under the old name.
struct OldTfMessage : tf2_msgs::TFMessage {};

namespace ros {
namespace message_traits {
template <>
struct DataType<OldTfMessage> {
  static const char* value() { return "tf/tfMessage"; }
  static const char* value(const OldTfMessage&) { return value(); }
};
template <>
struct MD5Sum<OldTfMessage> : MD5Sum<tf2_msgs::TFMessage> {};
template <>
struct Definition<OldTfMessage> : Definition<tf2_msgs::TFMessage> {};
}  // namespace message_traits
namespace serialization {
template <>
struct Serializer<OldTfMessage> : Serializer<tf2_msgs::TFMessage> {};
}  // namespace serialization
}  // namespace ros

namespace {

namespace fs = std::filesystem;

Eigen::Isometry3d readPose(const std::string& path) {
  std::ifstream in(path);
  Eigen::Matrix4d m;
  for (int i = 0; i < 16; ++i) in >> m(i / 4, i % 4);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = m.topLeftCorner<3, 3>();
  T.translation() = m.topRightCorner<3, 1>();
  return T;
}

Eigen::Isometry3d pose(const Eigen::Vector3d& axis, double angle, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
  T.translation() = t;
  return T;
}

geometry_msgs::TransformStamped transform(const ros::Time& t, const std::string& parent, const std::string& child,
                                          const Eigen::Isometry3d& T) {
  geometry_msgs::TransformStamped m;
  m.header.stamp = t;
  m.header.frame_id = parent;
  m.child_frame_id = child;
  m.transform.translation.x = T.translation().x();
  m.transform.translation.y = T.translation().y();
  m.transform.translation.z = T.translation().z();
  const Eigen::Quaterniond q(T.linear());
  m.transform.rotation.x = q.x();
  m.transform.rotation.y = q.y();
  m.transform.rotation.z = q.z();
  m.transform.rotation.w = q.w();
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  std::map<std::string, std::string> args{{"compression", "lz4"}, {"layout", "camera"}, {"world", "map"}, {"frames", "0"}, {"tf", "tf2"}, {"killed-after", "0"}, {"chunk-kb", "512"}};
  for (int i = 1; i + 1 < argc; i += 2) args[std::string(argv[i]).substr(2)] = argv[i + 1];
  if (!args.count("seq") || !args.count("out")) {
    std::fprintf(stderr, "usage: write_bag1 --seq DIR --out FILE.bag [options]\n");
    return 2;
  }
  const std::string seq = args["seq"];
  std::vector<std::string> depths;
  for (const auto& e : fs::directory_iterator(seq)) {
    const std::string name = e.path().filename().string();
    if (name.rfind("frame-", 0) == 0 && name.find(".depth.png") != std::string::npos) depths.push_back(e.path().string());
  }
  std::sort(depths.begin(), depths.end());
  if (const int n = std::stoi(args["frames"]); n > 0 && static_cast<std::size_t>(n) < depths.size()) depths.resize(n);
  std::ifstream kin(seq + "/camera-intrinsics.txt");
  double K[9];
  for (double& k : K) kin >> k;

  rosbag::Bag bag(args["out"], rosbag::bagmode::Write);
  bag.setCompression(args["compression"] == "bz2"   ? rosbag::compression::BZ2
                     : args["compression"] == "lz4" ? rosbag::compression::LZ4
                                                    : rosbag::compression::Uncompressed);
  bag.setChunkThreshold(static_cast<std::uint32_t>(std::stoi(args["chunk-kb"])) * 1024);
  const std::string optical = "camera_depth_optical_frame";
  const bool base = args["layout"] == "base", map_world = args["world"] == "map";
  const Eigen::Isometry3d T_map_odom = pose(Eigen::Vector3d::UnitZ(), 0.5, Eigen::Vector3d(3.0, -2.0, 0.0));
  const Eigen::Isometry3d T_base_link = pose(Eigen::Vector3d::UnitY(), 0.3, Eigen::Vector3d(0.25, 0.05, 0.9));
  Eigen::Isometry3d T_link_optical = Eigen::Isometry3d::Identity();
  T_link_optical.linear() << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  T_link_optical.translation() = Eigen::Vector3d(0.0, 0.02, 0.0);
  const ros::Time t0(1700000000, 0);
  const bool old_tf = args["tf"] == "old";
  auto writeTf = [&](const std::string& topic, const ros::Time& t, const tf2_msgs::TFMessage& m) {
    if (!old_tf) return bag.write(topic, t, m);
    OldTfMessage old;
    old.transforms = m.transforms;
    bag.write(topic, t, old);
  };
  if (base) {
    tf2_msgs::TFMessage statics;
    statics.transforms = {transform(t0, "base_link", "camera_link", T_base_link), transform(t0, "camera_link", optical, T_link_optical)};
    writeTf("/tf_static", t0, statics);
  }
  for (std::size_t i = 0; i < depths.size(); ++i) {
    // Nanoseconds past a second carried into seconds (Duration(0, ns) takes an int32).
    ros::Duration since_start;
    since_start.fromNSec(std::llround(static_cast<double>(i) * 1e9 / 30.0));
    const ros::Time t = t0 + since_start;
    const std::string stem = depths[i].substr(0, depths[i].size() - std::string(".depth.png").size());
    const Eigen::Isometry3d T_world_camera = readPose(stem + ".pose.txt");
    if (!base) {
      tf2_msgs::TFMessage tf;
      tf.transforms = {transform(t, args["world"], optical, T_world_camera)};
      writeTf("/tf", t, tf);
    } else {
      // Samples 5 ms either side, turned and moved by equal and opposite amounts.
      const Eigen::Isometry3d T_odom_base =
          (map_world ? T_map_odom.inverse() : Eigen::Isometry3d::Identity()) * T_world_camera * (T_base_link * T_link_optical).inverse();
      const double angle = 0.01 * static_cast<double>(i % 5 + 1);
      const Eigen::Vector3d shift(0.003 * static_cast<double>(i % 3), -0.002, 0.001);
      for (const int sign : {-1, 1}) {
        const ros::Time ts = sign < 0 ? t - ros::Duration(0, 5000000) : t + ros::Duration(0, 5000000);
        Eigen::Isometry3d T = T_odom_base * pose(Eigen::Vector3d(0.3, 0.2, 1.0), sign * angle, Eigen::Vector3d::Zero());
        T.translation() = T_odom_base.translation() + sign * shift;
        tf2_msgs::TFMessage tf;
        tf.transforms = {transform(ts, "odom", "base_link", T)};
        if (map_world) tf.transforms.push_back(transform(ts, "map", "odom", T_map_odom));
        writeTf("/tf", ts, tf);
      }
    }
    const mobmap::sources::Image16 png = mobmap::sources::readPng16(depths[i]);
    sensor_msgs::CameraInfo info;
    info.header.stamp = t;
    info.header.frame_id = optical;
    info.width = static_cast<std::uint32_t>(png.width);
    info.height = static_cast<std::uint32_t>(png.height);
    info.distortion_model = "plumb_bob";
    info.D = {0, 0, 0, 0, 0};
    std::copy(K, K + 9, info.K.begin());
    bag.write("/camera/depth/camera_info", t, info);
    sensor_msgs::Image img;
    img.header = info.header;
    img.width = info.width;
    img.height = info.height;
    img.encoding = "16UC1";
    img.is_bigendian = 0;
    img.step = 2 * img.width;
    img.data.resize(png.pixels.size() * 2);
    for (std::size_t k = 0; k < png.pixels.size(); ++k) {
      img.data[2 * k] = static_cast<std::uint8_t>(png.pixels[k] & 0xff);
      img.data[2 * k + 1] = static_cast<std::uint8_t>(png.pixels[k] >> 8);
    }
    bag.write("/camera/depth/image_raw", t, img);
    if (static_cast<std::size_t>(std::stoi(args["killed-after"])) == i + 1) std::_Exit(0);
  }
  bag.close();
  return 0;
}
