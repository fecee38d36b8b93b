// The ROS message decoder on messages built field by field as each wire format lays
// them out (CDR: aligned from the end of its 4-byte header, either byte order; ROS 1:
// packed), and on messages that end early or claim more than they hold.
#include "depth_decode.hpp"
#include "ros_messages.hpp"

#include "mobmap/sources/io_error.hpp"

#include <gtest/gtest.h>

#include <cstring>

namespace mobmap::sources::ros {
namespace {

// Lays out fields as one wire format does.
class Writer {
 public:
  Writer(Wire wire, bool big_endian = false) : wire_(wire), big_(big_endian) {
    if (wire_ == Wire::kCdr) bytes_ = {0, static_cast<std::uint8_t>(big_ ? 0 : 1), 0, 0};
  }
  template <typename T>
  Writer& put(T v) {
    align(sizeof(T));
    std::uint8_t b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (big_) std::reverse(b, b + sizeof(T));
    bytes_.insert(bytes_.end(), b, b + sizeof(T));
    return *this;
  }
  Writer& str(const std::string& s) {
    put<std::uint32_t>(static_cast<std::uint32_t>(s.size() + (wire_ == Wire::kCdr ? 1 : 0)));
    bytes_.insert(bytes_.end(), s.begin(), s.end());
    if (wire_ == Wire::kCdr) bytes_.push_back(0);
    return *this;
  }
  Writer& header(std::int32_t sec, std::uint32_t nsec, const std::string& frame) {
    if (wire_ == Wire::kRos1) put<std::uint32_t>(7);  // seq
    put<std::int32_t>(sec).put<std::uint32_t>(nsec);
    return str(frame);
  }
  Writer& raw(const std::vector<std::uint8_t>& b) {
    put<std::uint32_t>(static_cast<std::uint32_t>(b.size()));
    bytes_.insert(bytes_.end(), b.begin(), b.end());
    return *this;
  }
  const std::vector<std::uint8_t>& bytes() const { return bytes_; }

 private:
  void align(std::size_t n) {
    if (wire_ != Wire::kCdr) return;
    while ((bytes_.size() - 4) % n != 0) bytes_.push_back(0);
  }
  Wire wire_;
  bool big_;
  std::vector<std::uint8_t> bytes_;
};

std::vector<std::uint8_t> depthImage(Wire wire, bool big_endian, const std::string& encoding, std::uint32_t step) {
  Writer w(wire, big_endian);
  w.header(1700000000, 250000000, "camera_depth_optical_frame").put<std::uint32_t>(2).put<std::uint32_t>(3).str(encoding);
  w.put<std::uint8_t>(0).put<std::uint32_t>(step);
  std::vector<std::uint8_t> px;
  for (std::uint32_t v = 0; v < 2; ++v) {
    for (std::uint32_t u = 0; u < step; u += 2) {
      const std::uint16_t mm = u / 2 < 3 ? static_cast<std::uint16_t>(1000 + 10 * (3 * v + u / 2)) : 0xEEEE;  // padding past the row
      px.push_back(static_cast<std::uint8_t>(mm & 0xff));
      px.push_back(static_cast<std::uint8_t>(mm >> 8));
    }
  }
  w.raw(px);
  return w.bytes();
}

TEST(RosMessages, ImagesDecodeInEveryWireAndByteOrder) {
  for (const auto& [wire, big] : {std::pair{Wire::kCdr, false}, std::pair{Wire::kCdr, true}, std::pair{Wire::kRos1, false}}) {
    SCOPED_TRACE(static_cast<int>(wire) * 2 + big);
    const auto bytes = depthImage(wire, big, "16UC1", 8);  // rows padded to 8 bytes
    const Image m = decodeImage(bytes.data(), bytes.size(), wire);
    EXPECT_EQ(m.header.stamp_ns, 1700000000250000000LL);
    EXPECT_EQ(m.header.frame_id, "camera_depth_optical_frame");
    EXPECT_EQ(m.width, 3u);
    EXPECT_EQ(m.height, 2u);
    EXPECT_EQ(m.encoding, "16UC1");
    EXPECT_EQ(m.step, 8u);
    const perception::DepthImage d = depthFromImage(m, "image");
    ASSERT_EQ(d.width, 3);
    for (int v = 0; v < 2; ++v) {
      for (int u = 0; u < 3; ++u) EXPECT_FLOAT_EQ(d.at(u, v), static_cast<float>(1000 + 10 * (3 * v + u)) * 1e-3f);
    }
  }
}

TEST(RosMessages, CameraInfoAndTransformsDecode) {
  for (const Wire wire : {Wire::kCdr, Wire::kRos1}) {
    Writer w(wire);
    w.header(5, 6, "cam").put<std::uint32_t>(480).put<std::uint32_t>(640).str("plumb_bob").put<std::uint32_t>(5);
    for (double d : {0.1, -0.2, 0.0, 0.0, 0.05}) w.put<double>(d);
    for (double k : {525.0, 0.0, 319.5, 0.0, 526.0, 239.5, 0.0, 0.0, 1.0}) w.put<double>(k);
    const CameraInfo ci = decodeCameraInfo(w.bytes().data(), w.bytes().size(), wire);
    EXPECT_EQ(ci.width, 640u);
    EXPECT_EQ(ci.distortion_model, "plumb_bob");
    ASSERT_EQ(ci.d.size(), 5u);
    EXPECT_EQ(ci.d[1], -0.2);
    EXPECT_EQ(ci.k[4], 526.0);
    EXPECT_EQ(ci.k[5], 239.5);

    Writer tf(wire);
    tf.put<std::uint32_t>(2);
    for (int i = 0; i < 2; ++i) {
      tf.header(10 + i, 0, "odom").str(i == 0 ? "base_link" : "imu");
      for (double x : {1.0 + i, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0}) tf.put<double>(x);
    }
    const auto transforms = decodeTfMessage(tf.bytes().data(), tf.bytes().size(), wire);
    ASSERT_EQ(transforms.size(), 2u);
    EXPECT_EQ(transforms[1].child_frame_id, "imu");
    EXPECT_EQ(transforms[1].header.stamp_ns, 11 * 1000000000LL);
    EXPECT_EQ(transforms[1].translation[0], 2.0);
    EXPECT_EQ(transforms[1].rotation_xyzw[3], 1.0);
  }
}

TEST(RosMessages, ShortOrLyingMessagesThrow) {
  const auto bytes = depthImage(Wire::kCdr, false, "16UC1", 6);
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    EXPECT_THROW((void)decodeImage(bytes.data(), n, Wire::kCdr), MessageError) << n;
  }
  Writer w(Wire::kCdr);
  w.put<std::uint32_t>(0x7fffffff);  // transforms claimed
  EXPECT_THROW((void)decodeTfMessage(w.bytes().data(), w.bytes().size(), Wire::kCdr), MessageError);
  const std::vector<std::uint8_t> xcdr2 = {0, 7, 0, 0, 1, 2, 3, 4};
  EXPECT_THROW((void)decodeHeader(xcdr2.data(), xcdr2.size(), Wire::kCdr), MessageError);
}

TEST(RosMessages, DepthThatIsNotDepthMobmapReadsIsRefusedByName) {
  auto refuse = [](const std::vector<std::uint8_t>& bytes, const std::string& reason) {
    const Image m = decodeImage(bytes.data(), bytes.size(), Wire::kCdr);
    try {
      (void)depthFromImage(m, "img");
      ADD_FAILURE() << "accepted";
    } catch (const IoError& e) {
      EXPECT_NE(std::string(e.what()).find(reason), std::string::npos) << e.what();
    }
  };
  refuse(depthImage(Wire::kCdr, false, "mono16", 6), "its encoding is \"mono16\", not depth");
  refuse(depthImage(Wire::kCdr, false, "16UC1", 4), "its step is 4 bytes, less than a row of 3 16UC1 pixels (6)");
  auto big = depthImage(Wire::kCdr, false, "16UC1", 6);
  const Image m = decodeImage(big.data(), big.size(), Wire::kCdr);
  Image flagged = m;
  flagged.big_endian = true;
  EXPECT_THROW((void)depthFromImage(flagged, "img"), IoError);
  Image lying = m;
  lying.height = 3;
  EXPECT_THROW((void)depthFromImage(lying, "img"), IoError);
  EXPECT_EQ(compressedDepthEncoding("16UC1; compressedDepth png"), "16UC1");
  EXPECT_EQ(compressedDepthEncoding("32FC1; compressedDepth"), "32FC1");
  EXPECT_EQ(compressedDepthEncoding("rgb8; jpeg compressed bgr8"), "");
}

}  // namespace
}  // namespace mobmap::sources::ros
