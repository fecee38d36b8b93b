#pragma once
// Checks of what a depth input says against what depth cameras see: depth in the wrong
// unit, a range limit that cuts away most of a frame or its floor. The builder reports
// what these return; `analyze` prints them too. They name the fields that help
// (`depth_scale`, `max_range_m`).

#include "mobmap/perception/frame_result.hpp"
#include "mobmap/sources/frame.hpp"
#include "mobmap/sources/adjusted.hpp"
#include "mobmap/sources/sequence.hpp"

#include <Eigen/Core>

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace mobmap::builder {

/// The depth a command read a frame with (the library's, sources/frame.hpp).
using sources::DepthUnit;

/// Depth cameras see about this far: a frame whose median valid depth lies outside is
/// taken to be in another unit.
constexpr double kPlausibleMedianMin = 0.3, kPlausibleMedianMax = 12.0;

/// Low bits that most of a depth image's stored values have zero: depth in a unit 2^bits
/// times finer than it was read in, or an encoding such as SUN RGB-D's (millimetres
/// rotated left by 3 bits, so nearly every value is a multiple of 8).
struct LowZeroBits {
  int bits = 0;
  double share = 0.0;  ///< of the valid values
};
/// The most low bits (2 to 4) that at least 90 % of the image's valid values, as stored
/// (depth times unit.units_per_m; every 7th pixel), have zero; nullopt for clouds, float
/// depth, fewer than 1000 valid values in the sample, or no such bits (plain depth has each low bit zero in about half
/// its values).
std::optional<LowZeroBits> lowZeroBits(const perception::DepthImage& depth, const DepthUnit& unit);

/// When the frame's median valid depth is implausible for a depth camera: what it reads
/// as, and each ``depth_scale`` (units per metre) among the common ones (1000, 5000,
/// 10000, 100, 1) that puts the median between 0.4 and 8 m, the one nearest 2 m first;
/// when the stored values share low zero bits (`bits`), the scale and the depth format
/// those bits point to instead. Else nullopt.
std::optional<std::string> depthUnitProblem(const perception::RangeReport& r, const DepthUnit& unit,
                                            const std::optional<LowZeroBits>& bits = std::nullopt);

/// The ``max_range_m`` (metres, rounded up to half a metre) that keeps points out to
/// `range_m`.
double rangeToSuggest(double range_m);

/// When most of the frame's valid points (over half) lie beyond max_range_m: how many,
/// and the ``max_range_m`` that keeps 95 % of them. Else nullopt.
std::optional<std::string> rangeCutProblem(const perception::RangeReport& r);

/// When the lowest surface in view (likely the floor) lies mostly beyond max_range_m and
/// the ground found, if any, is well above it (15 cm): where it is and the ``max_range_m``
/// that keeps it. Else nullopt. `ground_distance_m`: the ground plane's distance below the
/// camera, when one was found.
std::optional<std::string> floorCutProblem(const perception::RangeReport& r, std::optional<double> ground_distance_m);

/// The checks over a run's frames (`build`): each kind of problem is told once, in the
/// first frame that shows it, then counted for the summary.
class DepthCheckTally {
 public:
  /// Checks one frame (`label`: "frame 12"); returns what to print now, each line
  /// starting "warning: " (depth in another unit) or "note: " (what the range cut).
  std::vector<std::string> add(const std::string& label, const perception::RangeReport& r,
                               std::optional<double> ground_distance_m, const DepthUnit& unit,
                               const std::optional<LowZeroBits>& bits = std::nullopt);
  /// Whether every frame checked read as depth in another unit (a map of them is not
  /// the scene's).
  [[nodiscard]] bool everyFrameInAnotherUnit() const { return frames_ > 0 && unit_frames_ == static_cast<int>(frames_); }
  /// For the run's summary: what the range took over all frames, and how many frames
  /// showed each problem, with the largest ``max_range_m`` suggested ("warning: " when a
  /// quarter of the frames or more did, else "note: ").
  [[nodiscard]] std::vector<std::string> summary() const;
  [[nodiscard]] std::size_t validPoints() const { return valid_; }
  /// The depth-unit problem of the first frame that showed one.
  [[nodiscard]] const std::optional<std::string>& unitProblem() const { return unit_problem_; }
  [[nodiscard]] std::size_t beyondMaxRange() const { return beyond_; }

 private:
  std::size_t frames_ = 0, valid_ = 0, beyond_ = 0;
  double max_range_m_ = 0;
  int unit_frames_ = 0, cut_frames_ = 0, floor_frames_ = 0;
  double cut_suggest_m_ = 0, floor_suggest_m_ = 0;
  std::optional<std::string> unit_problem_;
};

}  // namespace mobmap::builder
