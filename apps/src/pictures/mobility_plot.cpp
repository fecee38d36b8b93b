#include "pictures/mobility_plot.hpp"

#include <cmath>
#include <cstdio>

namespace mobmap::app {

Picture plotMobilitySurface(const gp::MobilityModel& model, const PlotRange& range, ColourScale scale) {
  constexpr int kW = 800, kH = 540;
  constexpr double kLeft = 80, kRight = 640, kTop = 56, kBottom = 456;  // plot area
  constexpr double kText = 12, kTitle = 15;
  const Rgb black{0, 0, 0};
  Picture c(kW, kH);
  const int pw = static_cast<int>(kRight - kLeft), ph = static_cast<int>(kBottom - kTop);
  // The surface, one pixel per unit, as an image.
  Eigen::MatrixX2d grid(static_cast<Eigen::Index>(pw) * ph, 2);
  for (int y = 0; y < ph; ++y) {
    for (int x = 0; x < pw; ++x) {
      const Eigen::Index i = static_cast<Eigen::Index>(y) * pw + x;
      grid(i, 0) = range.slope_max_deg * (x + 0.5) / pw;
      grid(i, 1) = range.roughness_max - (range.roughness_max - range.roughness_min) * (y + 0.5) / ph;
    }
  }
  const Eigen::VectorXd scores = model.mobility(grid);
  ImageRgb surface;
  surface.width = pw;
  surface.height = ph;
  surface.pixels.resize(static_cast<std::size_t>(pw) * static_cast<std::size_t>(ph));
  for (std::size_t i = 0; i < surface.pixels.size(); ++i) surface.pixels[i] = mobilityColour(scores(static_cast<Eigen::Index>(i)), scale);
  c.image(surface, kLeft, kTop, 1);
  const auto xOf = [&](double s) { return kLeft + s / range.slope_max_deg * pw; };
  const auto yOf = [&](double r) { return kTop + (range.roughness_max - r) / (range.roughness_max - range.roughness_min) * ph; };
  // Axes, ticks and their numbers first: the table's labels keep clear of them.
  c.strokeRect(kLeft - 0.5, kTop - 0.5, pw + 1, ph + 1, black, 1);
  const double text_h = c.textBox("0", kText).y1;
  for (int s = 0; s <= static_cast<int>(range.slope_max_deg); s += 10) {
    const double x = xOf(s);
    c.segments({{x, kBottom, x, kBottom + 5}}, black, 1);
    const std::string label = std::to_string(s);
    c.text(x - c.textBox(label, kText).x1 / 2, kBottom + 8, label, black, kText);
  }
  for (double r = range.roughness_min; r <= range.roughness_max + 1e-9; r += 0.25) {
    const double y = yOf(r);
    c.segments({{kLeft - 6, y, kLeft, y}}, black, 1);
    char buf[16];
    std::snprintf(buf, sizeof(buf), "%.2f", r);
    c.text(kLeft - 10 - c.textBox(buf, kText).x1, y - text_h / 2, buf, black, kText);
  }
  const std::string x_title = "slope (degrees)";
  c.text(kLeft + pw / 2.0 - c.textBox(x_title, 14).x1 / 2, kBottom + 30, x_title, black, 14);
  c.text(kLeft - 60, kTop - 26, "roughness A/A'", black, 14);
  const bool gp_model = model.process().has_value();
  const std::string title = gp_model ? "Mobility: Gaussian process (SE kernel) over the rule table" : "Mobility: the rule table";
  c.text(kLeft + (pw - c.textBox(title, kTitle, true).x1) / 2, 10, title, black, kTitle, true);
  // Table cell centres, marked, with the table's value beside them where it fits.
  const auto& t = model.table();
  const auto& se = t.slopeEdgesDeg();
  const auto& re = t.roughnessEdges();
  const Box plot{kLeft, kTop, kRight, kBottom};
  // The centres within the plot, each with its table value: the crosses are drawn (and
  // kept clear) first, so that no value covers another cell's cross.
  struct Centre {
    Eigen::Vector2d at;
    double value;
  };
  std::vector<Centre> centres;
  for (std::size_t i = 0; i < re.size(); ++i) {
    const double r = i + 1 < re.size() ? 0.5 * (re[i] + re[i + 1]) : re[i] + 0.5 * (re[i] - re[i - 1]);
    for (std::size_t j = 0; j < se.size(); ++j) {
      const double s = j + 1 < se.size() ? 0.5 * (se[j] + se[j + 1]) : se[j] + 0.5 * (se[j] - se[j - 1]);
      if (s > range.slope_max_deg || r > range.roughness_max || r < range.roughness_min) continue;
      centres.push_back({{xOf(s), yOf(r)}, t.values()(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j))});
    }
  }
  std::vector<std::array<double, 4>> crosses;
  for (const Centre& k : centres) {
    const double x = k.at.x(), y = k.at.y();
    crosses.push_back({x - 3, y, x + 3, y});
    crosses.push_back({x, y - 3, x, y + 3});
    c.keepClear({x - 4, y - 4, x + 4, y + 4});
  }
  c.segments(crosses, {255, 255, 255}, 3);  // a white casing: the crosses read on dark purple too
  c.segments(crosses, black, 1.2);
  for (const Centre& k : centres) {
    char buf[16];
    std::snprintf(buf, sizeof(buf), "%.2g", k.value);
    const Box b = Picture::textBox(buf, 10);
    const double dx = b.x1 / 2 + 8, dy = b.y1 / 2 + 6;
    c.label({k.at + Eigen::Vector2d(dx, dy), k.at + Eigen::Vector2d(dx, -dy), k.at + Eigen::Vector2d(-dx, dy),
             k.at + Eigen::Vector2d(-dx, -dy)},
            buf, black, 10, plot, 1.5);
  }
  drawMobilityLegend(c, 680, kTop, ph - 40, scale, {}, false);  // a model has no unknown
  return c;
}

}  // namespace mobmap::app
