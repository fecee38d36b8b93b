#include "pictures/mobility_plot.hpp"

#include <cmath>
#include <cstdio>

namespace mobmap::app {

Canvas plotMobilitySurface(const gp::MobilityModel& model, const PlotRange& range) {
  constexpr int kW = 760, kH = 520;
  constexpr int kLeft = 80, kRight = 640, kTop = 50, kBottom = 450;  // plot area
  const Rgb black{0, 0, 0};
  Canvas c(kW, kH);
  const int pw = kRight - kLeft, ph = kBottom - kTop;
  auto slopeAt = [&](int x) { return range.slope_max_deg * (x - kLeft + 0.5) / pw; };
  auto roughAt = [&](int y) {
    return range.roughness_max - (range.roughness_max - range.roughness_min) * (y - kTop + 0.5) / ph;
  };
  Eigen::MatrixX2d grid(static_cast<Eigen::Index>(pw) * ph, 2);
  for (int y = kTop; y < kBottom; ++y) {
    for (int x = kLeft; x < kRight; ++x) {
      const Eigen::Index i = static_cast<Eigen::Index>(y - kTop) * pw + (x - kLeft);
      grid(i, 0) = slopeAt(x);
      grid(i, 1) = roughAt(y);
    }
  }
  const Eigen::VectorXd scores = model.mobility(grid);
  for (int y = kTop; y < kBottom; ++y) {
    for (int x = kLeft; x < kRight; ++x) {
      c.set(x, y, mobilityColour(scores(static_cast<Eigen::Index>(y - kTop) * pw + (x - kLeft))));
    }
  }
  auto xOf = [&](double s) { return kLeft + static_cast<int>(std::lround(s / range.slope_max_deg * pw)); };
  auto yOf = [&](double r) {
    return kTop + static_cast<int>(std::lround((range.roughness_max - r) /
                                               (range.roughness_max - range.roughness_min) * ph));
  };
  // Table cell centres, labelled with the table's value.
  const auto& t = model.table();
  const auto& se = t.slopeEdgesDeg();
  const auto& re = t.roughnessEdges();
  for (std::size_t i = 0; i < re.size(); ++i) {
    const double r = i + 1 < re.size() ? 0.5 * (re[i] + re[i + 1]) : re[i] + 0.5 * (re[i] - re[i - 1]);
    for (std::size_t j = 0; j < se.size(); ++j) {
      const double s = j + 1 < se.size() ? 0.5 * (se[j] + se[j + 1]) : se[j] + 0.5 * (se[j] - se[j - 1]);
      if (s > range.slope_max_deg || r > range.roughness_max || r < range.roughness_min) continue;
      const int x = xOf(s), y = yOf(r);
      c.line(x - 3, y, x + 3, y, black);
      c.line(x, y - 3, x, y + 3, black);
      char buf[16];
      std::snprintf(buf, sizeof(buf), "%.2g", t.values()(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)));
      c.text(x + 4, y + 3, buf, black);
    }
  }
  // Axes and ticks.
  c.rect(kLeft - 1, kTop - 1, kRight, kBottom, black);
  for (int s = 0; s <= static_cast<int>(range.slope_max_deg); s += 10) {
    const int x = xOf(s);
    c.line(x, kBottom, x, kBottom + 5, black);
    const std::string label = std::to_string(s);
    c.text(x - Canvas::textWidth(label) / 2, kBottom + 9, label, black);
  }
  for (double r = range.roughness_min; r <= range.roughness_max + 1e-9; r += 0.25) {
    const int y = yOf(r);
    c.line(kLeft - 6, y, kLeft - 1, y, black);
    char buf[16];
    std::snprintf(buf, sizeof(buf), "%.2f", r);
    c.text(kLeft - 10 - Canvas::textWidth(buf), y - 3, buf, black);
  }
  c.text(kLeft + pw / 2 - Canvas::textWidth("SLOPE (DEG)", 2) / 2, kBottom + 26, "SLOPE (DEG)", black, 2);
  c.text(8, kTop - 30, "ROUGHNESS A/A'", black, 2);
  const bool gp_model = model.process().has_value();
  const std::string title = gp_model ? "MOBILITY: GP (SE KERNEL) OVER THE RULE TABLE" : "MOBILITY: RULE TABLE";
  c.text(kLeft + (pw - Canvas::textWidth(title, 2)) / 2, 12, title, black, 2);
  // Colour bar.
  const int bx0 = 680, bx1 = 705;
  for (int y = kTop; y < kBottom; ++y) {
    const double m = 1.0 - static_cast<double>(y - kTop) / (ph - 1);
    c.fillRect(bx0, y, bx1, y, mobilityColour(m));
  }
  c.rect(bx0 - 1, kTop - 1, bx1 + 1, kBottom, black);
  for (double m : {0.0, 0.25, 0.5, 0.75, 1.0}) {
    const int y = kTop + static_cast<int>(std::lround((1.0 - m) * (ph - 1)));
    c.line(bx1 + 1, y, bx1 + 5, y, black);
    char buf[16];
    std::snprintf(buf, sizeof(buf), "%.2f", m);
    c.text(bx1 + 8, y - 3, buf, black);
  }
  c.text(bx0 - 20, kTop - 16, "MOBILITY", black);
  return c;
}

}  // namespace mobmap::app
