// Tests of the gp module against oracles: the paper's table, closed forms,
// numerical derivatives.
#include "mobmap/gp/gaussian_process.hpp"
#include "mobmap/gp/mobility_model.hpp"
#include "mobmap/gp/rule_table.hpp"

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace mobmap::gp {
namespace {

TEST(RuleTable, PaperValuesAtEveryCellCentre) {
  const RuleTable t = RuleTable::paper();
  // Table I of the paper, transcribed independently of rule_table.cpp.
  const double expected[7][5] = {{1, .75, .5, .25, 0}, {.75, .5, .25, 0, 0}, {.5, .25, 0, 0, 0},
                                 {.25, 0, 0, 0, 0},    {0, 0, 0, 0, 0},      {0, 0, 0, 0, 0},
                                 {0, 0, 0, 0, 0}};
  const double slope_centres[5] = {5, 15, 25, 35, 60};
  const double rough_centres[7] = {1.1, 1.3, 1.5, 1.7, 1.9, 2.1, 2.5};
  for (int r = 0; r < 7; ++r) {
    for (int s = 0; s < 5; ++s) {
      EXPECT_DOUBLE_EQ(t.lookup(slope_centres[s], rough_centres[r]), expected[r][s])
          << "slope " << slope_centres[s] << " roughness " << rough_centres[r];
    }
  }
}

TEST(RuleTable, BinEdgesBelongToTheUpperBin) {
  const RuleTable t = RuleTable::paper();
  EXPECT_EQ(t.slopeBin(0.0), 0);
  EXPECT_EQ(t.slopeBin(std::nextafter(10.0, 0.0)), 0);
  EXPECT_EQ(t.slopeBin(10.0), 1);
  EXPECT_EQ(t.slopeBin(20.0), 2);
  EXPECT_EQ(t.slopeBin(30.0), 3);
  EXPECT_EQ(t.slopeBin(40.0), 4);
  EXPECT_EQ(t.slopeBin(89.9), 4);  // open-ended bin
  EXPECT_EQ(t.slopeBin(1e6), 4);
  EXPECT_EQ(t.roughnessBin(1.0), 0);
  EXPECT_EQ(t.roughnessBin(std::nextafter(1.2, 0.0)), 0);
  EXPECT_EQ(t.roughnessBin(1.2), 1);
  EXPECT_EQ(t.roughnessBin(2.2), 6);
  EXPECT_EQ(t.roughnessBin(50.0), 6);  // open-ended bin
  EXPECT_EQ(t.roughnessBin(0.999), 0);  // numerical noise below 1 stays in the first bin
  EXPECT_DOUBLE_EQ(t.lookup(10.0, 1.2), 0.5);
  EXPECT_DOUBLE_EQ(t.lookup(std::nextafter(10.0, 0.0), std::nextafter(1.2, 0.0)), 1.0);
}

TEST(RuleTable, RejectsNanAndNegativeInputs) {
  const RuleTable t = RuleTable::paper();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW((void)t.lookup(nan, 1.0), std::invalid_argument);
  EXPECT_THROW((void)t.lookup(5.0, nan), std::invalid_argument);
  EXPECT_THROW((void)t.lookup(-1.0, 1.0), std::invalid_argument);
  EXPECT_THROW((void)t.lookup(5.0, -0.5), std::invalid_argument);
  EXPECT_THROW((void)t.lookup(std::numeric_limits<double>::infinity(), 1.0), std::invalid_argument);
}

TEST(RuleTable, CsvRoundTripIsExact) {
  const RuleTable t = RuleTable::paper();
  EXPECT_EQ(RuleTable::parseCsv(t.toCsv()), t);
}

TEST(RuleTable, CustomCsvForAnotherRobot) {
  // A quadruped: tolerates 30 degrees, three slope bins, two roughness bins.
  const RuleTable q = RuleTable::parseCsv(
      "# quadruped\nroughness\\slope, 0, 15, 30\n1.0, 1, 0.8, 0.3\n1.3, 0.6, 0.4, 0\n");
  EXPECT_DOUBLE_EQ(q.lookup(20, 1.1), 0.8);
  EXPECT_DOUBLE_EQ(q.lookup(45, 1.1), 0.3);
  EXPECT_DOUBLE_EQ(q.lookup(0, 2.0), 0.6);
}

TEST(RuleTable, BadCsvNamesTheLine) {
  auto message = [](const std::string& text) {
    try {
      (void)RuleTable::parseCsv(text);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("r\\s,0,10\n1.0,1,abc\n").find("line 2"), std::string::npos);
  EXPECT_NE(message("r\\s,0,10\n1.0,1\n").find("line 2"), std::string::npos);
  EXPECT_NE(message("r\\s,0,10\n1.0,1,1.5\n").find("[0,1]"), std::string::npos);
  EXPECT_NE(message("r\\s,10,0\n1.0,1,1\n").find("increase"), std::string::npos);
  EXPECT_NE(message("").find("no header"), std::string::npos);
  EXPECT_NE(message("r\\s,0,10\n").find("no roughness rows"), std::string::npos);
}

// ---------------------------------------------------------------------------

TEST(GaussianProcess, OneDimensionalCaseMatchesHandComputedClosedForm) {
  // Two training points x = 0, 1 with targets 1, 0; sf = 1, l = 1, sn = 0.1.
  // K = [[1+sn^2, e^-1/2], [e^-1/2, 1+sn^2]]; at x* = 0.5, k* = e^-1/8 (1, 1).
  Eigen::MatrixXd x(2, 1);
  x << 0, 1;
  Eigen::VectorXd y(2);
  y << 1, 0;
  const KernelParams p{1.0, 1.0, 0.1};
  GaussianProcess gp(x, y, p);
  const double a = 1.0 + 0.01, b = std::exp(-0.5), ks = std::exp(-0.125);
  const double det = a * a - b * b;
  // mean = k*^T K^-1 y = ks * (a - b) / det * 1 (first row sum of the inverse times y)
  const double mean = ks * (a * 1 - b * 0) / det + ks * (-b * 1 + a * 0) / det;
  const double var = 1.0 - ks * ks * (2 * a - 2 * b) / det;
  Eigen::MatrixXd q(1, 1);
  q << 0.5;
  const auto pred = gp.predict(q);
  EXPECT_NEAR(pred.mean(0), mean, 1e-12);
  EXPECT_NEAR(pred.variance(0), var, 1e-12);
  // log marginal likelihood: -1/2 y^T K^-1 y - 1/2 log det K - log 2 pi.
  const double quad = a / det;  // y = (1, 0): (K^-1)_00
  EXPECT_NEAR(gp.logMarginalLikelihood(),
              -0.5 * quad - 0.5 * std::log(det) - std::log(2 * 3.14159265358979323846), 1e-12);
}

TEST(GaussianProcess, KernelMatrixIsSymmetricPositiveDefinite) {
  const MobilityModel model;
  const Eigen::MatrixXd x = model.normalise(model.trainingFeatures());
  const Eigen::MatrixXd k = squaredExponentialKernel(x, x, KernelParams{});
  EXPECT_LT((k - k.transpose()).cwiseAbs().maxCoeff(), 1e-15);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(k);
  EXPECT_GT(es.eigenvalues().minCoeff(), -1e-12);  // PSD up to rounding
  Eigen::MatrixXd kn = k;
  kn.diagonal().array() += 0.05 * 0.05;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> esn(kn);
  EXPECT_GE(esn.eigenvalues().minCoeff(), 0.05 * 0.05 * (1 - 1e-9));  // + sn^2 I lifts every eigenvalue
}

TEST(GaussianProcess, NearDuplicateInputsDoNotBreakCholesky) {
  Eigen::MatrixXd x(3, 2);
  x << 0.1, 0.2, 0.1 + 1e-13, 0.2, 0.5, 0.5;
  Eigen::VectorXd y(3);
  y << 1.0, 1.0, 0.0;
  GaussianProcess gp(x, y, KernelParams{1.0, 0.1, 1e-9});  // practically noise free
  EXPECT_GT(gp.jitter(), 0.0);
  const auto pred = gp.predict(x);
  EXPECT_TRUE(pred.mean.allFinite());
  EXPECT_NEAR(pred.mean(0), 1.0, 1e-3);
  EXPECT_NEAR(pred.mean(2), 0.0, 1e-3);
}

TEST(GaussianProcess, ExactDuplicatesWithConflictingTargetsAverageInsteadOfNan) {
  Eigen::MatrixXd x(2, 1);
  x << 0.3, 0.3;
  Eigen::VectorXd y(2);
  y << 0.0, 1.0;
  // Jitter makes the solve succeed; the prediction must be their average, never NaN.
  GaussianProcess gp(x, y, KernelParams{1.0, 0.1, 1e-9});
  Eigen::MatrixXd q(1, 1);
  q << 0.3;
  const auto p = gp.predict(q);
  EXPECT_TRUE(std::isfinite(p.mean(0)));
  EXPECT_NEAR(p.mean(0), 0.5, 1e-3);
}

TEST(GaussianProcess, RejectsBadParametersAndData) {
  Eigen::MatrixXd x(1, 1);
  x << 0;
  Eigen::VectorXd y(1);
  y << 1;
  EXPECT_THROW(GaussianProcess(x, y, KernelParams{1, 0, 0.1}), std::invalid_argument);
  EXPECT_THROW(GaussianProcess(x, y, KernelParams{-1, 0.1, 0.1}), std::invalid_argument);
  EXPECT_THROW(GaussianProcess(x, Eigen::VectorXd(2), KernelParams{}), std::invalid_argument);
  y(0) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(GaussianProcess(x, y, KernelParams{}), std::invalid_argument);
}

TEST(GaussianProcess, AnalyticGradientMatchesCentralDifferences) {
  const MobilityModel model;
  const Eigen::MatrixXd x = model.normalise(model.trainingFeatures());
  const Eigen::VectorXd y = model.trainingTargets();
  const KernelParams p{0.8, 0.13, 0.07};
  const GaussianProcess gp(x, y, p);
  const Eigen::Vector3d g = gp.logMarginalLikelihoodGradient();
  const double h = 1e-5;  // central differences in log space: error O(h^2)
  for (int i = 0; i < 3; ++i) {
    Eigen::Vector3d t(std::log(p.signal_std), std::log(p.length_scale), std::log(p.noise_std));
    Eigen::Vector3d tp = t, tm = t;
    tp(i) += h;
    tm(i) -= h;
    const auto lml = [&](const Eigen::Vector3d& th) {
      return GaussianProcess(x, y, KernelParams{std::exp(th(0)), std::exp(th(1)), std::exp(th(2))})
          .logMarginalLikelihood();
    };
    const double numeric = (lml(tp) - lml(tm)) / (2 * h);
    EXPECT_NEAR(g(i), numeric, 1e-4 * std::max(1.0, std::abs(numeric))) << "parameter " << i;
  }
}

TEST(GaussianProcess, FittingIncreasesTheMarginalLikelihood) {
  const MobilityModel model;
  const Eigen::MatrixXd x = model.normalise(model.trainingFeatures());
  const Eigen::VectorXd y = model.trainingTargets();
  const KernelParams start{};
  const double before = GaussianProcess(x, y, start).logMarginalLikelihood();
  const FitResult fit = fitHyperparameters(x, y, start);
  EXPECT_GT(fit.log_marginal_likelihood, before);
  // At the optimum the gradient is (nearly) zero.
  const GaussianProcess fitted(x, y, fit.params);
  EXPECT_LT(fitted.logMarginalLikelihoodGradient().norm(), 1e-2);
}

// ---------------------------------------------------------------------------

TEST(MobilityModel, GpReproducesTheTableAtEveryCellCentre) {
  const MobilityModel model;
  const RuleTable& t = model.table();
  double worst = 0.0;
  for (double s : {5.0, 15.0, 25.0, 35.0, 45.0}) {
    for (double r : {1.1, 1.3, 1.5, 1.7, 1.9, 2.1, 2.3}) {
      const double err = std::abs(model.predict(s, r).mobility - t.lookup(s, r));
      worst = std::max(worst, err);
      EXPECT_LE(err, 0.1) << "slope " << s << " roughness " << r;
    }
  }
  RecordProperty("worst_cell_centre_error", std::to_string(worst));
  std::cout << "[ info ] worst |GP - table| at cell centres: " << worst << "\n";
}

TEST(MobilityModel, GpIsSmoothWithoutOvershoot) {
  const MobilityModel model;
  const int n = 121;
  Eigen::MatrixX2d grid(n * n, 2);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      grid(i * n + j, 0) = 60.0 * i / (n - 1);
      grid(i * n + j, 1) = 1.0 + 1.5 * j / (n - 1);
    }
  }
  const Eigen::VectorXd raw = model.rawMean(grid);
  EXPECT_GE(raw.minCoeff(), -0.05);
  EXPECT_LE(raw.maxCoeff(), 1.05);
}

TEST(MobilityModel, GpMeanNeverIncreasesWithSlopeOrRoughness) {
  const MobilityModel model;
  const int ns = 241, nr = 151;  // 0.25 deg and 0.01 steps
  Eigen::MatrixX2d grid(ns * nr, 2);
  for (int i = 0; i < ns; ++i) {
    for (int j = 0; j < nr; ++j) {
      grid(i * nr + j, 0) = 60.0 * i / (ns - 1);
      grid(i * nr + j, 1) = 1.0 + 1.5 * j / (nr - 1);
    }
  }
  const Eigen::VectorXd m = model.rawMean(grid);
  double worst_s = 0, worst_r = 0;
  for (int i = 0; i < ns; ++i) {
    for (int j = 0; j < nr; ++j) {
      const double here = m(i * nr + j);
      if (i > 0) worst_s = std::max(worst_s, here - m((i - 1) * nr + j));
      if (j > 0) worst_r = std::max(worst_r, here - m(i * nr + j - 1));
    }
  }
  EXPECT_LE(worst_s, 0.02);
  EXPECT_LE(worst_r, 0.02);
  std::cout << "[ info ] largest increase along slope " << worst_s << ", along roughness "
            << worst_r << "\n";
}

TEST(MobilityModel, VarianceIsSmallOnTheDataAndTendsToSignalVarianceFarAway) {
  const MobilityModel model;
  const double near = model.predict(15, 1.3).variance;
  Eigen::MatrixX2d far(1, 2);
  far << 1000.0, 40.0;
  const double far_var = model.predict(far).front().variance;
  EXPECT_LT(near, 0.01);
  EXPECT_GT(far_var, near);
  EXPECT_NEAR(far_var, model.params().signal_std * model.params().signal_std, 1e-9);
}

TEST(MobilityModel, FlatSmoothGroundScoresNearOneAndWallsZero) {
  const MobilityModel model;
  EXPECT_GT(model.predict(0.0, 1.0).mobility, 0.95);
  EXPECT_LT(model.predict(90.0, 1.0).mobility, 0.05);
  EXPECT_LT(model.predict(0.0, 2.8).mobility, 0.05);
}

TEST(MobilityModel, BatchEqualsSinglePredictions) {
  const MobilityModel model;
  Eigen::MatrixX2d f(3, 2);
  f << 3, 1.05, 22, 1.33, 50, 2.4;
  const auto batch = model.predict(f);
  for (int i = 0; i < 3; ++i) {
    const auto one = model.predict(f(i, 0), f(i, 1));
    EXPECT_DOUBLE_EQ(batch[static_cast<std::size_t>(i)].mobility, one.mobility);
    EXPECT_DOUBLE_EQ(batch[static_cast<std::size_t>(i)].variance, one.variance);
  }
}

TEST(MobilityModel, MeanOnlyBatchEqualsFullPrediction) {
  const MobilityModel model;
  Eigen::MatrixX2d f(4, 2);
  f << 0, 1.0, 17, 1.45, 38, 1.1, 70, 2.9;
  const Eigen::VectorXd m = model.mobility(f);
  const auto full = model.predict(f);
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(m(i), full[static_cast<std::size_t>(i)].mobility, 1e-12);
}

TEST(MobilityModel, RuleModelUsesTheTableAndItsNominalVariance) {
  MobilityModelParams p;
  p.model = ModelKind::kRuleTable;
  const MobilityModel model(RuleTable::paper(), p);
  EXPECT_DOUBLE_EQ(model.predict(12, 1.25).mobility, 0.5);
  EXPECT_DOUBLE_EQ(model.predict(12, 1.25).variance, p.rule_variance);
  EXPECT_THROW((void)model.rawMean(Eigen::MatrixX2d::Zero(1, 2)), std::logic_error);
}

TEST(MobilityModel, RejectsInvalidInputsAndParameters) {
  const MobilityModel model;
  EXPECT_THROW((void)model.predict(std::numeric_limits<double>::quiet_NaN(), 1.0), std::invalid_argument);
  EXPECT_THROW((void)model.predict(-3, 1.0), std::invalid_argument);
  MobilityModelParams p;
  p.length_scale = 0;
  EXPECT_THROW(MobilityModel(RuleTable::paper(), p), std::invalid_argument);
  p = {};
  p.slope_scale_deg = std::numeric_limits<double>::infinity();
  EXPECT_THROW(MobilityModel(RuleTable::paper(), p), std::invalid_argument);
}

TEST(MobilityModel, TrainingPositionsCoverEdgesCentresAndOpenBins) {
  const auto s = trainingPositions({0, 10, 20, 30, 40}, 100);
  const std::vector<double> expected = {0, 5, 15, 25, 35, 45, 55, 65, 75, 85, 95};
  ASSERT_EQ(s.size(), expected.size());
  for (std::size_t i = 0; i < s.size(); ++i) EXPECT_NEAR(s[i], expected[i], 1e-9);
}

}  // namespace
}  // namespace mobmap::gp
