#include "commands/commands.hpp"
#include "io/config.hpp"
#include "io/files.hpp"
#include "io/io_error.hpp"
#include "commands/picture_options.hpp"
#include "pictures/mobility_plot.hpp"

#include "mobmap/gp/mobility_model.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>

namespace mobmap::app {

Command addScoreCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "score", "Mobility of a surface from its slope and roughness (rule table or Gaussian process)");
  struct Options {
    double slope = -1;
    double roughness = -1;
    std::string model = "gp";
    std::string table;
    std::string plot;
    ColourScale colours = ColourScale::kViridis;
    bool json = false;
    bool fit = false;
  };
  auto o = std::make_shared<Options>();
  auto* slope = cmd->add_option("--slope", o->slope, "Slope in degrees against gravity/ground (0-180)");
  auto* rough = cmd->add_option("--roughness", o->roughness, "Roughness ratio A/A' (>= 1)");
  cmd->add_option("--model", o->model, "Scorer: rule (paper Table I) or gp (GP over the table)")
      ->check(CLI::IsMember({"rule", "gp"}))->capture_default_str();
  cmd->add_option("--table", o->table, "Rule table CSV for another robot (see maps/FORMATS.md)");
  auto* plot = cmd->add_option("--plot", o->plot,
                               "Draw the mobility surface (slope 0-60, roughness 1-2.5) to a picture: .png, .svg or .pdf")
                   ->check(pictureFile());
  addColoursOption(*cmd, o->colours);
  cmd->add_flag("--json", o->json, "Print one JSON object");
  cmd->add_flag("--fit", o->fit, "Fit sf, l, sn by maximising the log marginal likelihood, report and use them");
  slope->needs(rough);
  rough->needs(slope);
  plot->excludes(slope);
  return [o, slope, plot]() {
    if (slope->count() == 0 && plot->count() == 0) {
      throw UsageError("score needs --slope and --roughness, or --plot OUT.png");
    }
    refuseToOverwriteInputs({{"--plot", o->plot}}, {{"--table", o->table}});
    gp::MobilityModelParams params;
    params.model = o->model == "rule" ? gp::ModelKind::kRuleTable : gp::ModelKind::kGaussianProcess;
    gp::RuleTable table = loadRuleTable(o->table);
    nlohmann::json fit_json;
    if (o->fit) {
      if (params.model != gp::ModelKind::kGaussianProcess) throw UsageError("--fit needs --model gp");
      const gp::MobilityModel initial(table, params);
      const auto fit = gp::fitHyperparameters(initial.normalise(initial.trainingFeatures()),
                                              initial.trainingTargets(),
                                              {params.signal_std, params.length_scale, params.noise_std});
      params.signal_std = fit.params.signal_std;
      params.length_scale = fit.params.length_scale;
      params.noise_std = fit.params.noise_std;
      fit_json = {{"signal_std", params.signal_std}, {"length_scale", params.length_scale},
                  {"noise_std", params.noise_std}, {"log_marginal_likelihood", fit.log_marginal_likelihood},
                  {"iterations", fit.iterations}, {"converged", fit.converged}};
      if (!o->json) {
        std::cout << "fitted hyperparameters: sf = " << params.signal_std << ", l = " << params.length_scale
                  << ", sn = " << params.noise_std << " (log marginal likelihood "
                  << fit.log_marginal_likelihood << ", " << fit.iterations << " iterations)\n";
      }
    }
    const gp::MobilityModel model(std::move(table), params);
    if (plot->count() > 0) {
      plotMobilitySurface(model, {}, o->colours).save(o->plot);
      if (o->json) {
        std::cout << nlohmann::json{{"plot", o->plot}, {"model", o->model}, {"fit", fit_json}}.dump() << "\n";
      } else {
        std::cout << "wrote " << o->plot << "\n";
      }
      return 0;
    }
    // The pipeline measures slopes in [0, 180] degrees and ratios A/A' >= 1 (a surface is
    // never smaller than its projection); outside those the models only extrapolate.
    const auto text = [](double v) {
      std::ostringstream out;
      out << v;
      return out.str();
    };
    if (!(o->slope >= 0 && o->slope <= 180)) throw UsageError("--slope must be in [0, 180] degrees, got " + text(o->slope));
    if (!(o->roughness >= 1 && std::isfinite(o->roughness))) {
      throw UsageError("--roughness is the ratio A/A' of a surface's area to its projection's, so >= 1; got " +
                       text(o->roughness));
    }
    gp::MobilityEstimate e;
    try {
      e = model.predict(o->slope, o->roughness);
    } catch (const std::invalid_argument& err) {
      throw UsageError(err.what());
    }
    if (o->json) {
      nlohmann::json j{{"slope_deg", o->slope}, {"roughness", o->roughness}, {"model", o->model},
                       {"mobility", e.mobility}, {"variance", e.variance}};
      if (o->fit) j["fit"] = fit_json;
      std::cout << j.dump() << "\n";
    } else {
      std::cout << std::fixed << std::setprecision(4) << "mobility " << e.mobility << "  variance "
                << e.variance << "  (" << o->model << ", slope " << o->slope << " deg, roughness "
                << o->roughness << ")\n";
    }
    return 0;
  };
}

}  // namespace mobmap::app
