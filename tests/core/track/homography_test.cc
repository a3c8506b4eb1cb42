#include "core/track/homography.h"

#include "tests/testing/noise.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <vector>

namespace saker::track {
namespace {

using saker::testing::Noise;

constexpr double kWidth = 1280;
constexpr double kHeight = 720;

// A frame-to-frame motion of an airborne camera: a few pixels of shift, a degree of rotation,
// 2 % zoom and a little perspective.
Eigen::Matrix3d TruthHomography() {
  Eigen::Matrix3d h;
  h << 1.018, 0.021, 14.5,   //
      -0.017, 0.994, -8.25,  //
      2.2e-5, -1.6e-5, 1.0;
  return h;
}

std::vector<Eigen::Vector2d> ImageCorners() {
  return {{-0.5, -0.5}, {kWidth - 0.5, -0.5}, {kWidth - 0.5, kHeight - 0.5}, {-0.5, kHeight - 0.5}};
}

struct Scene {
  std::vector<Eigen::Vector2d> source;  // noise-free, fixed over Monte Carlo trials
  std::vector<bool> outlier;
};

Scene MakeScene(int n, double outlier_fraction, Noise& noise) {
  Scene scene;
  for (int i = 0; i < n; ++i) {
    scene.source.emplace_back(noise.Uniform(0, kWidth), noise.Uniform(0, kHeight));
    scene.outlier.push_back(i < static_cast<int>(std::round(outlier_fraction * n)));
  }
  return scene;
}

// Noisy correspondences of `scene` under `h`: every point moves by sigma in both images;
// outliers go to a random place in the target image.
std::vector<Correspondence> Observe(const Scene& scene, const Eigen::Matrix3d& h, double sigma,
                                    Noise& noise) {
  std::vector<Correspondence> result;
  for (size_t i = 0; i < scene.source.size(); ++i) {
    Correspondence c;
    c.id = FeatureTrackId{static_cast<int64_t>(i)};
    c.source = scene.source[i] + noise.Gaussian2(sigma);
    const Eigen::Vector2d target =
        scene.outlier[i] ? Eigen::Vector2d(noise.Uniform(0, kWidth), noise.Uniform(0, kHeight))
                         : Transfer(h, scene.source[i]);
    c.target = target + noise.Gaussian2(sigma);
    result.push_back(c);
  }
  return result;
}

// Empirical mean and covariance of samples (columns).
template <int N>
struct Moments {
  Eigen::Matrix<double, N, 1> mean = Eigen::Matrix<double, N, 1>::Zero();
  Eigen::Matrix<double, N, N> cov = Eigen::Matrix<double, N, N>::Zero();
};
template <int N>
Moments<N> Empirical(const std::vector<Eigen::Matrix<double, N, 1>>& samples) {
  Moments<N> m;
  for (const auto& s : samples) m.mean += s;
  m.mean /= static_cast<double>(samples.size());
  for (const auto& s : samples) m.cov += (s - m.mean) * (s - m.mean).transpose();
  m.cov /= static_cast<double>(samples.size() - 1);
  return m;
}

// Each diagonal ratio empirical / predicted must lie within 1 +- tolerance.
template <int N>
void ExpectDiagonalsAgree(const Eigen::Matrix<double, N, N>& empirical,
                          const Eigen::Matrix<double, N, N>& predicted, double tolerance,
                          const char* what) {
  for (int i = 0; i < N; ++i) {
    const double ratio = empirical(i, i) / predicted(i, i);
    EXPECT_NEAR(ratio, 1.0, tolerance) << what << " variance " << i << ": empirical "
                                       << empirical(i, i) << ", predicted " << predicted(i, i);
  }
}

// Correlation coefficients must agree too, so a covariance with the right variances but the
// wrong shape does not pass.
template <int N>
void ExpectCorrelationsAgree(const Eigen::Matrix<double, N, N>& empirical,
                             const Eigen::Matrix<double, N, N>& predicted, double tolerance,
                             const char* what) {
  for (int i = 0; i < N; ++i) {
    for (int j = i + 1; j < N; ++j) {
      const double e = empirical(i, j) / std::sqrt(empirical(i, i) * empirical(j, j));
      const double p = predicted(i, j) / std::sqrt(predicted(i, i) * predicted(j, j));
      EXPECT_NEAR(e, p, tolerance) << what << " correlation " << i << "," << j;
    }
  }
}

HomographyOptions APrioriOptions(double sigma) {
  HomographyOptions options;
  options.measurement_sigma_px = sigma;
  options.noise_scale = NoiseScale::kAPriori;
  return options;
}

// --------------------------------------------------------------------------------------------
// Parameters and Jacobians.

TEST(HomographyParametersTest, OrderIsRowMajorWithoutH22) {
  Eigen::Matrix3d h;
  h << 2, 4, 6, 8, 10, 12, 14, 16, 2;
  const HomographyParameters p = ParametersFromHomography(h);
  HomographyParameters expected;
  expected << 1, 2, 3, 4, 5, 6, 7, 8;
  EXPECT_TRUE(p.isApprox(expected));
  EXPECT_TRUE(HomographyFromParameters(p).isApprox(h / 2));
}

TEST(HomographyJacobianTest, TransferJacobiansMatchCentralDifferences) {
  const Eigen::Matrix3d h = TruthHomography();
  for (const Eigen::Vector2d& p :
       {Eigen::Vector2d(0, 0), Eigen::Vector2d(1279, 5), Eigen::Vector2d(640.5, 711.25)}) {
    const Eigen::Matrix<double, 2, 8> analytic = TransferJacobian(h, p);
    const HomographyParameters theta = ParametersFromHomography(h);
    for (int k = 0; k < 8; ++k) {
      const double step = 1e-6 * std::max(std::abs(theta(k)), 1e-4);
      HomographyParameters plus = theta, minus = theta;
      plus(k) += step;
      minus(k) -= step;
      const Eigen::Vector2d numeric = (Transfer(HomographyFromParameters(plus), p) -
                                       Transfer(HomographyFromParameters(minus), p)) /
                                      (2 * step);
      EXPECT_NEAR((numeric - analytic.col(k)).norm(), 0.0, 1e-6 * (1 + numeric.norm()))
          << "parameter " << k;
    }
    const Eigen::Matrix2d a = TransferPointJacobian(h, p);
    for (int axis = 0; axis < 2; ++axis) {
      const Eigen::Vector2d d = 1e-4 * Eigen::Vector2d::Unit(axis);
      const Eigen::Vector2d numeric = (Transfer(h, p + d) - Transfer(h, p - d)) / 2e-4;
      EXPECT_NEAR((numeric - a.col(axis)).norm(), 0.0, 1e-8);
    }
  }
}

// A second homography, rather different, for the composition.
Eigen::Matrix3d OtherHomography() {
  Eigen::Matrix3d h;
  h << 0.95, -0.12, 40.0,  //
      0.10, 1.05, -22.0,   //
      -3.0e-5, 4.0e-5, 1.0;
  return h;
}

// Typical size of each parameter for a pixel image about 1000 px across: the linear part ~1,
// the shift ~1000 px, the perspective ~1/1000 px. Jacobians of parameters are compared in these
// units, so that entries of 1e6 and 1e-6 are held to the same relative accuracy.
HomographyParameters Scales() {
  HomographyParameters s;
  s << 1, 1, 1e3, 1, 1, 1e3, 1e-3, 1e-3;
  return s;
}

// Central differences of f: R^8 -> R^8 at x, in the units of Scales().
template <typename F>
Eigen::Matrix<double, 8, 8> NumericJacobian(const F& f, const HomographyParameters& x) {
  Eigen::Matrix<double, 8, 8> j;
  for (int k = 0; k < 8; ++k) {
    const double step = 1e-6 * Scales()(k);
    HomographyParameters plus = x, minus = x;
    plus(k) += step;
    minus(k) -= step;
    j.col(k) = (f(plus) - f(minus)) / (2 * step);
  }
  return j;
}

void ExpectJacobiansAgree(const Eigen::Matrix<double, 8, 8>& analytic,
                          const Eigen::Matrix<double, 8, 8>& numeric, const char* what) {
  const Eigen::Matrix<double, 8, 8> unit =
      Scales().cwiseInverse().asDiagonal() * (analytic - numeric) * Scales().asDiagonal();
  const Eigen::Matrix<double, 8, 8> size =
      Scales().cwiseInverse().asDiagonal() * numeric * Scales().asDiagonal();
  EXPECT_LT(unit.cwiseAbs().maxCoeff(), 1e-6 * (1 + size.cwiseAbs().maxCoeff()))
      << what << ": analytic\n"
      << analytic << "\nnumeric\n"
      << numeric;
}

TEST(HomographyJacobianTest, ComposeAndInverseJacobiansMatchCentralDifferences) {
  const Eigen::Matrix3d c = TruthHomography();
  const Eigen::Matrix3d b = OtherHomography();
  const Eigen::Matrix<double, 8, 16> analytic = ComposeJacobian(c, b);
  const HomographyParameters tc = ParametersFromHomography(c);
  const HomographyParameters tb = ParametersFromHomography(b);
  auto composed = [](const HomographyParameters& x, const HomographyParameters& y) {
    return ParametersFromHomography(HomographyFromParameters(x) * HomographyFromParameters(y));
  };
  ExpectJacobiansAgree(
      analytic.leftCols<8>(),
      NumericJacobian([&](const HomographyParameters& x) { return composed(x, tb); }, tc),
      "d(C B) / dC");
  ExpectJacobiansAgree(
      analytic.rightCols<8>(),
      NumericJacobian([&](const HomographyParameters& x) { return composed(tc, x); }, tb),
      "d(C B) / dB");
  ExpectJacobiansAgree(InverseJacobian(b),
                       NumericJacobian(
                           [](const HomographyParameters& x) {
                             return ParametersFromHomography(HomographyFromParameters(x).inverse());
                           },
                           tb),
                       "d(H^-1) / dH");
}

// --------------------------------------------------------------------------------------------
// Estimation.

TEST(EstimateHomographyTest, RecoversKnownHomographyDespiteThirtyPercentOutliers) {
  for (RobustMethod method : {RobustMethod::kMagsac, RobustMethod::kRansac}) {
    SCOPED_TRACE(method == RobustMethod::kMagsac ? "MAGSAC++" : "RANSAC");
    Noise noise(7);
    const Scene scene = MakeScene(500, 0.3, noise);
    const double sigma = 0.5;
    const std::vector<Correspondence> observed = Observe(scene, TruthHomography(), sigma, noise);
    HomographyOptions options;
    options.method = method;
    options.measurement_sigma_px = sigma;
    const auto start = std::chrono::steady_clock::now();
    const StatusOr<HomographyEstimate> estimate = EstimateHomography(observed, options);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    ASSERT_TRUE(estimate.ok()) << estimate.status().ToString();
    std::cout << "  500 correspondences, 30 % outliers: " << ms << " ms\n";

    // No outlier is kept, and all inliers are (|r| has a variance of about 2 sigma^2 per
    // coordinate; it exceeds the 3 px threshold with probability exp(-9) ~ 1e-4).
    int kept_outliers = 0;
    for (const Correspondence& c : estimate->inliers) {
      kept_outliers += scene.outlier[static_cast<size_t>(c.id)] ? 1 : 0;
    }
    EXPECT_EQ(kept_outliers, 0);
    EXPECT_GT(estimate->inliers.size(), 0.99 * 350);
    EXPECT_GE(estimate->ransac_inliers, 300);
    // Per-point residual: sigma^2 (1 + |A|^2) per coordinate, |A| ~ 1, so RMS ~ 2 sigma.
    EXPECT_NEAR(estimate->rms_px, 2 * sigma, 0.15 * 2 * sigma);
    EXPECT_NEAR(estimate->a_posteriori_sigma_px, sigma, 0.1 * sigma);
    EXPECT_DOUBLE_EQ(estimate->target_from_source(2, 2), 1.0);

    // Each corner within the 99.9 % ellipse of its own predicted covariance, and within a pixel.
    for (const Eigen::Vector2d& corner : ImageCorners()) {
      const Eigen::Vector2d error =
          Transfer(estimate->target_from_source, corner) - Transfer(TruthHomography(), corner);
      const Eigen::Matrix2d cov =
          TransferCovariance(estimate->target_from_source, estimate->covariance, corner);
      EXPECT_LT(error.dot(cov.ldlt().solve(error)), 13.8) << "corner " << corner.transpose();
      EXPECT_LT(error.norm(), 1.0);
    }
  }
}

TEST(EstimateHomographyTest, IsDeterministic) {
  Noise noise(3);
  const Scene scene = MakeScene(300, 0.3, noise);
  const std::vector<Correspondence> observed = Observe(scene, TruthHomography(), 0.7, noise);
  const auto a = EstimateHomography(observed, HomographyOptions{});
  const auto b = EstimateHomography(observed, HomographyOptions{});
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->target_from_source, b->target_from_source);
  EXPECT_EQ(a->covariance, b->covariance);
}

// The core claim: the predicted covariance is what repeated noise actually does. 1000 trials of
// 200 correspondences (30 % outliers, new noise each time, both images noisy); a variance
// estimate from 1000 samples has a relative standard deviation of 4.5 %, so 15 % is > 3 sigma.
TEST(EstimateHomographyTest, CovarianceMatchesMonteCarlo) {
  Noise noise(11);
  const Scene scene = MakeScene(200, 0.3, noise);
  const double sigma = 0.5;
  const HomographyOptions options = APrioriOptions(sigma);
  const int trials = 1000;
  std::vector<HomographyParameters> parameters;
  std::vector<std::vector<Eigen::Vector2d>> corners(4);
  HomographyCovariance predicted = HomographyCovariance::Zero();
  std::vector<Eigen::Matrix2d> corner_predicted(4, Eigen::Matrix2d::Zero());
  for (int t = 0; t < trials; ++t) {
    const auto estimate =
        EstimateHomography(Observe(scene, TruthHomography(), sigma, noise), options);
    ASSERT_TRUE(estimate.ok()) << estimate.status().ToString();
    parameters.push_back(ParametersFromHomography(estimate->target_from_source));
    predicted += estimate->covariance / trials;
    for (int c = 0; c < 4; ++c) {
      corners[c].push_back(Transfer(estimate->target_from_source, ImageCorners()[c]));
      corner_predicted[c] += TransferCovariance(estimate->target_from_source, estimate->covariance,
                                                ImageCorners()[c]) /
                             trials;
    }
  }
  const Moments<8> moments = Empirical<8>(parameters);
  std::cout << "  empirical / predicted parameter variance:";
  for (int k = 0; k < 8; ++k) std::cout << " " << moments.cov(k, k) / predicted(k, k);
  std::cout << "\n";
  ExpectDiagonalsAgree<8>(moments.cov, predicted, 0.15, "parameter");
  ExpectCorrelationsAgree<8>(moments.cov, predicted, 0.1, "parameter");
  // Unbiased to well within the spread.
  const HomographyParameters bias = moments.mean - ParametersFromHomography(TruthHomography());
  for (int k = 0; k < 8; ++k) EXPECT_LT(std::abs(bias(k)), 0.2 * std::sqrt(predicted(k, k)));

  for (int c = 0; c < 4; ++c) {
    const Moments<2> corner = Empirical<2>(corners[c]);
    ExpectDiagonalsAgree<2>(corner.cov, corner_predicted[c], 0.15, "corner");
    ExpectCorrelationsAgree<2>(corner.cov, corner_predicted[c], 0.1, "corner");
    std::cout << "  corner " << c << ": empirical sd " << std::sqrt(corner.cov(0, 0)) << ", "
              << std::sqrt(corner.cov(1, 1)) << " px; predicted "
              << std::sqrt(corner_predicted[c](0, 0)) << ", "
              << std::sqrt(corner_predicted[c](1, 1)) << " px\n";
  }
}

// Leaving out the source noise when the source points are as noisy as the target points halves
// the predicted variance (|A| ~ 1): the option matters and the Monte Carlo check can fail.
TEST(EstimateHomographyTest, IgnoringSourceNoiseUnderstatesTheCovariance) {
  Noise noise(5);
  const Scene scene = MakeScene(200, 0.0, noise);
  HomographyOptions options = APrioriOptions(0.8);
  options.count_source_noise = false;
  std::vector<HomographyParameters> parameters;
  HomographyCovariance predicted = HomographyCovariance::Zero();
  const int trials = 400;
  for (int t = 0; t < trials; ++t) {
    const auto estimate =
        EstimateHomography(Observe(scene, TruthHomography(), 0.8, noise), options);
    ASSERT_TRUE(estimate.ok());
    parameters.push_back(ParametersFromHomography(estimate->target_from_source));
    predicted += estimate->covariance / trials;
  }
  const Moments<8> moments = Empirical<8>(parameters);
  for (int k = 0; k < 8; ++k) EXPECT_NEAR(predicted(k, k) / moments.cov(k, k), 0.5, 0.12);
}

TEST(EstimateHomographyTest, NoiseScaleChoosesTheSigma) {
  Noise noise(13);
  const Scene scene = MakeScene(400, 0.1, noise);
  HomographyOptions options;
  options.ransac_threshold_px = 6;  // room for the 1.5 px noise
  options.measurement_sigma_px = 0.5;
  for (double truth_sigma : {0.2, 1.5}) {
    const std::vector<Correspondence> observed =
        Observe(scene, TruthHomography(), truth_sigma, noise);
    options.noise_scale = NoiseScale::kAPriori;
    const auto prior = EstimateHomography(observed, options);
    options.noise_scale = NoiseScale::kAPosteriori;
    const auto posterior = EstimateHomography(observed, options);
    options.noise_scale = NoiseScale::kLarger;
    const auto larger = EstimateHomography(observed, options);
    ASSERT_TRUE(prior.ok() && posterior.ok() && larger.ok());
    EXPECT_DOUBLE_EQ(prior->sigma_px, 0.5);
    EXPECT_NEAR(posterior->sigma_px, truth_sigma, 0.1 * truth_sigma);
    EXPECT_DOUBLE_EQ(larger->sigma_px, std::max(0.5, posterior->sigma_px));
    // The covariance scales with sigma^2, nothing else changes.
    const double ratio = posterior->covariance(2, 2) / prior->covariance(2, 2);
    EXPECT_NEAR(ratio, std::pow(posterior->sigma_px / 0.5, 2), 1e-6 * ratio);
  }
}

TEST(EstimateHomographyTest, FailuresAreStatuses) {
  HomographyOptions options;
  Noise noise(17);
  // Too few.
  const std::vector<Correspondence> few =
      Observe(MakeScene(6, 0, noise), TruthHomography(), 0.5, noise);
  EXPECT_EQ(EstimateHomography(few, options).status().code(), StatusCode::kInvalidData);
  // Collinear: all points on one line do not fix a homography.
  std::vector<Correspondence> line;
  for (int i = 0; i < 60; ++i) {
    const Eigen::Vector2d p(20.0 * i, 3.0 + 10.0 * i);
    line.push_back({FeatureTrackId{i}, p, Transfer(TruthHomography(), p)});
  }
  EXPECT_FALSE(EstimateHomography(line, options).ok());
  // All in one spot.
  std::vector<Correspondence> spot(50, Correspondence{FeatureTrackId{1}, {100, 100}, {110, 95}});
  EXPECT_FALSE(EstimateHomography(spot, options).ok());
  // Pure noise has no 15-point consensus at the 3 px threshold.
  Scene random = MakeScene(200, 1.0, noise);
  EXPECT_FALSE(EstimateHomography(Observe(random, TruthHomography(), 0.5, noise), options).ok());
  // Not finite.
  std::vector<Correspondence> nan = few;
  nan.resize(40, few.front());
  nan[3].target.x() = std::nan("");
  EXPECT_EQ(EstimateHomography(nan, options).status().code(), StatusCode::kInvalidData);
  // Bad options.
  HomographyOptions bad;
  bad.min_inliers = 4;
  EXPECT_EQ(bad.Validate().code(), StatusCode::kInvalidArgument);
  bad = HomographyOptions{};
  bad.measurement_sigma_px = 0;
  EXPECT_EQ(EstimateHomography(few, bad).status().code(), StatusCode::kInvalidArgument);
  bad = HomographyOptions{};
  bad.confidence = 1;
  EXPECT_FALSE(bad.Validate().ok());
  EXPECT_TRUE(HomographyOptions{}.Validate().ok());
}

// --------------------------------------------------------------------------------------------
// Propagation: composition and inversion against sampling.

// A realistic covariance: the estimate of TruthHomography from 120 points with 1 px noise.
HomographyCovariance RealisticCovariance(const Eigen::Matrix3d& h, uint64_t seed) {
  Noise noise(seed);
  const Scene scene = MakeScene(120, 0, noise);
  const auto estimate = EstimateHomography(Observe(scene, h, 1.0, noise), APrioriOptions(1.0));
  SAKER_CHECK(estimate.ok()) << estimate.status().ToString();
  return estimate->covariance;
}

TEST(HomographyPropagationTest, ComposeCovarianceMatchesSampling) {
  const Eigen::Matrix3d c_from_b = TruthHomography();
  const Eigen::Matrix3d b_from_a = OtherHomography();
  const HomographyCovariance cov_cb = RealisticCovariance(c_from_b, 21);
  const HomographyCovariance cov_ba = RealisticCovariance(b_from_a, 22);
  const auto composed = Compose(c_from_b, cov_cb, b_from_a, cov_ba);
  ASSERT_TRUE(composed.ok()) << composed.status().ToString();
  EXPECT_TRUE(
      composed->target_from_source.isApprox((c_from_b * b_from_a) / (c_from_b * b_from_a)(2, 2)));

  // 4000 samples: 2.2 % relative sd on a variance.
  Noise noise(23);
  std::vector<HomographyParameters> samples;
  std::vector<Eigen::Vector2d> corner;
  for (int s = 0; s < 4000; ++s) {
    const Eigen::Matrix3d cb =
        HomographyFromParameters(noise.Draw<8>(ParametersFromHomography(c_from_b), cov_cb));
    const Eigen::Matrix3d ba =
        HomographyFromParameters(noise.Draw<8>(ParametersFromHomography(b_from_a), cov_ba));
    samples.push_back(ParametersFromHomography(cb * ba));
    corner.push_back(Transfer(cb * ba, ImageCorners()[2]));
  }
  const Moments<8> moments = Empirical<8>(samples);
  ExpectDiagonalsAgree<8>(moments.cov, composed->covariance, 0.1, "composed");
  ExpectCorrelationsAgree<8>(moments.cov, composed->covariance, 0.05, "composed");
  const Moments<2> corner_moments = Empirical<2>(corner);
  ExpectDiagonalsAgree<2>(
      corner_moments.cov,
      TransferCovariance(composed->target_from_source, composed->covariance, ImageCorners()[2]),
      0.1, "composed corner");
}

TEST(HomographyPropagationTest, InverseCovarianceMatchesSampling) {
  const Eigen::Matrix3d h = OtherHomography();
  const HomographyCovariance cov = RealisticCovariance(h, 31);
  const auto inverse = Invert(h, cov);
  ASSERT_TRUE(inverse.ok()) << inverse.status().ToString();
  EXPECT_TRUE((inverse->target_from_source * h / (inverse->target_from_source * h)(2, 2))
                  .isApprox(Eigen::Matrix3d::Identity(), 1e-12));
  Noise noise(32);
  std::vector<HomographyParameters> samples;
  for (int s = 0; s < 4000; ++s) {
    const Eigen::Matrix3d draw =
        HomographyFromParameters(noise.Draw<8>(ParametersFromHomography(h), cov));
    samples.push_back(ParametersFromHomography(draw.inverse()));
  }
  const Moments<8> moments = Empirical<8>(samples);
  ExpectDiagonalsAgree<8>(moments.cov, inverse->covariance, 0.1, "inverse");
  ExpectCorrelationsAgree<8>(moments.cov, inverse->covariance, 0.05, "inverse");

  // Inverting twice gives back the covariance.
  const auto back = Invert(inverse->target_from_source, inverse->covariance);
  ASSERT_TRUE(back.ok());
  EXPECT_TRUE(back->covariance.isApprox(cov, 1e-8));
}

TEST(HomographyPropagationTest, ScaledInputsGiveTheSameCovariance) {
  // The covariances describe normalised parameters; a homography passed at another scale is the
  // same homography.
  const Eigen::Matrix3d h = TruthHomography();
  const HomographyCovariance cov = RealisticCovariance(h, 43);
  const auto composed = Compose(h, cov, h, cov);
  const auto scaled = Compose(2.0 * h, cov, -3.0 * h, cov);
  ASSERT_TRUE(composed.ok() && scaled.ok());
  EXPECT_TRUE(scaled->target_from_source.isApprox(composed->target_from_source, 1e-12));
  EXPECT_TRUE(scaled->covariance.isApprox(composed->covariance, 1e-9));
  const auto inverted = Invert(h, cov);
  const auto inverted_scaled = Invert(5.0 * h, cov);
  ASSERT_TRUE(inverted.ok() && inverted_scaled.ok());
  EXPECT_TRUE(inverted_scaled->covariance.isApprox(inverted->covariance, 1e-9));
}

TEST(HomographyPropagationTest, IdentityAndDegenerateCases) {
  const Eigen::Matrix3d h = TruthHomography();
  const HomographyCovariance cov = RealisticCovariance(h, 41);
  const auto left = Compose(Eigen::Matrix3d::Identity(), HomographyCovariance::Zero(), h, cov);
  ASSERT_TRUE(left.ok());
  EXPECT_TRUE(left->target_from_source.isApprox(h));
  EXPECT_TRUE(left->covariance.isApprox(cov, 1e-12));
  const auto right = Compose(h, cov, Eigen::Matrix3d::Identity(), HomographyCovariance::Zero());
  ASSERT_TRUE(right.ok());
  EXPECT_TRUE(right->covariance.isApprox(cov, 1e-12));

  Eigen::Matrix3d singular = h;
  singular.row(2) = singular.row(0) + singular.row(1);
  EXPECT_EQ(Invert(singular, cov).status().code(), StatusCode::kInvalidData);
  // The product sends the origin to infinity: (C B)(2,2) = 0.
  Eigen::Matrix3d b = Eigen::Matrix3d::Identity();
  b(0, 2) = 100;
  Eigen::Matrix3d c = Eigen::Matrix3d::Identity();
  c(2, 0) = -0.01;
  EXPECT_EQ(Compose(c, cov, b, cov).status().code(), StatusCode::kInvalidData);
}

TEST(HomographyPropagationTest, TransferCovarianceIsTheEllipse) {
  // With only a translation uncertain (h02, h12) every point moves alike: the ellipse is that
  // 2x2 block wherever the point is.
  HomographyCovariance cov = HomographyCovariance::Zero();
  cov(2, 2) = 4.0;
  cov(5, 5) = 1.0;
  cov(2, 5) = cov(5, 2) = 0.5;
  const Eigen::Matrix3d identity = Eigen::Matrix3d::Identity();
  for (const Eigen::Vector2d& p : ImageCorners()) {
    const Eigen::Matrix2d e = TransferCovariance(identity, cov, p);
    EXPECT_NEAR(e(0, 0), 4.0, 1e-12);
    EXPECT_NEAR(e(1, 1), 1.0, 1e-12);
    EXPECT_NEAR(e(0, 1), 0.5, 1e-12);
  }
}

// --------------------------------------------------------------------------------------------
// Fundamental matrix.

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d s;
  s << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return s;
}

struct TwoViews {
  Eigen::Matrix3d k;
  Eigen::Matrix3d r;  // x2 = r x1 + t in camera coordinates
  Eigen::Vector3d t;
  Eigen::Matrix3d fundamental() const {
    return k.inverse().transpose() * Skew(t) * r * k.inverse();
  }
  Eigen::Vector3d epipole_source() const { return k * (-r.transpose() * t); }
  Eigen::Vector3d epipole_target() const { return k * t; }
};

TwoViews MakeViews(const Eigen::Vector3d& t) {
  TwoViews v;
  v.k << 1000, 0, 640, 0, 1000, 360, 0, 0, 1;
  v.r = (Eigen::AngleAxisd(0.03, Eigen::Vector3d::UnitZ()) *
         Eigen::AngleAxisd(-0.02, Eigen::Vector3d::UnitX()))
            .toRotationMatrix();
  v.t = t;
  return v;
}

// Points of a 3-D scene (depth 30..90 m: buildings and ground) seen in both views.
std::vector<Correspondence> ObserveScene(const TwoViews& views, int n, double outlier_fraction,
                                         double sigma, Noise& noise, std::vector<bool>* outlier) {
  std::vector<Correspondence> result;
  outlier->clear();
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d ray =
        views.k.inverse() * Eigen::Vector3d(noise.Uniform(0, kWidth), noise.Uniform(0, kHeight), 1);
    const Eigen::Vector3d x1 = ray * noise.Uniform(30, 90);
    const Eigen::Vector3d x2 = views.r * x1 + views.t;
    Correspondence c;
    c.id = FeatureTrackId{i};
    c.source = (views.k * x1).hnormalized() + noise.Gaussian2(sigma);
    c.target = (views.k * x2).hnormalized() + noise.Gaussian2(sigma);
    const bool is_outlier = i < static_cast<int>(outlier_fraction * n);
    if (is_outlier) c.target = {noise.Uniform(0, kWidth), noise.Uniform(0, kHeight)};
    outlier->push_back(is_outlier);
    result.push_back(c);
  }
  return result;
}

double Angle(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::min(1.0, std::abs(a.normalized().dot(b.normalized()))));
}

TEST(EstimateFundamentalTest, RecoversEpipolarGeometryOfA3dScene) {
  for (RobustMethod method : {RobustMethod::kRansac, RobustMethod::kMagsac}) {
    SCOPED_TRACE(method == RobustMethod::kMagsac ? "MAGSAC++" : "RANSAC");
    const TwoViews views = MakeViews({2.0, 0.5, 1.0});
    Noise noise(51);
    std::vector<bool> outlier;
    const std::vector<Correspondence> observed =
        ObserveScene(views, 300, 0.2, 0.3, noise, &outlier);
    FundamentalOptions options;
    options.method = method;
    const auto estimate = EstimateFundamental(observed, options);
    ASSERT_TRUE(estimate.ok()) << estimate.status().ToString();
    ASSERT_EQ(estimate->inliers.size(), observed.size());
    int kept_outliers = 0;
    int found = 0;
    for (size_t i = 0; i < observed.size(); ++i) {
      if (!estimate->inliers[i]) continue;
      ++found;
      if (outlier[i]) {
        // A random outlier can fall on its epipolar line by chance; then it fits.
        ++kept_outliers;
        EXPECT_LE(SampsonDistance(estimate->fundamental, observed[i].source, observed[i].target),
                  1.0);
      }
    }
    EXPECT_EQ(found, estimate->inlier_count);
    EXPECT_LE(kept_outliers, 3);
    EXPECT_GE(estimate->inlier_count, 0.9 * 240);
    EXPECT_NEAR(estimate->fundamental.norm(), 1.0, 1e-12);
    EXPECT_LT(std::abs(estimate->fundamental.determinant()), 1e-12);

    // Noise-free pairs of new scene points lie on the estimated epipolar lines.
    Noise clean_noise(52);
    std::vector<bool> unused;
    double sum = 0;
    const std::vector<Correspondence> clean = ObserveScene(views, 200, 0, 0, clean_noise, &unused);
    for (const Correspondence& c : clean) {
      EXPECT_NEAR(SampsonDistance(views.fundamental(), c.source, c.target), 0.0, 1e-9);
      sum += SampsonDistance(estimate->fundamental, c.source, c.target);
    }
    EXPECT_LT(sum / clean.size(), 0.15);
    // The epipoles (here in the image plane, finite) within a fraction of a degree of direction.
    EXPECT_LT(Angle(estimate->epipole_source, views.epipole_source()), 2e-3);
    EXPECT_LT(Angle(estimate->epipole_target, views.epipole_target()), 2e-3);
    EXPECT_GT(estimate->epipole_source.z(), 0);
    EXPECT_NEAR((estimate->fundamental * estimate->epipole_source).norm(), 0.0, 1e-12);
    EXPECT_NEAR((estimate->fundamental.transpose() * estimate->epipole_target).norm(), 0.0, 1e-12);
  }
}

TEST(EstimateFundamentalTest, EpipoleAtInfinityForSidewaysMotion) {
  TwoViews views = MakeViews({3.0, 0.0, 0.0});
  views.r = Eigen::Matrix3d::Identity();
  Noise noise(61);
  std::vector<bool> outlier;
  const auto estimate =
      EstimateFundamental(ObserveScene(views, 200, 0.1, 0.2, noise, &outlier), {});
  ASSERT_TRUE(estimate.ok()) << estimate.status().ToString();
  // Horizontal epipolar lines: the epipole is the point at infinity along x.
  EXPECT_LT(std::abs(estimate->epipole_source.z()), 1e-4);
  EXPECT_NEAR(std::abs(estimate->epipole_source.x()), 1.0, 1e-6);
  EXPECT_LT(std::abs(estimate->epipole_target.z()), 1e-4);
}

TEST(SampsonDistanceTest, KnownValues) {
  // Sideways translation: F = [x]_cross, epipolar constraint y' = y. The nearest consistent pair
  // moves both y by half the gap, so the distance is |y - y'| / sqrt(2).
  const Eigen::Matrix3d f = Skew(Eigen::Vector3d::UnitX());
  EXPECT_NEAR(SampsonDistance(f, {10, 20}, {300, 23}), 3 / std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(SampsonDistance(f, {10, 20}, {-40, 20}), 0.0, 1e-12);
  EXPECT_NEAR(SampsonDistance(7.5 * f, {10, 20}, {300, 23}), 3 / std::sqrt(2.0), 1e-12);
}

TEST(EstimateFundamentalTest, FailuresAreStatuses) {
  Noise noise(71);
  std::vector<bool> outlier;
  const TwoViews views = MakeViews({1, 0, 0});
  EXPECT_EQ(
      EstimateFundamental(ObserveScene(views, 10, 0, 0.2, noise, &outlier), {}).status().code(),
      StatusCode::kInvalidData);
  FundamentalOptions bad;
  bad.min_inliers = 7;
  EXPECT_EQ(bad.Validate().code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(FundamentalOptions{}.Validate().ok());
}

}  // namespace
}  // namespace saker::track
