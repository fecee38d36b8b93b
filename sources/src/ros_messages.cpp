#include "ros_messages.hpp"

#include <cstring>

namespace mobmap::sources::ros {
namespace {

// Reads fields in order from one message. CDR aligns each primitive to its size (at
// most 8) counted from the end of the encapsulation header; ROS 1 packs them.
class Reader {
 public:
  Reader(const std::uint8_t* data, std::size_t size, Wire wire) : data_(data), size_(size), wire_(wire) {
    if (wire_ == Wire::kCdr) {
      if (size_ < 4) throw MessageError("shorter than CDR's 4-byte encapsulation header");
      if (data_[0] != 0 || data_[1] > 1) {
        throw MessageError("CDR encapsulation " + std::to_string(data_[0]) + "," + std::to_string(data_[1]) +
                           " is not plain CDR (0,0 big-endian or 0,1 little-endian)");
      }
      big_endian_ = data_[1] == 0;
      origin_ = at_ = 4;
    }
  }

  template <typename T>
  T get() {
    align(sizeof(T));
    need(sizeof(T), "a field");
    unsigned char bytes[sizeof(T)];
    std::memcpy(bytes, data_ + at_, sizeof(T));
    if (big_endian_) {
      for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(bytes[i], bytes[sizeof(T) - 1 - i]);
    }
    at_ += sizeof(T);
    T v;
    std::memcpy(&v, bytes, sizeof(T));
    return v;
  }

  std::uint32_t count(std::size_t element_size, const char* what) {
    const auto n = get<std::uint32_t>();
    // Checked against what is left before anything is allocated.
    if (element_size > 0 && n > (size_ - at_) / element_size + 1) {
      throw MessageError(std::string(what) + " claims " + std::to_string(n) + " elements, more than the message holds");
    }
    return n;
  }

  std::string string(const char* what) {
    const std::uint32_t n = count(1, what);
    need(n, what);
    std::size_t len = n;
    // CDR counts the terminating NUL; ROS 1 does not store one.
    if (wire_ == Wire::kCdr && len > 0 && data_[at_ + len - 1] == 0) --len;
    std::string s(reinterpret_cast<const char*>(data_ + at_), len);
    at_ += n;
    return s;
  }

  const std::uint8_t* bytes(std::size_t* size, const char* what) {
    const std::uint32_t n = count(1, what);
    need(n, what);
    const std::uint8_t* p = data_ + at_;
    at_ += n;
    *size = n;
    return p;
  }

  template <std::size_t N>
  std::array<double, N> doubles() {
    std::array<double, N> v{};
    for (auto& x : v) x = get<double>();
    return v;
  }

  std::int64_t time() {
    std::int64_t sec = 0;
    if (wire_ == Wire::kRos1) {
      sec = get<std::uint32_t>();
    } else {
      sec = get<std::int32_t>();
    }
    const auto nsec = get<std::uint32_t>();
    if (nsec >= 1000000000u) throw MessageError("a stamp's nanoseconds are " + std::to_string(nsec) + ", not below 1e9");
    return sec * 1000000000LL + nsec;
  }

  Header header() {
    if (wire_ == Wire::kRos1) (void)get<std::uint32_t>();  // seq
    Header h;
    h.stamp_ns = time();
    h.frame_id = string("header.frame_id");
    return h;
  }

 private:
  void align(std::size_t n) {
    if (wire_ != Wire::kCdr) return;
    const std::size_t a = n > 8 ? 8 : n;
    const std::size_t rel = at_ - origin_;
    const std::size_t pad = (a - rel % a) % a;
    need(pad, "padding");
    at_ += pad;
  }
  void need(std::size_t n, const char* what) const {
    if (n > size_ - at_) {
      throw MessageError(std::string("the message ends inside ") + what + " (" + std::to_string(size_) + " bytes)");
    }
  }

  const std::uint8_t* data_;
  std::size_t size_;
  Wire wire_;
  bool big_endian_ = false;
  std::size_t origin_ = 0;
  std::size_t at_ = 0;
};

}  // namespace

Header decodeHeader(const std::uint8_t* data, std::size_t size, Wire wire) {
  Reader r(data, size, wire);
  return r.header();
}

std::int64_t decodeClock(const std::uint8_t* data, std::size_t size, Wire wire) {
  Reader r(data, size, wire);
  return r.time();
}

Image decodeImage(const std::uint8_t* data, std::size_t size, Wire wire) {
  Reader r(data, size, wire);
  Image m;
  m.header = r.header();
  m.height = r.get<std::uint32_t>();
  m.width = r.get<std::uint32_t>();
  m.encoding = r.string("encoding");
  m.big_endian = r.get<std::uint8_t>() != 0;
  m.step = r.get<std::uint32_t>();
  m.data = r.bytes(&m.data_size, "data");
  return m;
}

CompressedImage decodeCompressedImage(const std::uint8_t* data, std::size_t size, Wire wire) {
  Reader r(data, size, wire);
  CompressedImage m;
  m.header = r.header();
  m.format = r.string("format");
  m.data = r.bytes(&m.data_size, "data");
  return m;
}

CameraInfo decodeCameraInfo(const std::uint8_t* data, std::size_t size, Wire wire) {
  Reader r(data, size, wire);
  CameraInfo m;
  m.header = r.header();
  m.height = r.get<std::uint32_t>();
  m.width = r.get<std::uint32_t>();
  m.distortion_model = r.string("distortion_model");
  const std::uint32_t nd = r.count(8, "D");
  m.d.reserve(nd);
  for (std::uint32_t i = 0; i < nd; ++i) m.d.push_back(r.get<double>());
  m.k = r.doubles<9>();
  return m;
}

std::vector<Transform> decodeTfMessage(const std::uint8_t* data, std::size_t size, Wire wire, std::size_t max_transforms) {
  Reader r(data, size, wire);
  // A transform takes at least its header's stamp, two string lengths and 7 doubles.
  const std::uint32_t n = r.count(wire == Wire::kCdr ? 72 : 76, "transforms");
  if (n > max_transforms) {
    throw MessageError("holds " + std::to_string(n) + " transforms, more than " + std::to_string(max_transforms));
  }
  std::vector<Transform> out;
  out.reserve(n);
  for (std::uint32_t i = 0; i < n; ++i) {
    Transform t;
    t.header = r.header();
    t.child_frame_id = r.string("child_frame_id");
    t.translation = r.doubles<3>();
    t.rotation_xyzw = r.doubles<4>();
    out.push_back(std::move(t));
  }
  return out;
}

Imu decodeImu(const std::uint8_t* data, std::size_t size, Wire wire) {
  Reader r(data, size, wire);
  Imu m;
  m.header = r.header();
  (void)r.doubles<4>();  // orientation
  (void)r.doubles<9>();
  (void)r.doubles<3>();  // angular velocity
  (void)r.doubles<9>();
  m.linear_acceleration = r.doubles<3>();
  return m;
}

PointCloud2 decodePointCloud2(const std::uint8_t* data, std::size_t size, Wire wire, std::size_t max_fields) {
  Reader r(data, size, wire);
  PointCloud2 m;
  m.header = r.header();
  m.height = r.get<std::uint32_t>();
  m.width = r.get<std::uint32_t>();
  // A field takes at least its name's length, an offset, a type and a count.
  const std::uint32_t n = r.count(13, "fields");
  if (n > max_fields) throw MessageError("fields: " + std::to_string(n) + ", more than " + std::to_string(max_fields));
  m.fields.resize(n);
  for (PointField& f : m.fields) {
    f.name = r.string("field name");
    f.offset = r.get<std::uint32_t>();
    f.datatype = r.get<std::uint8_t>();
    f.count = r.get<std::uint32_t>();
  }
  m.big_endian = r.get<std::uint8_t>() != 0;
  m.point_step = r.get<std::uint32_t>();
  m.row_step = r.get<std::uint32_t>();
  m.data = r.bytes(&m.data_size, "data");
  m.dense = r.get<std::uint8_t>() != 0;
  return m;
}

std::vector<std::array<float, 3>> cloudXyz(const PointCloud2& m) {
  std::uint64_t offsets[3] = {~0ull, ~0ull, ~0ull};
  for (const PointField& f : m.fields) {
    const int axis = f.name == "x" ? 0 : f.name == "y" ? 1 : f.name == "z" ? 2 : -1;
    if (axis >= 0 && f.datatype == 7 && f.count == 1) offsets[axis] = f.offset;
  }
  for (const std::uint64_t o : offsets) {
    if (o == ~0ull) throw MessageError("the cloud has no float32 x, y and z fields");
    if (o + 4 > m.point_step) throw MessageError("a field lies past the cloud's point_step");
  }
  if (m.big_endian) throw MessageError("the cloud is big-endian");
  const std::uint64_t w = m.width, h = m.height;
  if (m.row_step < m.point_step * w) throw MessageError("the cloud's row_step is shorter than its points");
  if (m.data_size < static_cast<std::uint64_t>(m.row_step) * h) throw MessageError("the cloud's data is shorter than its rows");
  std::vector<std::array<float, 3>> points;
  points.reserve(static_cast<std::size_t>(w * h));
  for (std::uint64_t r = 0; r < h; ++r) {
    for (std::uint64_t c = 0; c < w; ++c) {
      const std::uint8_t* at = m.data + r * m.row_step + c * m.point_step;
      std::array<float, 3> p{};
      for (int k = 0; k < 3; ++k) std::memcpy(&p[static_cast<std::size_t>(k)], at + offsets[k], 4);
      points.push_back(p);
    }
  }
  return points;
}

}  // namespace mobmap::sources::ros
