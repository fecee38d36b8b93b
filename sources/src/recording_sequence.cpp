#include "recording_sequence.hpp"

#include "mobmap/mapping/trajectory.hpp"
#include "mobmap/sources/dataset.hpp"
#include "mobmap/sources/trajectory_files.hpp"

namespace mobmap::sources {
namespace {

class RecordingSequence : public Sequence {
 public:
  explicit RecordingSequence(std::unique_ptr<Recording> r) : r_(std::move(r)) {}

  std::string format() const override { return r_->format(); }
  std::string describe() const override {
    std::string text = r_->path() + " (" + r_->format() + ": depth " + r_->depthTopic() + ", " +
                       std::to_string(r_->frames().size()) + " of " + std::to_string(r_->imageCount()) + " images posed " +
                       (r_->worldFrame().empty() ? std::string("by `poses`") : "in " + r_->worldFrame() + " through TF");
    if (!r_->cameraInfoTopic().empty()) text += ", intrinsics from " + r_->cameraInfoTopic();
    if (!r_->distortionNote().empty()) text += ", " + r_->distortionNote();
    return text + ")";
  }
  const perception::PinholeIntrinsics& intrinsics() const override { return r_->intrinsics(); }
  std::optional<Eigen::Vector3d> gravityDown() const override { return r_->gravityDown(); }
  std::string gravitySource() const override { return r_->gravitySource(); }
  const std::vector<int>& frames() const override { return r_->frames(); }
  void check(int /*n*/) const override {}  // the first image was decoded at open; each is checked as it is read
  Frame load(int n) const override {
    RecordingFrame rf = r_->load(n);
    Frame f;
    f.number = n;
    f.depth = std::move(rf.depth);
    f.T_world_camera = rf.T_world_camera;
    f.stamp_s = static_cast<double>(rf.stamp_ns) * 1e-9;
    return f;
  }
  std::optional<Eigen::Isometry3d> pose(int n) const override { return r_->pose(n); }
  std::vector<std::string> files(int /*n*/) const override { return r_->files(); }
  std::string skipped() const override {
    std::string text = r_->skipped();
    if (!r_->fault().empty()) {
      text += std::string(text.empty() ? "" : "; ") + "the recording ends early (" + r_->fault() +
              "); the images stored before that point are used";
    }
    return text;
  }
  DepthUnit depthUnit() const override { return {r_->depthUnitsPerMetre(), false}; }
  const Recording* recording() const override { return r_.get(); }

 private:
  std::unique_ptr<Recording> r_;
};

}  // namespace

RecordingOptions recordingOptions(const RecordingChoice& choice, double max_pose_gap_s) {
  RecordingOptions o;
  o.depth_topic = choice.depth_topic;
  o.camera_info_topic = choice.camera_info_topic;
  o.world_frame = choice.world_frame;
  o.imu_topic = choice.imu_topic;
  o.max_pose_gap_s = max_pose_gap_s;
  return o;
}

std::unique_ptr<Sequence> openRecordingSequence(const std::string& path, const SequenceOptions& options) {
  RecordingOptions o = recordingOptions(options.recording, options.max_pose_gap_s);
  const std::string& intrinsics_spec = options.intrinsics;
  const std::string& poses_path = options.poses;
  const double max_pose_gap_s = options.max_pose_gap_s;
  if (!intrinsics_spec.empty()) {
    o.intrinsics = [intrinsics_spec](int width, int height) { return parseIntrinsics(intrinsics_spec, width, height); };
  }
  if (!poses_path.empty()) {
    // A TUM trajectory matched to the images' stamps, as for TUM sequences.
    auto trajectory = std::make_shared<mapping::Trajectory>();
    for (const auto& [t, T] : readTumPoses(poses_path)) trajectory->insert(t, T);
    o.poses = [trajectory, max_pose_gap_s](std::int64_t stamp_ns) {
      return trajectory->at(static_cast<double>(stamp_ns) * 1e-9, max_pose_gap_s);
    };
  }
  return std::make_unique<RecordingSequence>(Recording::open(path, o));
}

}  // namespace mobmap::sources
