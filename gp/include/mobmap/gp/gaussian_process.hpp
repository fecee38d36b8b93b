#pragma once
/// @file gaussian_process.hpp
/// Gaussian-process regression with a squared-exponential kernel (Rasmussen &
/// Williams, "Gaussian Processes for Machine Learning", 2006, Algorithm 2.1).

#include <Eigen/Core>
#include <Eigen/Cholesky>

namespace mobmap::gp {

/// Hyperparameters of k(xi,xj) = sf^2 exp(-|xi-xj|^2 / (2 l^2)) plus i.i.d.
/// observation noise sn^2. Units are those of the (already normalised) inputs.
struct KernelParams {
  double signal_std = 1.0;    ///< sf; the paper uses 1.
  double length_scale = 0.1;  ///< l; the paper uses 0.1.
  double noise_std = 0.05;    ///< sn; the paper does not give it.
};

/// Throws std::invalid_argument naming the field unless every value is finite and > 0.
void validate(const KernelParams& params);

/// Squared-exponential kernel between the rows of `a` (n x d) and of `b` (m x d).
Eigen::MatrixXd squaredExponentialKernel(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b,
                                         const KernelParams& params);

/// Predictive mean and variance at a batch of query points.
struct GpPrediction {
  Eigen::VectorXd mean;      ///< posterior mean of the latent function
  Eigen::VectorXd variance;  ///< posterior variance of the latent function (no noise term)
};

/// A trained zero-mean GP. Training factorises K + sn^2 I once (Cholesky);
/// prediction costs O(n d) per point for the mean and O(n^2) for the variance.
/// Immutable after construction: const methods are safe from several threads.
class GaussianProcess {
 public:
  /// `inputs` holds one training point per row, `targets` one value per row.
  /// Throws std::invalid_argument on size mismatch, non-finite data or bad params,
  /// and std::runtime_error if K + sn^2 I stays non positive-definite after adding
  /// a diagonal jitter of up to 1e-6 sf^2 (R&W section 3.4.3 suggests jitter for
  /// near-duplicate inputs).
  GaussianProcess(Eigen::MatrixXd inputs, Eigen::VectorXd targets, KernelParams params);

  /// Mean and variance at each row of `queries` (m x d, same d as training).
  [[nodiscard]] GpPrediction predict(const Eigen::MatrixXd& queries) const;
  /// Mean only (cheaper: no triangular solve).
  [[nodiscard]] Eigen::VectorXd predictMean(const Eigen::MatrixXd& queries) const;

  /// log p(y | X, theta), R&W eq. 2.30.
  [[nodiscard]] double logMarginalLikelihood() const;
  /// Gradient of logMarginalLikelihood() with respect to
  /// (log sf, log l, log sn), R&W eq. 5.9.
  [[nodiscard]] Eigen::Vector3d logMarginalLikelihoodGradient() const;

  [[nodiscard]] const KernelParams& params() const { return params_; }
  /// Diagonal jitter that had to be added to make the Cholesky succeed (0 normally).
  [[nodiscard]] double jitter() const { return jitter_; }
  [[nodiscard]] const Eigen::MatrixXd& inputs() const { return inputs_; }
  [[nodiscard]] const Eigen::VectorXd& targets() const { return targets_; }
  /// (K + sn^2 I)^-1 y.
  [[nodiscard]] const Eigen::VectorXd& alpha() const { return alpha_; }

 private:
  Eigen::MatrixXd inputs_;
  Eigen::VectorXd targets_;
  KernelParams params_;
  double jitter_ = 0.0;
  Eigen::LLT<Eigen::MatrixXd> llt_;
  Eigen::VectorXd alpha_;
};

/// Options of fitHyperparameters().
struct FitOptions {
  int max_iterations = 200;
  double gradient_tolerance = 1e-5;  ///< stop when |grad| (log space) is below this
};

/// Result of fitHyperparameters().
struct FitResult {
  KernelParams params;
  double log_marginal_likelihood = 0.0;
  int iterations = 0;
  bool converged = false;
};

/// Maximises the log marginal likelihood over (log sf, log l, log sn) by gradient
/// ascent with backtracking, starting from `initial`.
FitResult fitHyperparameters(const Eigen::MatrixXd& inputs, const Eigen::VectorXd& targets,
                             const KernelParams& initial, const FitOptions& options = {});

}  // namespace mobmap::gp
