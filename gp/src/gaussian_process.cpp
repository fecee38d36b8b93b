#include "mobmap/gp/gaussian_process.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace mobmap::gp {
namespace {

constexpr double kPi = 3.14159265358979323846;

void requirePositive(double value, const char* field) {
  if (!std::isfinite(value) || value <= 0.0) {
    std::ostringstream msg;
    msg << "KernelParams: " << field << " must be finite and > 0, got " << value;
    throw std::invalid_argument(msg.str());
  }
}

Eigen::MatrixXd squaredDistances(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  Eigen::MatrixXd d2(a.rows(), b.rows());
  for (Eigen::Index j = 0; j < b.rows(); ++j) {
    d2.col(j) = (a.rowwise() - b.row(j)).rowwise().squaredNorm();
  }
  return d2;
}

}  // namespace

void validate(const KernelParams& params) {
  requirePositive(params.signal_std, "signal_std");
  requirePositive(params.length_scale, "length_scale");
  requirePositive(params.noise_std, "noise_std");
}

Eigen::MatrixXd squaredExponentialKernel(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b,
                                         const KernelParams& params) {
  if (a.cols() != b.cols()) {
    throw std::invalid_argument("squaredExponentialKernel: inputs have different dimensions");
  }
  const double sf2 = params.signal_std * params.signal_std;
  const double inv2l2 = 1.0 / (2.0 * params.length_scale * params.length_scale);
  return (sf2 * (-inv2l2 * squaredDistances(a, b).array()).exp()).matrix();
}

GaussianProcess::GaussianProcess(Eigen::MatrixXd inputs, Eigen::VectorXd targets,
                                 KernelParams params)
    : inputs_(std::move(inputs)), targets_(std::move(targets)), params_(params) {
  validate(params_);
  if (inputs_.rows() == 0 || inputs_.rows() != targets_.size()) {
    std::ostringstream msg;
    msg << "GaussianProcess: " << inputs_.rows() << " inputs but " << targets_.size()
        << " targets (need the same, at least one)";
    throw std::invalid_argument(msg.str());
  }
  if (!inputs_.allFinite() || !targets_.allFinite()) {
    throw std::invalid_argument("GaussianProcess: training data contains NaN or infinity");
  }
  const double sf2 = params_.signal_std * params_.signal_std;
  Eigen::MatrixXd k = squaredExponentialKernel(inputs_, inputs_, params_);
  k.diagonal().array() += params_.noise_std * params_.noise_std;
  llt_.compute(k);
  // Near-duplicate inputs with tiny noise make K numerically singular: add the
  // smallest diagonal jitter that restores positive definiteness.
  double jitter = 1e-12 * sf2;
  while (llt_.info() != Eigen::Success) {
    if (jitter > 1e-6 * sf2) {
      throw std::runtime_error(
          "GaussianProcess: kernel matrix is not positive definite even with jitter 1e-6 sf^2 "
          "(duplicate training inputs with different targets and noise_std near 0?)");
    }
    Eigen::MatrixXd kj = k;
    kj.diagonal().array() += jitter;
    llt_.compute(kj);
    jitter_ = jitter;
    jitter *= 10.0;
  }
  alpha_ = llt_.solve(targets_);
}

// Queries are processed in blocks so the m x n cross-kernel never exceeds a few MB,
// whatever m is (a user may evaluate a whole plane of features).
constexpr Eigen::Index kBlockRows = 2048;

Eigen::VectorXd GaussianProcess::predictMean(const Eigen::MatrixXd& queries) const {
  Eigen::VectorXd mean(queries.rows());
  for (Eigen::Index b = 0; b < queries.rows(); b += kBlockRows) {
    const Eigen::Index m = std::min(kBlockRows, queries.rows() - b);
    mean.segment(b, m) = squaredExponentialKernel(queries.middleRows(b, m), inputs_, params_) * alpha_;
  }
  return mean;
}

GpPrediction GaussianProcess::predict(const Eigen::MatrixXd& queries) const {
  GpPrediction out;
  out.mean.resize(queries.rows());
  out.variance.resize(queries.rows());
  const double sf2 = params_.signal_std * params_.signal_std;
  for (Eigen::Index b = 0; b < queries.rows(); b += kBlockRows) {
    const Eigen::Index m = std::min(kBlockRows, queries.rows() - b);
    const Eigen::MatrixXd k_star = squaredExponentialKernel(queries.middleRows(b, m), inputs_, params_);
    out.mean.segment(b, m) = k_star * alpha_;
    // v = L^-1 k*, variance = k(x*,x*) - v^T v  (Algorithm 2.1, lines 5-6).
    const Eigen::MatrixXd v = llt_.matrixL().solve(k_star.transpose());  // n x m
    out.variance.segment(b, m) = (sf2 - v.colwise().squaredNorm().array()).matrix().transpose();
  }
  return out;
}

double GaussianProcess::logMarginalLikelihood() const {
  const double n = static_cast<double>(targets_.size());
  const double log_det = 2.0 * llt_.matrixL().toDenseMatrix().diagonal().array().log().sum();
  return -0.5 * targets_.dot(alpha_) - 0.5 * log_det - 0.5 * n * std::log(2.0 * kPi);
}

Eigen::Vector3d GaussianProcess::logMarginalLikelihoodGradient() const {
  const Eigen::Index n = targets_.size();
  const Eigen::MatrixXd d2 = squaredDistances(inputs_, inputs_);
  const double sf2 = params_.signal_std * params_.signal_std;
  const double l2 = params_.length_scale * params_.length_scale;
  const Eigen::MatrixXd kf = (sf2 * (-d2.array() / (2.0 * l2)).exp()).matrix();
  const Eigen::MatrixXd k_inv = llt_.solve(Eigen::MatrixXd::Identity(n, n));
  // R&W eq. 5.9: d/dtheta log p = 1/2 tr((alpha alpha^T - K^-1) dK/dtheta).
  const Eigen::MatrixXd w = alpha_ * alpha_.transpose() - k_inv;
  Eigen::Vector3d g;
  g(0) = 0.5 * (w.array() * (2.0 * kf).array()).sum();                          // d/d log sf
  g(1) = 0.5 * (w.array() * (kf.array() * d2.array() / l2)).sum();              // d/d log l
  g(2) = 0.5 * w.trace() * 2.0 * params_.noise_std * params_.noise_std;        // d/d log sn
  return g;
}

FitResult fitHyperparameters(const Eigen::MatrixXd& inputs, const Eigen::VectorXd& targets,
                             const KernelParams& initial, const FitOptions& options) {
  validate(initial);
  auto toParams = [](const Eigen::Vector3d& t) {
    return KernelParams{std::exp(t(0)), std::exp(t(1)), std::exp(t(2))};
  };
  Eigen::Vector3d theta(std::log(initial.signal_std), std::log(initial.length_scale),
                        std::log(initial.noise_std));
  GaussianProcess gp(inputs, targets, initial);
  double lml = gp.logMarginalLikelihood();
  FitResult result;
  double step = 0.1;
  for (int it = 0; it < options.max_iterations; ++it) {
    const Eigen::Vector3d g = gp.logMarginalLikelihoodGradient();
    result.iterations = it + 1;
    if (g.norm() < options.gradient_tolerance) {
      result.converged = true;
      break;
    }
    // Backtracking line search along the normalised gradient (Armijo condition).
    bool improved = false;
    for (int tries = 0; tries < 30 && !improved; ++tries) {
      const Eigen::Vector3d candidate = theta + step * g / g.norm();
      try {
        GaussianProcess trial(inputs, targets, toParams(candidate));
        const double trial_lml = trial.logMarginalLikelihood();
        if (std::isfinite(trial_lml) && trial_lml > lml + 1e-4 * step * g.norm()) {
          theta = candidate;
          gp = std::move(trial);
          lml = trial_lml;
          improved = true;
          step *= 2.0;
        }
      } catch (const std::runtime_error&) {
        // Not positive definite at this candidate: shrink the step.
      }
      if (!improved) step *= 0.5;
    }
    if (!improved) {
      result.converged = true;  // no ascent direction left at machine precision
      break;
    }
  }
  result.params = toParams(theta);
  result.log_marginal_likelihood = lml;
  return result;
}

}  // namespace mobmap::gp
