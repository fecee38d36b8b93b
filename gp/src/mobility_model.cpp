#include "mobmap/gp/mobility_model.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace mobmap::gp {
namespace {

void requirePositive(double value, const char* field) {
  if (!std::isfinite(value) || value <= 0.0) {
    std::ostringstream msg;
    msg << "MobilityModelParams: " << field << " must be finite and > 0, got " << value;
    throw std::invalid_argument(msg.str());
  }
}

}  // namespace

void validate(const MobilityModelParams& params) {
  requirePositive(params.signal_std, "signal_std");
  requirePositive(params.length_scale, "length_scale");
  requirePositive(params.noise_std, "noise_std");
  requirePositive(params.slope_scale_deg, "slope_scale_deg");
  requirePositive(params.roughness_scale, "roughness_scale");
  requirePositive(params.open_slope_limit_deg, "open_slope_limit_deg");
  requirePositive(params.open_roughness_limit, "open_roughness_limit");
  if (!std::isfinite(params.rule_variance) || params.rule_variance < 0.0) {
    std::ostringstream msg;
    msg << "MobilityModelParams: rule_variance must be finite and >= 0, got "
        << params.rule_variance;
    throw std::invalid_argument(msg.str());
  }
}

std::vector<double> trainingPositions(const std::vector<double>& lower_edges, double open_limit) {
  std::vector<double> out;
  out.push_back(lower_edges.front());
  for (std::size_t i = 0; i + 1 < lower_edges.size(); ++i) {
    out.push_back(0.5 * (lower_edges[i] + lower_edges[i + 1]));
  }
  const double last = lower_edges.back();
  const double width =
      lower_edges.size() >= 2 ? last - lower_edges[lower_edges.size() - 2] : std::max(last, 1.0);
  for (double x = last + 0.5 * width; x <= std::max(open_limit, last + 0.5 * width) + 1e-9;
       x += width) {
    out.push_back(x);
  }
  return out;
}

MobilityModel::MobilityModel(RuleTable table, MobilityModelParams params)
    : table_(std::move(table)), params_(params) {
  validate(params_);
  const auto slopes = trainingPositions(table_.slopeEdgesDeg(), params_.open_slope_limit_deg);
  const auto roughs = trainingPositions(table_.roughnessEdges(), params_.open_roughness_limit);
  const auto n = static_cast<Eigen::Index>(slopes.size() * roughs.size());
  training_features_.resize(n, 2);
  training_targets_.resize(n);
  Eigen::Index k = 0;
  for (double r : roughs) {
    for (double s : slopes) {
      training_features_(k, 0) = s;
      training_features_(k, 1) = r;
      training_targets_(k) = table_.lookup(s, r);  // one target per cell, from the table
      ++k;
    }
  }
  if (params_.model == ModelKind::kGaussianProcess) {
    gp_.emplace(normalise(training_features_), training_targets_,
                KernelParams{params_.signal_std, params_.length_scale, params_.noise_std});
  }
}

Eigen::MatrixXd MobilityModel::normalise(const Eigen::MatrixX2d& features) const {
  Eigen::MatrixXd x(features.rows(), 2);
  x.col(0) = features.col(0) / params_.slope_scale_deg;
  x.col(1) = (features.col(1).array() - 1.0) / params_.roughness_scale;
  return x;
}

void MobilityModel::checkFeatures(const Eigen::MatrixX2d& features) const {
  for (Eigen::Index i = 0; i < features.rows(); ++i) {
    const double s = features(i, 0);
    const double r = features(i, 1);
    if (!std::isfinite(s) || s < 0.0 || !std::isfinite(r) || r < 0.0) {
      std::ostringstream msg;
      msg << "MobilityModel::predict: slope " << s << " deg, roughness " << r
          << " (both must be finite and >= 0)";
      throw std::invalid_argument(msg.str());
    }
  }
}

Eigen::VectorXd MobilityModel::rawMean(const Eigen::MatrixX2d& features) const {
  if (!gp_) throw std::logic_error("MobilityModel::rawMean: the rule-table model has no GP");
  checkFeatures(features);
  return gp_->predictMean(normalise(features));
}

Eigen::VectorXd MobilityModel::mobility(const Eigen::MatrixX2d& features) const {
  checkFeatures(features);
  Eigen::VectorXd out(features.rows());
  if (!gp_) {
    for (Eigen::Index i = 0; i < features.rows(); ++i) out(i) = table_.lookup(features(i, 0), features(i, 1));
    return out;
  }
  return gp_->predictMean(normalise(features)).cwiseMax(0.0).cwiseMin(1.0);
}

std::vector<MobilityEstimate> MobilityModel::predict(const Eigen::MatrixX2d& features) const {
  checkFeatures(features);
  std::vector<MobilityEstimate> out(static_cast<std::size_t>(features.rows()));
  if (!gp_) {
    for (Eigen::Index i = 0; i < features.rows(); ++i) {
      out[static_cast<std::size_t>(i)] = {table_.lookup(features(i, 0), features(i, 1)),
                                          params_.rule_variance};
    }
    return out;
  }
  const GpPrediction p = gp_->predict(normalise(features));
  for (Eigen::Index i = 0; i < features.rows(); ++i) {
    out[static_cast<std::size_t>(i)] = {std::clamp(p.mean(i), 0.0, 1.0), p.variance(i)};
  }
  return out;
}

MobilityEstimate MobilityModel::predict(double slope_deg, double roughness) const {
  Eigen::MatrixX2d f(1, 2);
  f << slope_deg, roughness;
  return predict(f).front();
}

}  // namespace mobmap::gp
