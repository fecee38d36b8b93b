#include "commands/commands.hpp"
#include "io/ground_truth.hpp"
#include "io/map_files.hpp"
#include "pictures/mobility_plot.hpp"
#include "commands/progress.hpp"
#include "io/simulation_writer.hpp"

#include "mobmap/gp/mobility_model.hpp"

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <thread>

namespace mobmap::app {

Command addDemoCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "demo", "Run the embedded default: simulate the corridor, build its mobility map, compare with the truth");
  struct Options {
    std::string out = "maps/demo";
    int frames = sim::CorridorParams{}.frames;
    int step = 3;
    bool quiet = false;
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("--out", o->out, "Output directory")->capture_default_str();
  cmd->add_option("--frames", o->frames, "Frames to simulate")->check(CLI::Range(1, 100000))->capture_default_str();
  cmd->add_option("--step", o->step, "Fuse every STEP-th frame")->check(CLI::Range(1, 1000))->capture_default_str();
  cmd->add_flag("--quiet,-q", o->quiet, "No progress output");
  return [o, &app]() {
    namespace fs = std::filesystem;
    const std::string seq = (fs::path(o->out) / "corridor").string();
    sim::CorridorParams p;
    p.frames = o->frames;
    p.noise = sim::NoiseModel::kKinect;
    const sim::CorridorScene scene(p);
    std::cout << "mobmap demo: a head-mounted Kinect walks " << p.speed_mps * (p.frames - 1) / p.frame_rate_hz
              << " m down a corridor with ramps, a rough patch, stairs and a box that moves away\n";
    Progress progress("simulate", p.frames, o->quiet);
    const int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    writeSimulation(scene, seq, threads, [&](int done) { progress.update(done); });

    const gp::MobilityModel model;
    const std::string plot = (fs::path(o->out) / "mobility_surface.png").string();
    plotMobilitySurface(model).save(plot);

    // Build the map with the same code path as `mobmap build`.
    const std::string map_path = (fs::path(o->out) / "corridor.ot").string();
    std::vector<std::string> args = {"build", seq, "--out", map_path, "--force",
                                     "--frames", "0:" + std::to_string(p.frames - 1) + ":" + std::to_string(o->step)};
    if (o->quiet) args.push_back("--quiet");
    std::printf("\nmobmap build %s --out %s --frames 0:%d:%d\n", seq.c_str(), map_path.c_str(), p.frames - 1, o->step);
    const int rc = runSubcommand(app, args);
    if (rc != 0) return rc;

    const mapping::MobilityMap map = mapping::openMap(map_path);
    const GroundTruth truth = loadGroundTruth((fs::path(seq) / "ground_truth.json").string());
    const Evaluation ev = evaluateMap(map, truth, 3, 0.04);
    std::printf("\nMap vs ground truth (voxels seen >= 3 times):\n%-24s %8s %7s %10s\n", "surface", "expected", "voxels", "mean |err|");
    for (const auto& s : ev.surfaces) {
      if (s.voxels < 200) continue;  // the well-observed surfaces; `mobmap evaluate` lists all
      std::printf("%-24s %8.2f %7d %10.3f\n", s.surface->name.c_str(), s.surface->expected_mobility, s.voxels, s.mean_abs_error);
    }
    const int total = ev.true_traversable + ev.false_traversable + ev.true_untraversable + ev.false_untraversable;
    if (ev.edge_voxels > 0) {
      std::printf("%d voxels on edges between surfaces with different answers (scored apart): mean |err| %.3f\n",
                  ev.edge_voxels, ev.edge_mean_abs_error);
    }
    if (total) {
      std::printf("right side of 0.5: %.1f %% of %d voxels\n", 100.0 * (ev.true_traversable + ev.true_untraversable) / total, total);
    }
    const std::string stem = mapping::mapFileStem(map_path);
    // The executable as the user can type it (build/apps/mobmap before `cmake --install`).
    std::error_code ec;
    std::string exe = fs::read_symlink("/proc/self/exe", ec).string();
    if (ec) exe = "mobmap";
    const fs::path rel = fs::relative(exe, fs::current_path(), ec);
    if (!ec && !rel.empty() && rel.string().rfind("..", 0) != 0) exe = "./" + rel.string();
    std::cout << "\nFiles:\n"
              << "  " << seq << "/  " << p.frames << " frames in the 7-Scenes layout (depth/colour/label PNGs, poses, intrinsics)\n"
              << "  " << seq << "/ground_truth.json  every surface with slope, roughness and expected mobility\n"
              << "  " << map_path << "  the mobility OctoMap (MobilityOcTree)\n"
              << "  " << stem << ".octovis.ot  the same as a ColorOcTree: viridis, dark purple 0 ... yellow 1\n"
              << "  " << stem << ".bt  occupancy only;  " << stem << ".json  metadata\n"
              << "  " << plot << "  the GP mobility surface (paper Fig. 3)\n"
              << "View: octovis " << stem << ".octovis.ot   (Debian package octovis)\n"
              << "      " << exe << " serve " << map_path << "   (then open http://127.0.0.1:8080/ in a browser; Ctrl-C stops)\n"
              << "Ask:  " << exe << " query " << map_path << " 1.0 0.0 0.3 --snap 0.5\n"
              << "      " << exe << " query " << map_path << " --foot 3.0 -0.9 0.08 0 0.25 0.12   (a sole on the 15-degree ramp)\n"
              << "      " << exe << " info " << map_path << "\n"
              << "      " << exe << " reach " << map_path << " --png " << o->out << "/reach.png   (where a robot stepping 15 cm can walk)\n"
              << "      " << exe << " query " << map_path
              << " --foot 4.8 0.8 0.5 0 0.25 0.12 --reach   (the box top: flat, but 0.5 m up and out of reach)\n"
              << "      " << exe << " plan " << map_path << " --from 5.6 0.9 0 --to 7.05 0.9 0.68 --max-step 0.2 --png " << o->out
              << "/plan.png   (footsteps up the stairs; with --max-step 0.15: why not)\n"
              << "      " << exe << " evaluate " << map_path << " --truth " << seq << "/ground_truth.json\n"
              << "      " << exe << " export " << map_path << " --png " << o->out << "/top.png\n"
              << "      " << exe << " overlay " << map_path << " --frame " << p.frames / 2 << " --out " << o->out
              << "/overlay.png   (the map drawn into a frame, as in the paper's figures)\n";
    return 0;
  };
}

}  // namespace mobmap::app
