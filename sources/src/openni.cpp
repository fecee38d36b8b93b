#include "mobmap/sources/openni.hpp"

#include "mobmap/sources/dataset.hpp"
#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/trajectory_files.hpp"

#include "mobmap/mapping/trajectory.hpp"

#include <functional>
#include <OpenNI.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <memory>
#include <mutex>
#include <sstream>
#include <vector>

#include <unistd.h>

namespace mobmap::sources {
namespace {

namespace fs = std::filesystem;

enum class Wait { kReady, kTimedOut, kInterrupted };

// Waits up to timeout_s for a frame of `stream`, in slices of 100 ms so that
// `interrupted` (if given) is noticed promptly.
Wait waitForFrame(openni::VideoStream& stream, double timeout_s, const std::function<bool()>& interrupted) {
  openni::VideoStream* streams[] = {&stream};
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  for (;;) {
    if (interrupted && interrupted()) return Wait::kInterrupted;
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return Wait::kTimedOut;
    int ready = -1;
    const int slice = static_cast<int>(std::min<long long>(100, left.count()));
    if (openni::OpenNI::waitForAnyStream(streams, 1, &ready, slice) == openni::STATUS_OK) return Wait::kReady;
  }
}

// OpenNI2 is initialised once per process and never shut down: Debian's DummyDevice
// driver keeps a thread running past OpenNI::shutdown() that then crashes.
void initialiseOpenNi() {
  static std::once_flag once;
  static openni::Status status = openni::STATUS_OK;
  static std::string error;
  std::call_once(once, [] {
    status = openni::OpenNI::initialize();
    if (status != openni::STATUS_OK) error = openni::OpenNI::getExtendedError();
  });
  if (status != openni::STATUS_OK) throw IoError("OpenNI2", "initialisation failed: " + error);
}

std::string extendedError() {
  const std::string e = openni::OpenNI::getExtendedError();
  return e.empty() ? "no reason given" : e;
}

// Opens a live device ("" = the first one) or a recording; `name` is for messages.
void openDevice(openni::Device& device, const std::string& uri, bool is_file, const std::string& name) {
  initialiseOpenNi();
  if (is_file) {
    std::error_code ec;
    if (!fs::is_regular_file(uri, ec)) throw IoError(uri, "missing or not a file");
  } else if (uri.empty()) {
    openni::Array<openni::DeviceInfo> list;
    openni::OpenNI::enumerateDevices(&list);
    if (list.getSize() == 0) {
      throw IoError("OpenNI2", "no depth sensor is attached: OpenNI2 found no device (check the cable, and that this "
                                "user may open it: libopenni2-0 installs udev rules)");
    }
  }
  if (device.open(uri.empty() ? openni::ANY_DEVICE : uri.c_str()) != openni::STATUS_OK) {
    throw IoError(name, "OpenNI2 cannot open it: " + extendedError());
  }
  if (!device.hasSensor(openni::SENSOR_DEPTH)) throw IoError(name, "has no depth sensor");
}

// A device and its depth stream, stopped but never destroyed or closed: both are parked
// until the process exits (OpenNI2 is never shut down either, see initialiseOpenNi).
// Two of Debian's OpenNI2 drivers have threads that outlive the objects they read:
// - the file player (libOniFile): its playback thread walks the device's stream list
//   without a lock (PlayerDevice::MainLoop), while destroying a stream deletes it from
//   that list, and closing the device deletes its streams before it stops the thread.
//   `build` on an .oni crashed in that thread about once in 30 runs on a busy machine.
// - the Dummy device (libDummyDevice): stopping its stream only clears a flag that its
//   frame thread reads after each 33 ms sleep, and nothing joins that thread, so
//   destroying the stream frees memory the thread still uses. `build --device Dummy`
//   crashed in that thread 3 times in 1500 runs on a busy machine.
// Real sensors are released by the operating system when the process ends.
struct OpenNiHandles {
  OpenNiHandles() = default;
  OpenNiHandles(const OpenNiHandles&) = delete;
  OpenNiHandles& operator=(const OpenNiHandles&) = delete;
  ~OpenNiHandles() {
    depth->stop();
    static std::mutex m;
    // Reachable until exit and never freed (so not a leak to LeakSanitizer).
    static auto* parked = new std::vector<std::pair<openni::Device*, openni::VideoStream*>>();
    std::lock_guard<std::mutex> lock(m);
    parked->emplace_back(device.release(), depth.release());
  }
  std::unique_ptr<openni::Device> device = std::make_unique<openni::Device>();
  std::unique_ptr<openni::VideoStream> depth = std::make_unique<openni::VideoStream>();
};

class OpenNiSequence : public Sequence {
 public:
  explicit OpenNiSequence(const OpenNiOptions& o) : o_(o) {
    name_ = o.is_file ? o.uri : (o.uri.empty() ? std::string("the first OpenNI2 device") : o.uri);
    openDevice(device_, o.uri, o.is_file, name_);
    if (!o.is_file && device_.hasSensor(openni::SENSOR_COLOR) &&
        device_.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR)) {
      registered_ = device_.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR) == openni::STATUS_OK;
    }
    if (depth_.create(device_, openni::SENSOR_DEPTH) != openni::STATUS_OK) {
      throw IoError(name_, "cannot create its depth stream: " + extendedError());
    }
    const openni::VideoMode mode = depth_.getVideoMode();
    switch (mode.getPixelFormat()) {
      case openni::PIXEL_FORMAT_DEPTH_1_MM: scale_ = 0.001f; break;
      case openni::PIXEL_FORMAT_DEPTH_100_UM: scale_ = 0.0001f; break;
      default:
        throw IoError(name_, "depth pixel format " + std::to_string(static_cast<int>(mode.getPixelFormat())) +
                                 " is neither millimetres nor 100 micrometres");
    }
    const int w = mode.getResolutionX(), h = mode.getResolutionY();
    if (w <= 0 || h <= 0) throw IoError(name_, "depth stream has no resolution");
    k_ = intrinsicsFor(w, h);
    if (o.is_file) {
      openni::PlaybackControl* pc = device_.getPlaybackControl();
      if (pc == nullptr) throw IoError(name_, "OpenNI2 gives no playback control for it");
      recorded_ = pc->getNumberOfFrames(depth_);
      if (recorded_ <= 0) throw IoError(name_, "holds no depth frames");
      OniCropping cropping{};
      if (depth_.getProperty<OniCropping>(openni::STREAM_PROPERTY_CROPPING, &cropping) != openni::STATUS_OK) {
        throw IoError(name_, "its depth stream was recorded without a cropping property, and OpenNI2's player "
                             "drops every frame of such a stream (recordings of OpenNI2's Dummy device are like this)");
      }
      pc->setRepeatEnabled(false);
      pc->setSpeed(-1.0f);  // manual: each readFrame() delivers the next recorded frame
    }
    int last = o.last;
    if (o.is_file) last = last < 0 ? recorded_ - 1 : std::min(last, recorded_ - 1);
    if (!o.is_file && last < 0) last = o.first + 299;
    for (int n = o.first; n <= last; n += o.step) frames_.push_back(n);
    if (frames_.empty()) {
      throw IoError(name_, "holds " + std::to_string(recorded_) + " depth frames (0.." + std::to_string(recorded_ - 1) +
                               "), none of those asked for (from " + std::to_string(o.first) + ")");
    }
    if (!o.poses_path.empty()) {
      for (const auto& [t, T] : readTumPoses(o.poses_path)) trajectory_.insert(t, T);
      if (trajectory_.size() == 0) throw IoError(o.poses_path, "no poses in this file");
    }
    if (depth_.start() != openni::STATUS_OK) throw IoError(name_, "cannot start its depth stream: " + extendedError());
  }
  ~OpenNiSequence() override = default;  // handles_ stops the stream and parks it

  std::string format() const override { return "OpenNI2"; }
  std::string describe() const override {
    std::ostringstream s;
    s << name_ << " (OpenNI2 " << (o_.is_file ? ".oni recording of " + std::to_string(recorded_) + " depth frames" : "live sensor")
      << ", " << k_.width << "x" << k_.height << (registered_ ? ", depth registered to colour by the driver" : "")
      << ", fx " << k_.fx << " fy " << k_.fy << " cx " << k_.cx << " cy " << k_.cy << ", "
      << (o_.poses_path.empty() ? "static camera (no `poses`)" : "poses from " + o_.poses_path + " by time stamp") << ")";
    return s.str();
  }
  const perception::PinholeIntrinsics& intrinsics() const override { return k_; }
  std::optional<Eigen::Vector3d> gravityDown() const override {
    // A static camera maps in its own frame, where "down" is +y until told otherwise.
    if (o_.poses_path.empty()) return Eigen::Vector3d(0, 1, 0);
    return std::nullopt;
  }
  const std::vector<int>& frames() const override { return frames_; }
  void check(int /*n*/) const override {}

  // A live sensor keeps sending while perception is busy, and OpenNI2 hands out the
  // newest frame: the gaps in the driver's frame indices are the frames never read.
  std::string skipped() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    if (o_.is_file || read_ < 0 || last_index_ < first_index_) return {};
    const long long sent = static_cast<long long>(last_index_) - first_index_ + 1;
    const long long dropped = sent - (read_ + 1);
    if (dropped <= 0) return {};
    std::ostringstream s;
    s << name_ << " sent " << sent << " depth frames while " << (read_ + 1) << " were read: " << dropped
      << " arrived while perception was busy and were dropped (`voxel_size_m` 0.02 perceives about 3 times faster)";
    return s.str();
  }

  Frame load(int n) const override {
    std::unique_lock<std::mutex> lock(mutex_);
    turn_.wait(lock, [&] { return failed_ || (cursor_ < frames_.size() && frames_[cursor_] == n); });
    if (failed_) throw IoError(name_, "reading stopped at an earlier frame");
    try {
      openni::VideoFrameRef f;
      while (read_ < n) {
        next(f);
        if (read_ < 0) first_index_ = f.getFrameIndex();
        last_index_ = f.getFrameIndex();
        ++read_;
      }
      Frame out = convert(f, n);
      ++cursor_;
      turn_.notify_all();
      return out;
    } catch (...) {
      failed_ = true;
      turn_.notify_all();
      throw;
    }
  }

 private:
  perception::PinholeIntrinsics intrinsicsFor(int w, int h) {
    if (!o_.intrinsics_spec.empty()) return parseIntrinsics(o_.intrinsics_spec, w, h);
    float hfov = depth_.getHorizontalFieldOfView(), vfov = depth_.getVerticalFieldOfView();
    if (registered_) {  // registered depth lives in the colour camera
      openni::VideoStream colour;
      if (colour.create(device_, openni::SENSOR_COLOR) == openni::STATUS_OK) {
        hfov = colour.getHorizontalFieldOfView();
        vfov = colour.getVerticalFieldOfView();
        colour.destroy();
      }
    }
    if (!(hfov > 0.f && hfov < 3.1f) || !(vfov > 0.f && vfov < 3.1f)) {
      throw IoError(name_, "reports no usable field of view, so its intrinsics are unknown: give `intrinsics` fx,fy,cx,cy");
    }
    perception::PinholeIntrinsics k;
    k.width = w, k.height = h;
    k.fx = w / (2.0 * std::tan(hfov / 2.0));
    k.fy = h / (2.0 * std::tan(vfov / 2.0));
    k.cx = (w - 1) / 2.0;  // pixel centres, as OpenNI's own depth-to-world conversion
    k.cy = (h - 1) / 2.0;
    return k;
  }

  void next(openni::VideoFrameRef& f) const {
    if (!o_.is_file) {
      const Wait w = waitForFrame(depth_, o_.frame_timeout_s, o_.interrupted);
      if (w == Wait::kInterrupted) throw StreamInterrupted(name_ + ": stopped while waiting for a depth frame");
      if (w == Wait::kTimedOut) {
        std::ostringstream msg;
        msg << "no depth frame within " << o_.frame_timeout_s << " s ";
        if (read_ < 0) {
          msg << "of starting its depth stream (is the sensor streaming?)";
        } else {
          msg << "after frame " << read_;
        }
        throw IoError(name_, msg.str());
      }
    }
    if (depth_.readFrame(&f) != openni::STATUS_OK || !f.isValid()) {
      throw IoError(name_, "reading depth frame " + std::to_string(read_ + 1) + " failed: " + extendedError());
    }
  }

  Frame convert(const openni::VideoFrameRef& f, int n) const {
    if (f.getWidth() != k_.width || f.getHeight() != k_.height) {
      throw IoError(name_, "frame " + std::to_string(n) + " is " + std::to_string(f.getWidth()) + "x" +
                               std::to_string(f.getHeight()) + ", the stream is " + std::to_string(k_.width) + "x" +
                               std::to_string(k_.height));
    }
    const int stride = f.getStrideInBytes();
    if (stride < k_.width * 2 || f.getDataSize() < stride * (k_.height - 1) + k_.width * 2) {
      throw IoError(name_, "frame " + std::to_string(n) + " holds fewer bytes than its size needs");
    }
    Frame out;
    out.number = n;
    out.depth = perception::DepthImage(k_.width, k_.height);
    const auto* bytes = static_cast<const unsigned char*>(f.getData());
    for (int v = 0; v < k_.height; ++v) {
      const auto* row = reinterpret_cast<const openni::DepthPixel*>(bytes + static_cast<std::ptrdiff_t>(v) * stride);
      for (int u = 0; u < k_.width; ++u) out.depth->at(u, v) = static_cast<float>(row[u]) * scale_;
    }
    out.stamp_s = static_cast<double>(f.getTimestamp()) * 1e-6;  // the device's clock
    if (trajectory_.size() > 0) {
      out.T_world_camera = trajectory_.at(*out.stamp_s, o_.max_pose_gap_s);  // unset: no pose within the gap
    } else {
      out.T_world_camera = Eigen::Isometry3d::Identity();  // a static camera
    }
    return out;
  }

  OpenNiOptions o_;
  std::string name_;
  OpenNiHandles handles_;
  openni::Device& device_ = *handles_.device;
  openni::VideoStream& depth_ = *handles_.depth;
  bool registered_ = false;
  float scale_ = 0.001f;
  int recorded_ = 0;
  perception::PinholeIntrinsics k_;
  std::vector<int> frames_;
  mapping::Trajectory trajectory_;
  mutable std::mutex mutex_;
  mutable std::condition_variable turn_;
  mutable std::size_t cursor_ = 0;  // index into frames_ of the next load()
  mutable int read_ = -1;           // number of the last frame read from the stream
  mutable bool failed_ = false;
  mutable int first_index_ = 0;  // the driver's index of the first frame read
  mutable int last_index_ = -1;  // and of the last
};

}  // namespace

std::unique_ptr<Sequence> openOpenNi(const OpenNiOptions& options) { return std::make_unique<OpenNiSequence>(options); }

int recordOni(const std::string& device_uri, const std::string& out_path, int frames, double frame_timeout_s,
              const std::function<bool()>& interrupted) {
  const std::string name = device_uri.empty() ? std::string("the first OpenNI2 device") : device_uri;
  OpenNiHandles handles;  // parks the stream when done, whatever happens
  openni::Device& device = *handles.device;
  openni::VideoStream& depth = *handles.depth;
  openDevice(device, device_uri, false, name);
  if (depth.create(device, openni::SENSOR_DEPTH) != openni::STATUS_OK) {
    throw IoError(name, "cannot create its depth stream: " + extendedError());
  }
  const std::string tmp = out_path + ".part-" + std::to_string(::getpid()) + ".oni";
  openni::Recorder recorder;
  if (recorder.create(tmp.c_str()) != openni::STATUS_OK || recorder.attach(depth) != openni::STATUS_OK) {
    throw IoError(out_path, "OpenNI2 cannot record to it: " + extendedError());
  }
  if (depth.start() != openni::STATUS_OK || recorder.start() != openni::STATUS_OK) {
    recorder.destroy();
    std::error_code ec;
    fs::remove(tmp, ec);
    throw IoError(name, "cannot start recording: " + extendedError());
  }
  int got = 0;
  std::string failure;
  bool stopped = false;
  while (got < frames) {
    const Wait w = waitForFrame(depth, frame_timeout_s, interrupted);
    if (w == Wait::kInterrupted) {
      stopped = true;
      break;
    }
    if (w == Wait::kTimedOut) {
      std::ostringstream msg;
      msg << "no depth frame within " << frame_timeout_s << " s after " << got << " frames";
      failure = msg.str();
      break;
    }
    openni::VideoFrameRef f;
    if (depth.readFrame(&f) == openni::STATUS_OK) ++got;
  }
  recorder.stop();
  recorder.destroy();
  std::error_code ec;
  if (!failure.empty() || got == 0) {
    fs::remove(tmp, ec);
    throw IoError(name, !failure.empty() ? failure
                        : stopped       ? "stopped by Ctrl-C before the first depth frame arrived; nothing recorded"
                                        : "recorded no frames");
  }
  fs::rename(tmp, out_path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw IoError(out_path, "cannot move the recording into place");
  }
  return got;
}

}  // namespace mobmap::sources
