#include "commands/commands.hpp"
#include "commands/progress.hpp"
#include "io/cli_text.hpp"
#include "io/io_error.hpp"
#include "io/simulation_writer.hpp"

#include <filesystem>
#include <iostream>
#include <memory>
#include <thread>

namespace mobmap::app {

Command addSimulateCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "simulate",
      "Render a synthetic walk through a corridor with exact ground truth, in the 7-Scenes layout");
  struct Options {
    std::string scene = "corridor";
    std::string out;
    int frames = sim::CorridorParams{}.frames;
    std::uint64_t seed = 1;
    std::string noise = "kinect";
    int edge_window = sim::KinectNoiseParams{}.edge_window_px;
    bool force = false;
    bool quiet = false;
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("--scene", o->scene,
                  "Scene to render: corridor (ramps, pyramids, box, stairs, a moving box) or rough (the same walk past "
                  "fields of pyramids, ridges along and across the path, blocks and random stones, each with its exact "
                  "area ratio in ground_truth.json)")
      ->check(CLI::IsMember({"corridor", "rough"}))
      ->capture_default_str();
  cmd->add_option("--out", o->out, "Output directory")->required();
  cmd->add_option("--frames", o->frames, "Number of frames (30 Hz)")->check(CLI::Range(1, 100000))->capture_default_str();
  cmd->add_option("--seed", o->seed, "Noise seed")->capture_default_str();
  cmd->add_option("--noise", o->noise, "Depth noise model: none (exact depth, 1 mm PNG quantisation) or kinect")
      ->check(CLI::IsMember({"none", "kinect"}))->capture_default_str();
  cmd->add_option("--edge-window", o->edge_window,
                  "With --noise kinect: the depth sensor's correlation window in pixels (odd), over which depth edges "
                  "are smoothed and mixed; 0 gives sharp edges (docs/SIMULATOR.md)")
      ->check(CLI::Range(0, 31))
      ->capture_default_str();
  cmd->add_flag("--force", o->force, "Write into a directory that already holds a sequence (its frames are replaced)");
  cmd->add_flag("--quiet,-q", o->quiet, "No progress output");
  return [o]() {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (!o->force && fs::exists(fs::path(o->out) / "ground_truth.json", ec)) {
      throw UsageError(o->out + " already holds a simulated sequence; pass --force to overwrite it");
    }
    sim::CorridorParams p;
    p.frames = o->frames;
    p.seed = o->seed;
    p.noise = o->noise == "kinect" ? sim::NoiseModel::kKinect : sim::NoiseModel::kNone;
    p.kinect.edge_window_px = o->edge_window;
    p.layout = o->scene == "rough" ? sim::Layout::kRoughYard : sim::Layout::kCorridor;
    try {
      sim::validate(p);
    } catch (const std::invalid_argument& e) {
      throw UsageError(cliText(e));
    }
    const sim::CorridorScene scene(p);
    if (o->force) {
      // The frames of an older, longer sequence past this one's last would otherwise stay
      // and be read as part of it.
      for (fs::directory_iterator it(o->out, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        if (name.size() < 13 || name.compare(0, 6, "frame-") != 0 || name[12] != '.' ||
            name.find_first_not_of("0123456789", 6) != 12) {
          continue;
        }
        std::error_code ignored;
        if (std::stoi(name.substr(6, 6)) >= p.frames) fs::remove(it->path(), ignored);
      }
    }
    Progress progress("simulate", p.frames, o->quiet);
    const int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    writeSimulation(scene, o->out, threads, [&](int done) { progress.update(done); });
    std::cout << "wrote " << p.frames << " frames of the " << (o->scene == "rough" ? "rough yard" : "corridor") << " (" << o->noise << " noise, seed "
              << p.seed << ", " << scene.surfaces().size() << " surfaces) to " << o->out << "\n"
              << "  ground truth: " << (fs::path(o->out) / "ground_truth.json").string() << "\n";
    return 0;
  };
}

}  // namespace mobmap::app
