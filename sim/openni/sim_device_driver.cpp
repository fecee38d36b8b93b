// An OpenNI2 device driver that serves the synthetic corridor as a live depth sensor,
// so the OpenNI2 paths of `mobmap build` (--device, recording, .oni playback) can be
// tested against known geometry without hardware.
//
// OpenNI2 loads drivers from the "OpenNI2/Drivers" folder beside the libOpenNI2.so it
// was loaded from; the tests build that folder (a link to the system library plus this
// driver) and run mobmap with LD_LIBRARY_PATH pointing at it.
//
// Device URI: "mobmap-sim://corridor". One depth sensor, 640x480 at 30 Hz, 1 mm units.
// Frame i is corridor frame i, time stamped i/30 s (in microseconds), paced at 30 Hz.
// Environment: MOBMAP_SIM_FRAMES (frames before the stream goes quiet, default 90),
// MOBMAP_SIM_NOISE ("none" or "kinect", default none), MOBMAP_SIM_LOOP (if > 1: walk a
// corridor of that many frames back and forth, for long runs), MOBMAP_SIM_POSES (a file
// to receive the true trajectory of every frame, TUM format, time stamps in seconds),
// MOBMAP_SIM_FPS (frame rate, default 30; time stamps are i / rate).

// OniDriverAPI.h's export macro allocates with XnLib's macros, which Debian does not
// ship; plain new/delete do the same job.
#define XN_NEW(type, arg) new type(arg)
#define XN_DELETE(p) delete (p)
#include <Driver/OniDriverAPI.h>

#include "mobmap/sim/corridor_scene.hpp"
#include "mobmap/sim/tum_pose.hpp"

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>
#include <thread>

namespace {

constexpr const char* kUri = "mobmap-sim://corridor";

int envInt(const char* name, int fallback) {
  const char* v = std::getenv(name);
  return v != nullptr ? std::atoi(v) : fallback;
}

int frameRate() { return std::max(1, envInt("MOBMAP_SIM_FPS", 30)); }

// The corridor frame shown as device frame i: straight through, or back and forth.
int corridorFrame(int i) {
  const int loop = envInt("MOBMAP_SIM_LOOP", 0);
  if (loop < 2) return i;
  const int period = 2 * (loop - 1);
  const int k = i % period;
  return k < loop ? k : period - k;
}

int corridorLength() {
  const int loop = envInt("MOBMAP_SIM_LOOP", 0);
  return std::max(2, loop >= 2 ? loop : envInt("MOBMAP_SIM_FRAMES", 90));
}

class CorridorStream : public oni::driver::StreamBase {
 public:
  explicit CorridorStream(std::shared_ptr<const mobmap::sim::CorridorScene> scene) : scene_(std::move(scene)) {
    const auto& k = scene_->params().intrinsics;
    mode_.pixelFormat = ONI_PIXEL_FORMAT_DEPTH_1_MM;
    mode_.resolutionX = k.width;
    mode_.resolutionY = k.height;
    mode_.fps = frameRate();
  }
  ~CorridorStream() override { stop(); }

  OniStatus start() override {
    stop();
    running_ = true;
    worker_ = std::thread([this] { run(); });
    return ONI_STATUS_OK;
  }
  void stop() override {
    running_ = false;
    if (worker_.joinable()) worker_.join();
  }

  OniStatus getProperty(int id, void* data, int* size) override {
    const auto& k = scene_->params().intrinsics;
    switch (id) {
      case ONI_STREAM_PROPERTY_VIDEO_MODE:
        if (*size != static_cast<int>(sizeof(OniVideoMode))) return ONI_STATUS_BAD_PARAMETER;
        *static_cast<OniVideoMode*>(data) = mode_;
        return ONI_STATUS_OK;
      case ONI_STREAM_PROPERTY_HORIZONTAL_FOV:
      case ONI_STREAM_PROPERTY_VERTICAL_FOV: {
        if (*size != static_cast<int>(sizeof(float))) return ONI_STATUS_BAD_PARAMETER;
        const bool h = id == ONI_STREAM_PROPERTY_HORIZONTAL_FOV;
        *static_cast<float*>(data) =
            static_cast<float>(2.0 * std::atan(h ? k.width / (2.0 * k.fx) : k.height / (2.0 * k.fy)));
        return ONI_STATUS_OK;
      }
      case ONI_STREAM_PROPERTY_MIN_VALUE:
      case ONI_STREAM_PROPERTY_MAX_VALUE:
        if (*size != static_cast<int>(sizeof(int))) return ONI_STATUS_BAD_PARAMETER;
        *static_cast<int*>(data) = id == ONI_STREAM_PROPERTY_MIN_VALUE ? 0 : 10000;
        return ONI_STATUS_OK;
      case ONI_STREAM_PROPERTY_STRIDE:
        if (*size != static_cast<int>(sizeof(int))) return ONI_STATUS_BAD_PARAMETER;
        *static_cast<int*>(data) = mode_.resolutionX * 2;
        return ONI_STATUS_OK;
      case ONI_STREAM_PROPERTY_MIRRORING:
        if (*size != static_cast<int>(sizeof(OniBool))) return ONI_STATUS_BAD_PARAMETER;
        *static_cast<OniBool*>(data) = FALSE;
        return ONI_STATUS_OK;
      case ONI_STREAM_PROPERTY_CROPPING: {
        // Reported (as off) so that recordings carry it: OpenNI2's .oni player drops
        // every frame of a stream whose recording has no cropping property.
        if (*size != static_cast<int>(sizeof(OniCropping))) return ONI_STATUS_BAD_PARAMETER;
        OniCropping c{};
        c.enabled = FALSE;
        c.width = mode_.resolutionX;
        c.height = mode_.resolutionY;
        *static_cast<OniCropping*>(data) = c;
        return ONI_STATUS_OK;
      }
      default:
        return ONI_STATUS_NOT_SUPPORTED;
    }
  }
  OniBool isPropertySupported(int id) override {
    return id == ONI_STREAM_PROPERTY_VIDEO_MODE || id == ONI_STREAM_PROPERTY_HORIZONTAL_FOV ||
           id == ONI_STREAM_PROPERTY_VERTICAL_FOV || id == ONI_STREAM_PROPERTY_MIN_VALUE ||
           id == ONI_STREAM_PROPERTY_MAX_VALUE || id == ONI_STREAM_PROPERTY_STRIDE ||
           id == ONI_STREAM_PROPERTY_MIRRORING || id == ONI_STREAM_PROPERTY_CROPPING;
  }
  OniStatus setProperty(int id, const void* data, int size) override {
    // Accept the mode we have (applications set it back), refuse others.
    if (id == ONI_STREAM_PROPERTY_VIDEO_MODE && size == static_cast<int>(sizeof(OniVideoMode))) {
      const auto* m = static_cast<const OniVideoMode*>(data);
      return m->resolutionX == mode_.resolutionX && m->resolutionY == mode_.resolutionY &&
                     m->pixelFormat == mode_.pixelFormat
                 ? ONI_STATUS_OK
                 : ONI_STATUS_NOT_SUPPORTED;
    }
    if (id == ONI_STREAM_PROPERTY_MIRRORING) return ONI_STATUS_OK;
    return ONI_STATUS_NOT_SUPPORTED;
  }
  int getRequiredFrameSize() override { return mode_.resolutionX * mode_.resolutionY * 2; }

 private:
  void run() {
    const int frames = envInt("MOBMAP_SIM_FRAMES", 90);
    const auto period = std::chrono::microseconds(1000000 / frameRate());
    auto next = std::chrono::steady_clock::now();
    for (int i = 0; i < frames && running_; ++i) {
      const auto r = scene_->render(corridorFrame(i));
      OniFrame* f = getServices().acquireFrame();
      if (f == nullptr) break;
      f->frameIndex = i;
      f->timestamp = static_cast<std::uint64_t>(i) * 1000000ULL / static_cast<std::uint64_t>(frameRate());
      f->sensorType = ONI_SENSOR_DEPTH;
      f->videoMode = mode_;
      f->width = mode_.resolutionX;
      f->height = mode_.resolutionY;
      f->croppingEnabled = FALSE;
      f->cropOriginX = f->cropOriginY = 0;
      f->stride = mode_.resolutionX * 2;
      f->dataSize = getRequiredFrameSize();
      auto* px = static_cast<std::uint16_t*>(f->data);
      for (std::size_t p = 0; p < r.depth.depth_m.size(); ++p) {
        const float z = r.depth.depth_m[p];
        px[p] = z > 0.f && z < 65.f ? static_cast<std::uint16_t>(std::lround(z * 1000.f)) : 0;
      }
      raiseNewFrame(f);
      getServices().releaseFrame(f);
      next += period;
      std::this_thread::sleep_until(next);
    }
  }

  std::shared_ptr<const mobmap::sim::CorridorScene> scene_;
  OniVideoMode mode_{};
  std::atomic<bool> running_{false};
  std::thread worker_;
};

class CorridorDevice : public oni::driver::DeviceBase {
 public:
  CorridorDevice() {
    mobmap::sim::CorridorParams p;
    const char* noise = std::getenv("MOBMAP_SIM_NOISE");
    p.noise = noise != nullptr && std::string(noise) == "kinect" ? mobmap::sim::NoiseModel::kKinect : mobmap::sim::NoiseModel::kNone;
    p.frames = corridorLength();
    scene_ = std::make_shared<const mobmap::sim::CorridorScene>(p);
    if (const char* poses = std::getenv("MOBMAP_SIM_POSES")) writePoses(poses);
    mode_.pixelFormat = ONI_PIXEL_FORMAT_DEPTH_1_MM;
    mode_.resolutionX = p.intrinsics.width;
    mode_.resolutionY = p.intrinsics.height;
    mode_.fps = frameRate();
    sensor_.sensorType = ONI_SENSOR_DEPTH;
    sensor_.numSupportedVideoModes = 1;
    sensor_.pSupportedVideoModes = &mode_;
  }
  OniStatus getSensorInfoList(OniSensorInfo** sensors, int* count) override {
    *sensors = &sensor_;
    *count = 1;
    return ONI_STATUS_OK;
  }
  oni::driver::StreamBase* createStream(OniSensorType type) override {
    return type == ONI_SENSOR_DEPTH ? new CorridorStream(scene_) : nullptr;
  }
  void destroyStream(oni::driver::StreamBase* stream) override { delete stream; }

 private:
  void writePoses(const char* path) const {
    std::ofstream out(path);
    const int frames = envInt("MOBMAP_SIM_FRAMES", 90);
    for (int i = 0; i < frames; ++i) {
      mobmap::sim::writeTumPoseLine(out, i / static_cast<double>(frameRate()), scene_->cameraPose(corridorFrame(i)));
    }
  }

  std::shared_ptr<const mobmap::sim::CorridorScene> scene_;
  OniVideoMode mode_{};
  OniSensorInfo sensor_{};
};

class CorridorDriver : public oni::driver::DriverBase {
 public:
  explicit CorridorDriver(OniDriverServices* services) : DriverBase(services) {}
  OniStatus initialize(oni::driver::DeviceConnectedCallback connected, oni::driver::DeviceDisconnectedCallback disconnected,
                       oni::driver::DeviceStateChangedCallback changed, void* cookie) override {
    DriverBase::initialize(connected, disconnected, changed, cookie);
    OniDeviceInfo info{};
    std::strncpy(info.uri, kUri, ONI_MAX_STR - 1);
    std::strncpy(info.vendor, "mobmap", ONI_MAX_STR - 1);
    std::strncpy(info.name, "synthetic corridor", ONI_MAX_STR - 1);
    info_ = info;
    deviceConnected(&info_);
    return ONI_STATUS_OK;
  }
  oni::driver::DeviceBase* deviceOpen(const char* uri, const char* /*mode*/) override {
    if (std::strcmp(uri, kUri) != 0) return nullptr;
    return new CorridorDevice();
  }
  void deviceClose(oni::driver::DeviceBase* device) override { delete device; }
  OniStatus tryDevice(const char* uri) override {
    return std::strcmp(uri, kUri) == 0 ? ONI_STATUS_OK : ONI_STATUS_ERROR;
  }
  void shutdown() override {}

 private:
  OniDeviceInfo info_{};
};

}  // namespace

ONI_EXPORT_DRIVER(CorridorDriver)
