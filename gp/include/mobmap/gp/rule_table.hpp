#pragma once
/// @file rule_table.hpp
/// The empirical mobility rule of Genesio et al. (Table I): a score in [0,1] per
/// (slope, roughness) bin.

#include <Eigen/Core>

#include <string>
#include <vector>

namespace mobmap::gp {

/// A mobility lookup table over slope (degrees) and roughness ratio (A/A', >= 1).
///
/// Bins are half-open `[lower_i, lower_{i+1})`; the last bin on each axis is open
/// ended (`[lower_n, +inf)`). A value on a bin edge belongs to the upper bin, so
/// 10 degrees falls in "10-20". Inputs below the first edge fall in the first bin
/// (a measured roughness of 0.9999 is numerical noise around 1, not an error).
/// Immutable after construction; safe to share between threads.
class RuleTable {
 public:
  /// Builds a table from lower bin edges and values (rows: roughness bins,
  /// columns: slope bins). Throws std::invalid_argument naming the problem when
  /// edges are not finite and strictly increasing, sizes disagree, or a value is
  /// outside [0,1].
  RuleTable(std::vector<double> slope_lower_edges_deg, std::vector<double> roughness_lower_edges,
            Eigen::MatrixXd values);

  /// The table published in the paper (Table I): slope bins 0,10,20,30,40+ degrees,
  /// roughness bins 1.0,1.2,...,2.2+.
  static RuleTable paper();

  /// Parses the CSV form written by toCsv(): an optional `#` comment block, a header
  /// `roughness\slope,<slope lower edges...>` and one row per roughness bin
  /// `<roughness lower edge>,<values...>`. Throws std::invalid_argument with the
  /// 1-based line number and the problem. The library never opens files: the
  /// caller reads the text and adds the path to the message.
  static RuleTable parseCsv(const std::string& text);

  /// The CSV text that parseCsv() reads back to an equal table.
  [[nodiscard]] std::string toCsv() const;

  /// Mobility in [0,1] for a slope in degrees and a roughness ratio. Throws
  /// std::invalid_argument for NaN, infinite or negative inputs.
  [[nodiscard]] double lookup(double slope_deg, double roughness) const;

  /// Index of the slope bin holding `slope_deg` (same validation as lookup()).
  [[nodiscard]] int slopeBin(double slope_deg) const;
  /// Index of the roughness bin holding `roughness` (same validation as lookup()).
  [[nodiscard]] int roughnessBin(double roughness) const;

  [[nodiscard]] const std::vector<double>& slopeEdgesDeg() const { return slope_edges_deg_; }
  [[nodiscard]] const std::vector<double>& roughnessEdges() const { return roughness_edges_; }
  /// Values: rows are roughness bins, columns slope bins.
  [[nodiscard]] const Eigen::MatrixXd& values() const { return values_; }

  bool operator==(const RuleTable& other) const;

 private:
  std::vector<double> slope_edges_deg_;
  std::vector<double> roughness_edges_;
  Eigen::MatrixXd values_;
};

}  // namespace mobmap::gp
