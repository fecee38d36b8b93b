#pragma once
/// @file mobility_model.hpp
/// Surface features (slope, roughness) -> mobility score in [0,1] with a variance,
/// by the paper's rule table or by a Gaussian process trained on it.

#include "mobmap/gp/gaussian_process.hpp"
#include "mobmap/gp/rule_table.hpp"

#include <optional>

namespace mobmap::gp {

/// Which scorer MobilityModel uses.
enum class ModelKind {
  kRuleTable,        ///< piecewise-constant lookup (paper Table I)
  kGaussianProcess,  ///< GP regression over the table (paper section III-E)
};

/// Parameters of MobilityModel. Defaults reproduce the paper (sf = 1, l = 0.1).
///
/// Input normalisation: the paper gives l = 0.1 without saying how inputs are
/// scaled. We map slope s (degrees) and roughness r to
///   u = s / slope_scale_deg,   v = (r - 1) / roughness_scale,
/// so that with the defaults one table bin (10 degrees, 0.2 of roughness) spans
/// 0.1 = l on both axes: neighbouring cells are correlated by exp(-1/2), enough for
/// a smooth, monotone surface without the dips a shorter scale leaves between cells.
struct MobilityModelParams {
  ModelKind model = ModelKind::kGaussianProcess;
  double signal_std = 1.0;       ///< GP sf (paper: 1)
  double length_scale = 0.1;     ///< GP l in normalised units (paper: 0.1)
  double noise_std = 0.05;       ///< GP sn (not in the paper; smooths the table's steps)
  double slope_scale_deg = 100.0;  ///< degrees per normalised unit
  double roughness_scale = 2.0;    ///< roughness per normalised unit
  /// Open-ended bins (">40 deg", ">2.2") get training points every bin width up to
  /// these limits, so the GP stays confident there instead of decaying to its prior.
  double open_slope_limit_deg = 100.0;
  double open_roughness_limit = 3.0;
  /// Variance reported by the rule table, which has none of its own: a uniform
  /// error over one table step of 0.25, 0.25^2 / 12.
  double rule_variance = 0.25 * 0.25 / 12.0;
};

/// Throws std::invalid_argument naming the field and value when a field is invalid.
void validate(const MobilityModelParams& params);

/// One score.
struct MobilityEstimate {
  double mobility = 0.0;  ///< in [0,1]; 0 untraversable, 1 flat smooth ground
  double variance = 0.0;  ///< predictive variance (unclamped; GP latent variance)
};

/// Scores surface features. Immutable after construction; const methods may be
/// called from several threads at once.
class MobilityModel {
 public:
  explicit MobilityModel(RuleTable table = RuleTable::paper(), MobilityModelParams params = {});

  /// Score one segment. slope in degrees vs the reference (0 = level), roughness
  /// A/A' (>= 1). Throws std::invalid_argument for NaN or negative inputs.
  [[nodiscard]] MobilityEstimate predict(double slope_deg, double roughness) const;

  /// Score many: column 0 slope (degrees), column 1 roughness. Same validation.
  [[nodiscard]] std::vector<MobilityEstimate> predict(const Eigen::MatrixX2d& features) const;

  /// Mobility only (clamped to [0,1]), without variances: O(n) per point instead of
  /// O(n^2), for drawing the whole (slope, roughness) plane.
  [[nodiscard]] Eigen::VectorXd mobility(const Eigen::MatrixX2d& features) const;

  /// Unclamped GP mean (for diagnostics and tests). Throws std::logic_error for the
  /// rule-table model.
  [[nodiscard]] Eigen::VectorXd rawMean(const Eigen::MatrixX2d& features) const;

  /// The (slope, roughness) training points and targets the GP was built from.
  [[nodiscard]] Eigen::MatrixX2d trainingFeatures() const { return training_features_; }
  [[nodiscard]] Eigen::VectorXd trainingTargets() const { return training_targets_; }

  /// Maps (slope deg, roughness) rows to the GP's normalised input space.
  [[nodiscard]] Eigen::MatrixXd normalise(const Eigen::MatrixX2d& features) const;

  [[nodiscard]] const RuleTable& table() const { return table_; }
  [[nodiscard]] const MobilityModelParams& params() const { return params_; }
  /// The trained GP (nullopt for the rule-table model).
  [[nodiscard]] const std::optional<GaussianProcess>& process() const { return gp_; }

 private:
  void checkFeatures(const Eigen::MatrixX2d& features) const;

  RuleTable table_;
  MobilityModelParams params_;
  Eigen::MatrixX2d training_features_;
  Eigen::VectorXd training_targets_;
  std::optional<GaussianProcess> gp_;
};

/// Positions of GP training points along one axis of a rule table: the physical
/// lower limit (first edge), each closed bin's centre, and for the open last bin
/// one point per (last closed) bin width from half a width past its edge up to
/// `open_limit`.
std::vector<double> trainingPositions(const std::vector<double>& lower_edges, double open_limit);

}  // namespace mobmap::gp
