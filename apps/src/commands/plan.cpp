// `mobmap plan`: footsteps from a start to a goal over a map (mapping::planFootsteps).
#include "answers/answers.hpp"
#include "commands/commands.hpp"
#include "commands/picture_options.hpp"
#include "commands/reach_options.hpp"
#include "io/cli_text.hpp"
#include "io/files.hpp"
#include "io/io_error.hpp"
#include "io/map_files.hpp"
#include "pictures/top_view.hpp"

#include "mobmap/mapping/footstep_planner.hpp"

#include <cmath>
#include <filesystem>
#include <cstdio>
#include <iostream>
#include <limits>
#include <memory>

namespace mobmap::app {
namespace {

// Blue and vermilion (Okabe and Ito's pair): apart with the common colour-vision
// deficiencies and from every mobility colour.
constexpr Rgb kLeftSole{0, 114, 178};
constexpr Rgb kRightSole{213, 94, 0};

/// Exit code of a run that found no plan (the answer is still printed).
constexpr int kNoPlan = 3;

}  // namespace

Command addPlanCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("plan", "Footsteps from a start to a goal: alternating left and right soles a planner can trust");
  struct Options {
    std::string map, frame = "map", png;
    std::vector<double> from, to;
    mapping::PlanParams params;
    int max_pixels = 1400;
    bool json = false;
    ColourScale colours = ColourScale::kViridis;
  };
  auto o = std::make_shared<Options>();
  cmd->add_option("MAP", o->map, "A .ot map written by `mobmap build`")->required();
  cmd->add_option("--from", o->from, "X Y Z: where the robot stands (metres, on or above its footing)")->expected(3)->required();
  cmd->add_option("--to", o->to, "X Y Z: the goal (metres, on or above the surface to stand on)")->expected(3)->required();
  cmd->add_option("--input-frame", o->frame,
                  "Frame of --from and --to, and of the footsteps printed: map (gravity aligned) or world (the data's own)")
      ->check(CLI::IsMember({"map", "world"}))
      ->capture_default_str();
  addRobotOptions(*cmd, o->params.robot);
  cmd->add_option("--goal-tolerance", o->params.goal_tolerance_m,
                  "A footstep whose centre lies this close to the goal (horizontally) ends the plan, metres")
      ->capture_default_str();
  cmd->add_option("--step-cost", o->params.step_cost_m, "Cost of each footstep, in metres of walking")->capture_default_str();
  cmd->add_option("--mobility-weight", o->params.mobility_weight_m,
                  "Cost of a footstep per unit of (1 - the lowest mobility under it), metres")
      ->capture_default_str();
  cmd->add_option("--weight", o->params.heuristic_weight,
                  "Heuristic weight of the A* search: 1 finds the cheapest plan; w > 1 a plan at most w times as costly, "
                  "much faster")
      ->capture_default_str();
  cmd->add_option("--time-limit", o->params.time_limit_s, "Give up after this many seconds of search")->capture_default_str();
  cmd->add_flag("--json", o->json, "One JSON object instead of the text");
  cmd->add_option("--png", o->png,
                  "Top view with the footsteps (left blue, right vermilion) over the mobility map; a .svg or .pdf name draws "
                  "it in that format")
      ->check(pictureFile());
  addColoursOption(*cmd, o->colours);
  cmd->add_option("--max-pixels", o->max_pixels, "Longest side of the picture's map area")
      ->check(CLI::Range(64, 16384))
      ->capture_default_str();
  return [o]() {
    try {
      mapping::validate(o->params);
    } catch (const std::invalid_argument& e) {
      throw UsageError(cliText(e));
    }
    const Eigen::Vector3d from_in(o->from[0], o->from[1], o->from[2]), to_in(o->to[0], o->to[1], o->to[2]);
    if (!from_in.allFinite()) throw UsageError("--from: values must be finite");
    if (!to_in.allFinite()) throw UsageError("--to: values must be finite");
    refuseToOverwriteInputs({{"--png", o->png}}, mapFilesAsInputs(o->map));
    const OpenedMap opened = openMapFiles(o->map);
    const mapping::MobilityMap& map = opened.map;
    const bool world = o->frame == "world";
    const Eigen::Vector3d from = world ? map.worldToMap(from_in) : from_in;
    const Eigen::Vector3d to = world ? map.worldToMap(to_in) : to_in;
    mapping::Plan plan;
    try {
      plan = mapping::planFootsteps(map.tree(), from, to, o->params);
    } catch (const mapping::PlanInputError& e) {
      throw IoError(o->map, e.what());
    } catch (const std::invalid_argument& e) {  // a step under two voxels of this map
      throw UsageError(cliText(e));
    }
    const InputFrame frame = world ? InputFrame::kWorld : InputFrame::kMap;
    if (o->json) {
      nlohmann::json answer = planJson(map, plan, o->params, frame);
      if (answer.contains("reason")) answer["reason"] = cliText(answer["reason"].get<std::string>());
      std::cout << answer.dump() << "\n";
    } else if (plan.found) {
      const auto& robot = o->params.robot;
      std::printf("plan: %zu footsteps after the start stance, %.2f m walked, highest step %.3f m, cost %.2f (%zu states "
                  "expanded in %.3f s); %s frame. Under each sole: the mean mobility and the share under --min-mobility %s "
                  "(a sole stands on at most %s of it):\n",
                  plan.footsteps.size() - 2, plan.length_m, plan.max_step_height_m, plan.cost, plan.expansions,
                  plan.planning_time_s, o->frame.c_str(), mapping::formatLimit(robot.min_mobility).c_str(),
                  (mapping::formatLimit(100 * robot.max_poor_fraction) + " %").c_str());
      for (std::size_t i = 0; i < plan.footsteps.size(); ++i) {
        const auto& f = plan.footsteps[i];
        const FootstepIn s = footstepIn(map, f, frame);
        std::printf("  %2zu %-5s x %7.3f  y %7.3f  z %6.3f  yaw %6.1f deg  mobility %.2f mean, %3.0f %% poor  tilt %4.1f deg%s\n",
                    i, mapping::toString(f.side), s.centre.x(), s.centre.y(), s.centre.z(), s.yaw * 180 / M_PI,
                    f.mean_mobility, 100 * f.poor_fraction, f.tilt_deg, i < 2 ? "  (start)" : "");
      }
    } else {
      std::printf("no plan: %s\n", cliText(plan.reason).c_str());
    }
    if (!o->png.empty()) {
      TopView view;
      std::vector<Eigen::Vector2d> cover{from.head<2>(), to.head<2>()};
      try {
        view = computeTopView(map.tree(), cover, o->max_pixels, std::numeric_limits<double>::infinity(), o->colours);
      } catch (const std::invalid_argument& e) {
        throw IoError(o->map, std::string("cannot draw a top view: ") + e.what());
      }
      TopViewPicture picture;
      picture.title = plan.found ? "Footstep plan on " + std::filesystem::path(o->map).filename().string()
                                 : "No plan: " + cliText(plan.reason).substr(0, 120);
      picture.colours = o->colours;
      const double l = o->params.robot.sole_length_m / 2, w = o->params.robot.sole_width_m / 2;
      for (const auto& f : plan.footsteps) {
        TopViewPicture::Outline sole;
        const double c = std::cos(f.yaw), s = std::sin(f.yaw);
        for (const auto& [a, b] : {std::pair{l, w}, std::pair{-l, w}, std::pair{-l, -w}, std::pair{l, -w}}) {
          sole.corners.emplace_back(f.x + c * a - s * b, f.y + s * a + c * b);
        }
        sole.colour = f.side == mapping::Side::kLeft ? kLeftSole : kRightSole;
        sole.label = f.side == mapping::Side::kLeft ? "left foot" : "right foot";
        picture.outlines.push_back(std::move(sole));
      }
      picture.mark = to.head<2>();
      picture.mark_label = "goal";
      const Picture canvas = drawTopView(view, picture, o->max_pixels);
      canvas.save(o->png);
      if (!o->json) std::printf("wrote %s (%s)\n", o->png.c_str(), describeTopView(view, canvas, o->max_pixels).c_str());
    }
    return plan.found ? 0 : kNoPlan;
  };
}

}  // namespace mobmap::app
