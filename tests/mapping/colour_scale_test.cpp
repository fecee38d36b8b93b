// The mobility colour scales: the stops and the linear steps between them, and whether
// mobility 0, 0.5, 1 and unknown stay apart for viewers with a colour-vision deficiency.
//
// The simulation: Machado, Oliveira and Fernandes (2009), "A Physiologically-based Model
// for Simulation of Color Vision Deficiency", the matrices of severity 1.0 for
// protanopia and deuteranopia, applied to linear sRGB; then CIELAB (D65) and the CIE76
// colour difference. docs/MAPPING.md gives the numbers.
#include "mobmap/mapping/mobility_map.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>

#include <cmath>
#include <string>

namespace mobmap::mapping {
namespace {

double linear(std::uint8_t c) {
  const double v = c / 255.0;
  return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
}

// CIELAB (D65 white) of a colour, as a viewer with `vision` (linear sRGB to linear sRGB)
// sees it.
Eigen::Vector3d labSeen(const VoxelRgb& c, const Eigen::Matrix3d& vision) {
  const Eigen::Vector3d rgb = (vision * Eigen::Vector3d(linear(c[0]), linear(c[1]), linear(c[2]))).cwiseMax(0.0).cwiseMin(1.0);
  Eigen::Matrix3d to_xyz;
  to_xyz << 0.4124, 0.3576, 0.1805, 0.2126, 0.7152, 0.0722, 0.0193, 0.1192, 0.9505;
  const Eigen::Vector3d xyz = (to_xyz * rgb).cwiseQuotient(Eigen::Vector3d(0.95047, 1.0, 1.08883));
  const auto f = [](double t) { return t > 216.0 / 24389 ? std::cbrt(t) : (24389.0 / 27 * t + 16) / 116; };
  return {116 * f(xyz.y()) - 16, 500 * (f(xyz.x()) - f(xyz.y())), 200 * (f(xyz.y()) - f(xyz.z()))};
}

struct Vision {
  std::string name;
  Eigen::Matrix3d matrix;
};

std::vector<Vision> visions() {
  Eigen::Matrix3d protanopia, deuteranopia;
  protanopia << 0.152286, 1.052583, -0.204868, 0.114503, 0.786281, 0.099216, -0.003882, -0.048116, 1.051998;
  deuteranopia << 0.367322, 0.860646, -0.227968, 0.280085, 0.672501, 0.047413, -0.011820, 0.042940, 0.968881;
  return {{"normal", Eigen::Matrix3d::Identity()}, {"protanopia", protanopia}, {"deuteranopia", deuteranopia}};
}

// The smallest CIE76 difference between mobility 0, 0.5, 1 and unknown on `scale`.
double smallestDifference(ColourScale scale, const Eigen::Matrix3d& vision) {
  const std::vector<VoxelRgb> colours{mobilityRgb(0.0, scale), mobilityRgb(0.5, scale), mobilityRgb(1.0, scale), unknownRgb(scale)};
  double smallest = 1e9;
  for (std::size_t i = 0; i < colours.size(); ++i) {
    for (std::size_t j = i + 1; j < colours.size(); ++j) {
      smallest = std::min(smallest, (labSeen(colours[i], vision) - labSeen(colours[j], vision)).norm());
    }
  }
  return smallest;
}

TEST(ColourScale, PassesThroughItsStopsLinearly) {
  for (const ColourScale scale : {ColourScale::kViridis, ColourScale::kRedGreen}) {
    const std::vector<VoxelRgb>& stops = colourStops(scale);
    const double n = static_cast<double>(stops.size() - 1);
    for (std::size_t k = 0; k < stops.size(); ++k) EXPECT_EQ(mobilityRgb(k / n, scale), stops[k]) << toString(scale) << k;
    for (std::size_t k = 0; k + 1 < stops.size(); ++k) {
      const VoxelRgb mid = mobilityRgb((k + 0.5) / n, scale);
      for (std::size_t c = 0; c < 3; ++c) EXPECT_NEAR(mid[c], (stops[k][c] + stops[k + 1][c]) / 2.0, 0.5 + 1e-9);
    }
    EXPECT_EQ(mobilityRgb(-3.0, scale), stops.front());
    EXPECT_EQ(mobilityRgb(7.0, scale), stops.back());
    EXPECT_EQ(mobilityRgb(std::nan(""), scale), unknownRgb(scale));
    EXPECT_EQ(colourScaleNamed(toString(scale)), scale);
  }
  EXPECT_EQ(colourScaleNamed("jet"), std::nullopt);
  // The red-green scale is the paper's: red, yellow at 0.5, green.
  EXPECT_EQ(mobilityRgb(0.0, ColourScale::kRedGreen), (VoxelRgb{255, 0, 0}));
  EXPECT_EQ(mobilityRgb(0.25, ColourScale::kRedGreen), (VoxelRgb{255, 110, 0}));
  EXPECT_EQ(mobilityRgb(1.0, ColourScale::kRedGreen), (VoxelRgb{0, 220, 0}));
}

// The default keeps 0, 0.5, 1 and unknown at least 20 CIELAB units apart for normal
// vision, protanopia and deuteranopia; the red-green scale does not (which is why it is
// not the default), so the test can tell the two apart.
TEST(ColourScale, ViridisStaysApartUnderSimulatedColourBlindness) {
  constexpr double kMinDifference = 20;
  for (const Vision& v : visions()) {
    EXPECT_GE(smallestDifference(ColourScale::kViridis, v.matrix), kMinDifference) << v.name;
  }
  const auto all = visions();
  EXPECT_LT(smallestDifference(ColourScale::kRedGreen, all[1].matrix), kMinDifference) << "protanopia";
  EXPECT_LT(smallestDifference(ColourScale::kRedGreen, all[2].matrix), kMinDifference) << "deuteranopia";
  // Ordered for every viewer: lightness rises with mobility along the whole scale, so a
  // higher mobility always reads lighter.
  for (const Vision& v : all) {
    double previous = -1;
    for (int i = 0; i <= 40; ++i) {
      const double lightness = labSeen(mobilityRgb(i / 40.0), v.matrix).x();
      EXPECT_GT(lightness, previous) << v.name << " at " << i / 40.0;
      previous = lightness;
    }
  }
}

}  // namespace
}  // namespace mobmap::mapping
