#pragma once
// The mobility surface over (slope, roughness) as a heat map: the paper's Fig. 3.

#include "pictures/canvas.hpp"

#include "mobmap/gp/mobility_model.hpp"

namespace mobmap::app {

/// Plot ranges.
struct PlotRange {
  double slope_max_deg = 60.0;
  double roughness_min = 1.0;
  double roughness_max = 2.5;
};

/// Draws mobility over slope (x) and roughness (y) with axes, ticks, a colour bar and
/// the rule table's cell centres marked with their table value.
Canvas plotMobilitySurface(const gp::MobilityModel& model, const PlotRange& range = {});

}  // namespace mobmap::app
