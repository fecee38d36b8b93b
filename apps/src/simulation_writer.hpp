#pragma once
// Writes a rendered synthetic sequence in the 7-Scenes layout plus ground truth.

#include "mobmap/sim/corridor_scene.hpp"

#include <nlohmann/json.hpp>

#include <functional>
#include <string>

namespace mobmap::app {

/// The ground truth of a scene as written to ground_truth.json (format described in
/// maps/FORMATS.md).
nlohmann::json groundTruthJson(const sim::CorridorScene& scene);

/// Renders every frame of `scene` into `dir` using `threads` worker threads:
/// frame-NNNNNN.{depth,color,labels}.png and .pose.txt, camera-intrinsics.txt,
/// gravity-direction.txt and ground_truth.json. `progress(frames_done)` is called
/// from the calling thread. Files are written atomically one by one.
void writeSimulation(const sim::CorridorScene& scene, const std::string& dir, int threads,
                     const std::function<void(int)>& progress);

}  // namespace mobmap::app
