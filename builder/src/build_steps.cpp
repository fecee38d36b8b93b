#include "build_steps.hpp"

#include "mobmap/builder/frames.hpp"
#include "mobmap/util/field_error.hpp"

#include "mobmap/mapping/mobility_map.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <exception>
#include <sstream>
#include <thread>

namespace mobmap::builder {

IoError withSkipHint(const IoError& e) {
  return IoError(e.path(), e.reason() + " (`skip_bad_frames` leaves such frames out)");
}

FrameRange parseFrameRange(const std::string& spec) {
  FrameRange r;
  if (spec.empty()) return r;
  std::vector<std::string> parts;
  std::stringstream in(spec);
  std::string part;
  while (std::getline(in, part, ':')) parts.push_back(part);
  try {
    if (parts.size() >= 1 && !parts[0].empty()) r.first = std::stoi(parts[0]);
    if (parts.size() >= 2 && !parts[1].empty()) r.last = std::stoi(parts[1]);
    if (parts.size() >= 3 && !parts[2].empty()) r.step = std::stoi(parts[2]);
  } catch (const std::exception&) {
    throw util::FieldError("frames", "must be FIRST:LAST:STEP, got '" + spec + "'");
  }
  if (parts.empty() || parts.size() > 3 || r.first < 0 || r.step < 1 || (r.last >= 0 && r.last < r.first)) {
    throw util::FieldError("frames", "must be FIRST:LAST:STEP with 0 <= FIRST <= LAST and STEP >= 1, got '" + spec + "'");
  }
  return r;
}

perception::FrameResult perceive(const perception::FramePipeline& pipeline, const Sequence& dir, const Frame& f,
                                 const std::optional<Eigen::Vector3f>& gravity_down_camera) {
  if (dir.hasDepth()) return pipeline.process(*f.depth, dir.intrinsics(), gravity_down_camera);
  if (f.height > 1 && f.points.size() == static_cast<std::size_t>(f.width) * static_cast<std::size_t>(f.height)) {
    return pipeline.processOrganized(f.points, f.width, f.height, gravity_down_camera);
  }
  return pipeline.process(f.points, gravity_down_camera);
}

std::optional<mapping::DownObservation> floorVote(const perception::FrameResult& r, const Eigen::Matrix3d& r_wc) {
  if (!r.ground_plane) return std::nullopt;
  double weight = 0.0;
  for (const auto& s : r.segments) weight += s.is_ground ? static_cast<double>(s.points.size()) : 0.0;
  return mapping::DownObservation{r_wc * -r.ground_plane->head<3>().cast<double>(), std::max(1.0, weight)};
}

FloorSample sampleFloors(const Sequence& dir, const std::vector<int>& frames, const perception::FramePipeline& finder,
                         const std::function<Eigen::Vector3f(const Eigen::Matrix3d&)>& down_in_camera, bool skip_unreadable,
                         PerceivedForRun* for_run) {
  FloorSample sample;
  if (!dir.hasDepth()) for_run = nullptr;  // clouds: perceived by the run as always
  // Read in turn (a recording is read from one place), perceived on every core: the
  // sample is the wait before a run's first frame.
  const std::size_t samples = std::min<std::size_t>(8, frames.size());
  std::vector<Frame> loaded;
  std::vector<int> numbers;
  for (std::size_t i = 0; i < samples; ++i) {
    const std::size_t at = samples == 1 ? 0 : i * (frames.size() - 1) / (samples - 1);
    Frame f;
    try {
      f = dir.load(frames[at]);
    } catch (const IoError& e) {
      if (!skip_unreadable) throw withSkipHint(e);
      continue;
    }
    if (!f.T_world_camera) continue;
    sample.rotations.push_back(f.T_world_camera->linear());
    loaded.push_back(std::move(f));
    numbers.push_back(frames[at]);
  }
  std::vector<std::optional<mapping::DownObservation>> votes(loaded.size());
  std::vector<std::optional<perception::FrameResult>> runs(loaded.size());
  std::atomic<std::size_t> next{0};
  std::vector<std::exception_ptr> failures(loaded.size());  // the first frame's in order is thrown
  const auto work = [&] {
    for (std::size_t i; (i = next++) < loaded.size();) {
      try {
        const Eigen::Matrix3d& r_wc = sample.rotations[i];
        if (for_run) {
          std::vector<perception::FrameResult> both = finder.processPerGroundCone(
              *loaded[i].depth, dir.intrinsics(), down_in_camera(r_wc),
              {finder.params().ground_max_tilt_deg, for_run->ground_cone_deg});
          votes[i] = floorVote(both[0], r_wc);
          runs[i] = std::move(both[1]);
        } else {
          votes[i] = floorVote(perceive(finder, dir, loaded[i], down_in_camera(r_wc)), r_wc);
        }
      } catch (...) {
        failures[i] = std::current_exception();
      }
    }
  };
  const std::size_t threads = std::min<std::size_t>(loaded.size(), std::max(1u, std::thread::hardware_concurrency()));
  std::vector<std::thread> pool;
  for (std::size_t t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
  for (const std::exception_ptr& failure : failures) {
    if (failure) std::rethrow_exception(failure);
  }
  for (const auto& v : votes) {
    if (v) sample.floors.push_back(*v);
  }
  for (std::size_t i = 0; i < runs.size(); ++i) {
    if (runs[i]) {
      for_run->results.emplace(numbers[i], PerceivedForRun::Early{std::move(*runs[i]), down_in_camera(sample.rotations[i])});
    }
  }
  return sample;
}

GravityGuess estimateGravity(const Sequence& dir, const std::vector<int>& frames, const perception::PerceptionParams& pp,
                             const gp::MobilityModel& model, bool skip_unreadable) {
  perception::PerceptionParams p = pp;
  p.ground_max_tilt_deg = 45.0;
  const FloorSample sample = sampleFloors(
      dir, frames, perception::FramePipeline(p, model), [](const Eigen::Matrix3d&) { return Eigen::Vector3f(0, 1, 0); },
      skip_unreadable);
  const std::size_t posed = sample.rotations.size();
  Eigen::Vector3d camera_y_sum = Eigen::Vector3d::Zero();
  for (const Eigen::Matrix3d& r_wc : sample.rotations) camera_y_sum += r_wc.col(1);
  const auto vote = mapping::consensusDown(sample.floors, 5.0);
  std::ostringstream how;
  how.precision(2);
  if (vote && vote->weight_share >= 0.5) {
    how << "the floor in " << vote->agreeing << " of " << posed << " sampled frames (within " << std::fixed
        << vote->spread_deg << " degrees of each other)";
    return {vote->down, how.str()};
  }
  if (camera_y_sum.norm() > 1e-6) {
    how << "the cameras' mean +y axis (no floor agreed on in " << posed << " sampled frames)";
    return {camera_y_sum.normalized(), how.str()};
  }
  return {Eigen::Vector3d(0, 0, -1), "-z (no posed frame sampled)"};
}

std::optional<FloorCheck> floorNear(const Eigen::Vector3d& given_down, const Sequence* dir, const std::vector<int>& frames,
                                    const Frame* single, const perception::PerceptionParams& pp,
                                    const gp::MobilityModel& model, bool skip_unreadable, PerceivedForRun* for_run) {
  perception::PerceptionParams p = pp;
  p.ground_max_tilt_deg = kGravityRefineConeDeg;
  const perception::FramePipeline finder(p, model);
  const auto down_in_camera = [&](const Eigen::Matrix3d& r_wc) { return Eigen::Vector3f((r_wc.transpose() * given_down).cast<float>()); };
  FloorSample sample;
  if (single) {  // its world frame is its points' frame (the camera's, or the cloud's it was turned from)
    const Eigen::Matrix3d r_wc = single->T_cloud_camera.value_or(Eigen::Isometry3d::Identity()).linear();
    sample.rotations.push_back(r_wc);
    if (auto vote = floorVote(perceiveFrame(finder, *single, down_in_camera(r_wc)), r_wc)) sample.floors.push_back(*vote);
  } else {
    sample = sampleFloors(*dir, frames, finder, down_in_camera, skip_unreadable, for_run);
  }
  const auto vote = mapping::consensusDown(sample.floors, 5.0);
  if (!vote || vote->weight_share < 0.5) return std::nullopt;
  return FloorCheck{*vote, sample.rotations.size()};
}

ExistingMap openForExtension(const std::string& ot_path) {
  ExistingMap m;
  m.tree = mapping::loadMobilityMap(ot_path);
  m.meta = mapping::readMapMetadata(ot_path);  // the earlier runs' records, for the new MAP.json
  m.origin_world = m.meta.originWorld();  // zero for a map from before origins were recorded
  if (!m.meta.hasFrame()) {
    throw IoError(m.meta.path, "missing, or without \"R_map_world\": `extend` needs the metadata written beside the map "
                               "(the rotation from the input's world frame to the map frame)");
  }
  m.R_map_world = m.meta.R_map_world();
  m.down_world = m.R_map_world.transpose() * Eigen::Vector3d(0, 0, -1);
  // The recorded gravity gives the first run's rotation bit for bit (the matrix printed
  // in MAP.json goes through nearestRotation when read): then both are taken from it.
  if (const auto g = m.meta.gravityDownWorld()) {
    const Eigen::Matrix3d r = mapping::gravityAlignment(*g);
    if ((r - m.R_map_world).cwiseAbs().maxCoeff() < 1e-9) {
      m.R_map_world = r;
      m.down_world = *g;
    }
  }
  return m;
}

double angleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

std::string formatVector(const Eigen::Vector3d& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.3f, %.3f, %.3f)", v.x(), v.y(), v.z());
  return buf;
}

std::vector<RunRange> overlappingRuns(const mapping::MapMetadata& earlier, const std::string& input, int first, int last) {
  const std::vector<const mapping::MapRun*> runs = earlier.runs();
  std::vector<RunRange> out;
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const mapping::MapRun& r = *runs[i];
    if (r.input != input || !r.frame_numbers) continue;
    const RunRange range{i + 1, (*r.frame_numbers)[0], (*r.frame_numbers)[1]};
    if (range.first <= last && first <= range.last) out.push_back(range);
  }
  return out;
}

}  // namespace mobmap::builder
