#pragma once
// Writes a rendered synthetic sequence in the 7-Scenes layout plus ground truth.

#include "mobmap/sim/corridor_scene.hpp"

#include <nlohmann/json.hpp>

#include <functional>
#include <string>
#include <vector>

namespace mobmap::app {

/// The ground truth of a scene as written to ground_truth.json (format described in
/// maps/FORMATS.md). With `pixels_seen` (indexed by surface id), each surface records
/// how many pixels of the rendered frames show it; `mobmap evaluate` leaves surfaces
/// never in view out of the assignment.
nlohmann::json groundTruthJson(const sim::CorridorScene& scene, const std::vector<long long>* pixels_seen = nullptr);

/// Adds the pixels of one rendered frame to `pixels_seen` (resized to fit every id).
void countSurfacePixels(const sim::RenderedFrame& frame, std::vector<long long>& pixels_seen);

/// Renders every frame of `scene` into `dir` using `threads` worker threads:
/// frame-NNNNNN.{depth,color,labels}.png and .pose.txt, camera-intrinsics.txt,
/// gravity-direction.txt and ground_truth.json (written last, with the pixels each
/// surface shows over all frames). `progress(frames_done)` is called from the calling
/// thread. Files are written atomically one by one.
void writeSimulation(const sim::CorridorScene& scene, const std::string& dir, int threads,
                     const std::function<void(int)>& progress);

}  // namespace mobmap::app
