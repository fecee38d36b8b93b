#include "commands/recording_info.hpp"

#include "io/cli_text.hpp"
#include "mobmap/sources/sequence.hpp"

#include "mobmap/sources/recording.hpp"

#include <nlohmann/json.hpp>

#include <cstdio>

namespace mobmap::app {

int describeRecording(const std::string& path, const RecordingChoice& choice, double max_pose_gap_s, bool json) {
  sources::RecordingOptions o = sources::recordingOptions(choice, max_pose_gap_s);
  o.describe_only = true;
  const auto rec = sources::Recording::open(path, o);
  const bool chosen = rec->problem().empty();

  nlohmann::json j;
  j["recording"] = path;
  j["format"] = rec->format();
  j["files"] = rec->files();
  j["topics"] = nlohmann::json::array();
  for (const auto& t : rec->topics()) {
    j["topics"].push_back({{"name", t.name}, {"type", t.type}, {"count", t.count}, {"rate_hz", t.rate_hz}});
  }
  j["tf"] = nlohmann::json::array();
  for (const auto& e : rec->tf().edges()) {
    j["tf"].push_back({{"parent", e.parent}, {"child", e.child}, {"static", e.is_static}, {"samples", e.samples}});
  }
  j["tf_frames"] = rec->tf().frames();
  if (chosen) {
    j["depth_topic"] = rec->depthTopic();
    j["camera_info_topic"] = rec->cameraInfoTopic().empty() ? nlohmann::json() : nlohmann::json(rec->cameraInfoTopic());
    j["world_frame"] = rec->worldFrame();
    j["camera_frame"] = rec->cameraFrame();
    j["images"] = rec->imageCount();
    j["frames"] = rec->frames().size();
    const auto& k = rec->intrinsics();
    j["intrinsics"] = {{"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy}, {"width", k.width}, {"height", k.height}};
    if (!rec->distortionNote().empty()) j["distortion"] = rec->distortionNote();
    if (rec->gravityDown()) j["gravity_source"] = rec->gravitySource();
    if (!rec->skipped().empty()) j["skipped"] = cliText(rec->skipped());
  } else {
    j["problem"] = rec->problem();
  }
  if (!rec->fault().empty()) j["fault"] = rec->fault();
  if (!rec->recovered().empty()) j["recovered"] = cliText(rec->recovered());
  if (json) {
    std::printf("%s\n", j.dump().c_str());
    return 0;
  }

  std::printf("%s: %s, %zu file%s\n", path.c_str(), rec->format().c_str(), rec->files().size(), rec->files().size() == 1 ? "" : "s");
  std::printf("\n%-44s %-32s %8s %9s\n", "topic", "type", "messages", "rate (Hz)");
  for (const auto& t : rec->topics()) {
    std::printf("%-44s %-32s %8zu %9.2f\n", t.name.c_str(), t.type.c_str(), t.count, t.rate_hz);
  }
  std::printf("\nTF tree (parent -> child):\n");
  if (rec->tf().edges().empty()) std::printf("  none (no /tf or /tf_static messages)\n");
  for (const auto& e : rec->tf().edges()) {
    if (e.is_static) {
      std::printf("  %s -> %s (static)\n", e.parent.c_str(), e.child.c_str());
    } else {
      std::printf("  %s -> %s (%zu samples)\n", e.parent.c_str(), e.child.c_str(), e.samples);
    }
  }
  if (!rec->recovered().empty()) std::printf("\nwarning: a recording its recorder did not finish, recovered: %s\n", cliText(rec->recovered()).c_str());
  if (!rec->fault().empty()) std::printf("\nwarning: the recording ends early (%s)\n", rec->fault().c_str());
  if (!chosen) {
    std::printf("\nbuild cannot read it as it is: %s\n", rec->problem().c_str());
    return 0;
  }
  const auto& k = rec->intrinsics();
  std::printf("\nbuild would read:\n");
  std::printf("  depth_topic        %s\n", rec->depthTopic().c_str());
  std::printf("  camera_info_topic  %s (%dx%d, fx %.2f fy %.2f cx %.2f cy %.2f%s%s)\n",
              rec->cameraInfoTopic().empty() ? "(none: --intrinsics)" : rec->cameraInfoTopic().c_str(), k.width, k.height, k.fx,
              k.fy, k.cx, k.cy, rec->distortionNote().empty() ? "" : "; ", rec->distortionNote().c_str());
  std::printf("  world_frame        %s%s%s\n", rec->worldFrame().c_str(), rec->gravityDown() ? ", gravity from " : "",
              rec->gravityDown() ? rec->gravitySource().c_str() : "");
  std::printf("  camera_frame       %s\n", rec->cameraFrame().c_str());
  std::printf("  frames             %zu of %d depth images have a pose\n", rec->frames().size(), rec->imageCount());
  if (!rec->skipped().empty()) std::printf("  skipped            %s\n", cliText(rec->skipped()).c_str());
  return 0;
}

}  // namespace mobmap::app
