#pragma once
// The mobility surface over (slope, roughness) as a heat map: the paper's Fig. 3.

#include "pictures/picture.hpp"

#include "mobmap/gp/mobility_model.hpp"

namespace mobmap::app {

/// Plot ranges.
struct PlotRange {
  double slope_max_deg = 60.0;
  double roughness_min = 1.0;
  double roughness_max = 2.5;
};

/// Draws mobility over slope (x) and roughness (y) with axes, ticks, the mobility legend
/// and the rule table's cell centres marked, each with its table value where the value
/// fits without covering another text.
Picture plotMobilitySurface(const gp::MobilityModel& model, const PlotRange& range = {},
                            ColourScale scale = ColourScale::kViridis);

}  // namespace mobmap::app
