#include "core/mosaic/chain_solver.h"

#include "core/mosaic/adjustment.h"
#include "core/mosaic/link_graph.h"
#include "core/mosaic/mosaic_builder.h"
#include "core/mosaic/residuals.h"
#include "core/track/homography.h"
#include "core/track/image_geometry.h"
#include "core/util/check.h"
#include "tests/core/mosaic/synthetic_camera.h"
#include "tests/testing/noise.h"

#include <Eigen/Dense>
#include <ceres/ceres.h>
#include <ceres/covariance.h>
#include <ceres/jet.h>
#include <ceres/manifold.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace saker::mosaic {
namespace {

using saker::testing::Noise;
using testing_support::GroundFromImage;
using testing_support::Normalised;

using Matrix8 = Eigen::Matrix<double, 8, 8>;
using Vector8 = Eigen::Matrix<double, 8, 1>;
using Parameters = std::array<double, 8>;

constexpr int kWidth = testing_support::SyntheticCamera{}.width;
constexpr int kHeight = testing_support::SyntheticCamera{}.height;

// `frames` video frames of a camera flying `step_m` metres per frame (1.6 m: 40 m/s at 25 frames
// per second, about 10 px at 0.156 m/px) along a curve, its heading turning out to `turn_rad` and
// back, pitching and rolling a little.
std::vector<Eigen::Matrix3d> CurvedFlight(int frames, double step_m, double turn_rad) {
  std::vector<Eigen::Matrix3d> truth;
  double x = 0, y = 0;
  for (int k = 0; k < frames; ++k) {
    const double s = static_cast<double>(k) / std::max(1, frames - 1);
    const double heading = turn_rad * std::sin(M_PI * s);
    truth.push_back(
        GroundFromImage(x, y, heading, 0.03 * std::sin(0.05 * k), 0.02 * std::cos(0.031 * k)));
    x += step_m * std::cos(heading);
    y += step_m * std::sin(heading);
  }
  return truth;
}

// A random, correlated covariance of the 8 measured corner coordinates of a step, with an average
// per-coordinate sigma of about sigma_px.
Matrix8 CornerCovariance(double sigma_px, Noise& noise) {
  Matrix8 b;
  for (int i = 0; i < 64; ++i) b(i) = noise.Gaussian();
  return sigma_px * sigma_px * (0.6 * Matrix8::Identity() + 0.4 / 8 * b * b.transpose());
}

// The step k -> k + 1 of the truth, its corners moved by N(0, corner_cov) (none without noise)
// and fitted exactly; its stated covariance the one that noise implies, C = J^-1 S J^-T, so the
// noise is drawn with the step's own covariance.
ChainStep MeasureStep(const std::vector<Eigen::Matrix3d>& truth, size_t k, double sigma_px,
                      Noise& noise, bool noisy) {
  const Matrix8 corner_cov = CornerCovariance(sigma_px, noise);
  const Eigen::Matrix3d exact = Normalised(truth[k + 1].inverse() * truth[k]);
  const auto corners = track::ImageCorners(kWidth, kHeight);
  const Vector8 error = noisy ? noise.Draw<8>(corner_cov) : Vector8::Zero();
  std::array<Eigen::Vector2d, 4> measured;
  for (int i = 0; i < 4; ++i) {
    measured[static_cast<size_t>(i)] =
        track::Transfer(exact, corners[static_cast<size_t>(i)]) + error.segment<2>(2 * i);
  }
  const auto fitted = track::HomographyFromCorners(corners, measured, 1.0);
  SAKER_CHECK(fitted.ok()) << fitted.status().ToString();
  ChainStep step;
  step.next_from_previous = fitted->target_from_source;
  Matrix8 j;
  for (int i = 0; i < 4; ++i) {
    j.middleRows<2>(2 * i) =
        track::TransferJacobian(step.next_from_previous, corners[static_cast<size_t>(i)]);
  }
  const Matrix8 j_inv = j.inverse();
  step.covariance = j_inv * corner_cov * j_inv.transpose();
  step.covariance = 0.5 * (step.covariance + step.covariance.transpose()).eval();
  return step;
}

std::vector<ChainStep> MeasureChain(const std::vector<Eigen::Matrix3d>& truth, double sigma_px,
                                    uint64_t seed, bool noisy = true) {
  Noise noise(seed);
  std::vector<ChainStep> steps;
  for (size_t k = 0; k + 1 < truth.size(); ++k) {
    steps.push_back(MeasureStep(truth, k, sigma_px, noise, noisy));
  }
  return steps;
}

// map_from_{k+1} = map_from_k * next_from_previous_k^-1 from map_from_0 = first.
std::vector<Eigen::Matrix3d> Chained(const Eigen::Matrix3d& first,
                                     const std::vector<ChainStep>& steps) {
  std::vector<Eigen::Matrix3d> chained = {first};
  for (const ChainStep& s : steps) {
    chained.push_back(Normalised(chained.back() * s.next_from_previous.inverse()));
  }
  return chained;
}

// The largest distance, in frame pixels, between where `estimate` and `reference` put the image
// corners of a frame (estimate^-1 reference applied to the corners).
double CornerDifferencePx(const Eigen::Matrix3d& reference, const Eigen::Matrix3d& estimate) {
  const Eigen::Matrix3d e = estimate.inverse() * reference;
  double worst = 0;
  for (const Eigen::Vector2d& c : track::ImageCorners(kWidth, kHeight)) {
    worst = std::max(worst, (track::Transfer(e, c) - c).norm());
  }
  return worst;
}

// RMS over the corners, in frame pixels, of the same difference.
double CornerRmsPx(const Eigen::Matrix3d& reference, const Eigen::Matrix3d& estimate) {
  const Eigen::Matrix3d e = estimate.inverse() * reference;
  double sum = 0;
  for (const Eigen::Vector2d& c : track::ImageCorners(kWidth, kHeight)) {
    sum += (track::Transfer(e, c) - c).squaredNorm();
  }
  return std::sqrt(sum / 4);
}

Parameters ParametersOf(const Eigen::Matrix3d& h) {
  const track::HomographyParameters p = track::ParametersFromHomography(h);
  Parameters a;
  for (int i = 0; i < 8; ++i) a[static_cast<size_t>(i)] = p(i);
  return a;
}

Eigen::Matrix3d MatrixOf(const Parameters& p) {
  return track::HomographyFromParameters(Eigen::Map<const track::HomographyParameters>(p.data()));
}

// The reference: the same residuals (internal::LinkResidual, whitened as SolveChain does) and the
// same manifold in a ceres::Problem, both ends constant, started from the chained product,
// Levenberg-Marquardt to tight tolerances.
class CeresChain {
 public:
  CeresChain(const Eigen::Matrix3d& first, const Eigen::Matrix3d& last,
             const std::vector<ChainStep>& steps,
             double floor_px = ChainOptions().min_link_sigma_px)
      : manifold_(new ceres::AutoDiffManifold<internal::HomographyStep, 8, 8>(
            new internal::HomographyStep(internal::HomographyStep::ForImage(kWidth, kHeight)))) {
    ceres::Problem::Options options;
    options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    problem_ = std::make_unique<ceres::Problem>(options);
    const std::vector<Eigen::Matrix3d> chained = Chained(first, steps);
    for (const Eigen::Matrix3d& m : chained) frames_.push_back(ParametersOf(m));
    frames_.back() = ParametersOf(last);
    const auto corners = track::ImageCorners(kWidth, kHeight);
    for (size_t i = 0; i < steps.size(); ++i) {
      problem_->AddResidualBlock(
          new ceres::AutoDiffCostFunction<internal::LinkResidual, 8, 8, 8>(
              new internal::LinkResidual(internal::MakeLinkResidual(
                  steps[i].next_from_previous, steps[i].covariance, corners, floor_px))),
          nullptr, frames_[i].data(), frames_[i + 1].data());
    }
    for (Parameters& p : frames_) problem_->SetManifold(p.data(), manifold_.get());
    problem_->SetParameterBlockConstant(frames_.front().data());
    problem_->SetParameterBlockConstant(frames_.back().data());
  }

  void Solve(bool sparse = false) {
    ceres::Solver::Options options;
    options.linear_solver_type = sparse ? ceres::SPARSE_NORMAL_CHOLESKY : ceres::DENSE_QR;
    options.max_num_iterations = 500;
    options.function_tolerance = 1e-16;
    options.gradient_tolerance = 1e-16;
    options.parameter_tolerance = 1e-16;
    options.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(options, problem_.get(), &summary);
    ASSERT_TRUE(summary.IsSolutionUsable()) << summary.BriefReport();
    std::printf("  ceres: %s\n", summary.BriefReport().c_str());
    final_cost_ = summary.final_cost;
  }

  // Ceres's covariance of frame k's 8 parameters at the current frames (set with Set).
  Matrix8 Covariance(size_t k) {
    ceres::Covariance::Options options;
    options.algorithm_type = ceres::DENSE_SVD;
    ceres::Covariance covariance(options);
    std::vector<std::pair<const double*, const double*>> blocks = {
        {frames_[k].data(), frames_[k].data()}};
    SAKER_CHECK(covariance.Compute(blocks, problem_.get()));
    Eigen::Matrix<double, 8, 8, Eigen::RowMajor> block;
    SAKER_CHECK(covariance.GetCovarianceBlock(frames_[k].data(), frames_[k].data(), block.data()));
    return block;
  }

  Eigen::Matrix3d Frame(size_t k) const { return MatrixOf(frames_[k]); }
  void Set(size_t k, const Eigen::Matrix3d& m) { frames_[k] = ParametersOf(m); }
  double final_cost() const { return final_cost_; }

 private:
  std::unique_ptr<ceres::Manifold> manifold_;
  std::vector<Parameters> frames_;  // never resized after setup
  std::unique_ptr<ceres::Problem> problem_;
  double final_cost_ = 0;
};

// 1. Noise-free steps consistent with both ends: the truth, exactly, and no residual left.
TEST(ChainSolverTest, NoiseFreeStepsRecoverTheTruth) {
  const std::vector<Eigen::Matrix3d> truth = CurvedFlight(41, 1.6, 0.8);
  const std::vector<ChainStep> steps = MeasureChain(truth, 0.5, 1, /*noisy=*/false);
  const StatusOr<ChainSolution> solution =
      SolveChain(truth.front(), truth.back(), steps, kWidth, kHeight);
  ASSERT_TRUE(solution.ok()) << solution.status().ToString();
  ASSERT_EQ(solution->map_from_frame.size(), truth.size());
  double worst = 0;
  for (size_t k = 0; k < truth.size(); ++k) {
    EXPECT_NEAR(solution->map_from_frame[k](2, 2), 1.0, 1e-15);
    worst = std::max(worst, CornerDifferencePx(truth[k], solution->map_from_frame[k]));
  }
  std::printf("  worst corner error %.3g px, cost %.3g, %d iterations\n", worst,
              solution->final_cost, solution->iterations);
  EXPECT_LT(worst, 1e-6);
  EXPECT_LT(solution->final_cost, 1e-12);
  EXPECT_TRUE(solution->covariances.empty());  // not requested
}

// 2. A noisy chain: the linear-time solution is Ceres's, to 1e-4 px at every corner.
TEST(ChainSolverTest, NoisyChainEqualsCeresReference) {
  const std::vector<Eigen::Matrix3d> truth = CurvedFlight(31, 1.6, 0.6);
  const std::vector<ChainStep> steps = MeasureChain(truth, 0.5, 2);
  const StatusOr<ChainSolution> solution =
      SolveChain(truth.front(), truth.back(), steps, kWidth, kHeight);
  ASSERT_TRUE(solution.ok()) << solution.status().ToString();
  CeresChain reference(truth.front(), truth.back(), steps);
  reference.Solve();
  double worst = 0;
  for (size_t k = 0; k < truth.size(); ++k) {
    worst = std::max(worst, CornerDifferencePx(reference.Frame(k), solution->map_from_frame[k]));
  }
  const double closure = CornerDifferencePx(truth.back(), Chained(truth.front(), steps).back());
  std::printf(
      "  chained closure error %.2f px; SolveChain vs Ceres: worst corner %.3g px; cost %.6g -> "
      "%.10g (Ceres %.10g), %d iterations\n",
      closure, worst, solution->initial_cost, solution->final_cost, reference.final_cost(),
      solution->iterations);
  EXPECT_LT(worst, 1e-4);
  EXPECT_NEAR(solution->final_cost, reference.final_cost(), 1e-8 * reference.final_cost());
  EXPECT_GT(solution->initial_cost, solution->final_cost);
  EXPECT_GE(solution->iterations, 1);
  EXPECT_LE(solution->iterations, 4);
  // The ends are copied bit for bit.
  EXPECT_EQ(solution->map_from_frame.front(), truth.front());
  EXPECT_EQ(solution->map_from_frame.back(), truth.back());
}

// 3. Covariances: Ceres's Covariance (dense SVD of the whole Jacobian, the same manifold) at the
// solution, frame by frame.
TEST(ChainSolverTest, CovariancesEqualCeresCovariance) {
  const std::vector<Eigen::Matrix3d> truth = CurvedFlight(9, 1.6, 0.5);
  const std::vector<ChainStep> steps = MeasureChain(truth, 0.5, 3);
  ChainOptions options;
  options.covariances = true;
  const StatusOr<ChainSolution> solution =
      SolveChain(truth.front(), truth.back(), steps, kWidth, kHeight, options);
  ASSERT_TRUE(solution.ok()) << solution.status().ToString();
  ASSERT_EQ(solution->covariances.size(), truth.size());
  EXPECT_EQ(solution->covariances.front(), Matrix8::Zero());
  EXPECT_EQ(solution->covariances.back(), Matrix8::Zero());
  CeresChain reference(truth.front(), truth.back(), steps);
  for (size_t k = 1; k + 1 < truth.size(); ++k) reference.Set(k, solution->map_from_frame[k]);
  double worst = 0;
  for (size_t k = 1; k + 1 < truth.size(); ++k) {
    const Matrix8 expected = reference.Covariance(k);
    const Matrix8& actual = solution->covariances[k];
    // Parameters differ by orders of magnitude (pixels against per pixel): compare after scaling
    // each to unit variance.
    const Vector8 scale = expected.diagonal().cwiseSqrt().cwiseInverse();
    const double relative =
        (scale.asDiagonal() * (actual - expected) * scale.asDiagonal()).cwiseAbs().maxCoeff();
    worst = std::max(worst, relative);
    EXPECT_LT(relative, 1e-6) << "frame " << k;
    EXPECT_TRUE(actual.isApprox(actual.transpose(), 1e-12)) << "frame " << k;
  }
  std::printf("  worst relative covariance difference %.3g\n", worst);

  // The middle frame is the least certain: a corner's predicted std grows away from both ends.
  const auto corner_variance = [&](size_t k) {
    return track::TransferCovariance(solution->map_from_frame[k], solution->covariances[k],
                                     Eigen::Vector2d(0, 0))
        .trace();
  };
  EXPECT_LT(corner_variance(1), corner_variance(4));
  EXPECT_LT(corner_variance(7), corner_variance(4));
}

// 3b. One end fixed: the covariances are NodeCovariances' on the same chain as a link graph (its
// gauge: node 0 fixed), so the convention is the same.
TEST(ChainSolverTest, OneEndCovariancesEqualNodeCovariances) {
  const std::vector<Eigen::Matrix3d> truth = CurvedFlight(12, 1.6, 0.5);
  const std::vector<ChainStep> steps = MeasureChain(truth, 0.5, 4);
  ChainOptions options;
  options.covariances = true;
  const StatusOr<ChainSolution> solution =
      SolveChain(truth.front(), std::nullopt, steps, kWidth, kHeight, options);
  ASSERT_TRUE(solution.ok()) << solution.status().ToString();

  LinkGraph graph;
  graph.image_width = kWidth;
  graph.image_height = kHeight;
  graph.geo_referenced = true;
  for (size_t k = 0; k < truth.size(); ++k) {
    Node node;
    node.id = static_cast<KeyFrameId>(static_cast<int>(k));
    node.map_from_frame = solution->map_from_frame[k];
    graph.nodes.push_back(node);
  }
  for (size_t k = 0; k < steps.size(); ++k) {
    Link link;
    link.from = static_cast<KeyFrameId>(static_cast<int>(k));
    link.to = static_cast<KeyFrameId>(static_cast<int>(k) + 1);
    link.to_from_from = steps[k].next_from_previous;
    link.covariance = steps[k].covariance;
    graph.links.push_back(link);
  }
  AdjustmentOptions adjustment;
  adjustment.loss_scale = 0;
  const StatusOr<std::vector<track::HomographyCovariance>> expected =
      NodeCovariances(graph, adjustment);
  ASSERT_TRUE(expected.ok()) << expected.status().ToString();
  ASSERT_EQ(solution->covariances.size(), expected->size());
  EXPECT_EQ(solution->covariances[0], Matrix8::Zero());
  for (size_t k = 1; k < truth.size(); ++k) {
    const Matrix8& e = (*expected)[k];
    const Vector8 scale = e.diagonal().cwiseSqrt().cwiseInverse();
    const double relative =
        (scale.asDiagonal() * (solution->covariances[k] - e) * scale.asDiagonal())
            .cwiseAbs()
            .maxCoeff();
    EXPECT_LT(relative, 1e-6) << "frame " << k;
  }
  // Uncertainty grows along the chain.
  EXPECT_LT(solution->covariances[3].trace(), solution->covariances[11].trace());
}

// 4. A long noisy chain (300 steps, tens of pixels of closure error): both ends fixed is clearly
// better than forward chaining, and its error is largest towards the middle, not at the ends.
TEST(ChainSolverTest, BothEndsBeatForwardChainingOnALongChain) {
  constexpr int kSteps = 300;
  const std::vector<Eigen::Matrix3d> truth = CurvedFlight(kSteps + 1, 1.6, 1.0);
  const std::vector<ChainStep> steps = MeasureChain(truth, 0.5, 1);
  ChainOptions options;
  options.covariances = true;
  const StatusOr<ChainSolution> solution =
      SolveChain(truth.front(), truth.back(), steps, kWidth, kHeight, options);
  ASSERT_TRUE(solution.ok()) << solution.status().ToString();
  const std::vector<Eigen::Matrix3d> chained = Chained(truth.front(), steps);

  double sum_solved = 0, sum_chained = 0, worst = 0, predicted_worst = 0;
  size_t worst_frame = 0, predicted_worst_frame = 0;
  for (size_t k = 1; k < static_cast<size_t>(kSteps); ++k) {
    const double solved = CornerRmsPx(truth[k], solution->map_from_frame[k]);
    sum_solved += solved * solved;
    const double c = CornerRmsPx(truth[k], chained[k]);
    sum_chained += c * c;
    if (solved > worst) {
      worst = solved;
      worst_frame = k;
    }
    const double predicted =
        track::TransferCovariance(solution->map_from_frame[k], solution->covariances[k],
                                  Eigen::Vector2d(0, 0))
            .trace();
    if (predicted > predicted_worst) {
      predicted_worst = predicted;
      predicted_worst_frame = k;
    }
  }
  const double rms_solved = std::sqrt(sum_solved / (kSteps - 1));
  const double rms_chained = std::sqrt(sum_chained / (kSteps - 1));
  const double closure = CornerDifferencePx(truth.back(), chained.back());
  // Mean error next to the ends (first and last 5 %) and in the middle third.
  const auto mean_error = [&](size_t begin, size_t end) {
    double sum = 0;
    for (size_t k = begin; k < end; ++k) sum += CornerRmsPx(truth[k], solution->map_from_frame[k]);
    return sum / static_cast<double>(end - begin);
  };
  const double near_ends = 0.5 * (mean_error(1, 16) + mean_error(kSteps - 15, kSteps));
  const double middle = mean_error(kSteps / 3, 2 * kSteps / 3);
  std::printf(
      "  closure error of the chained product %.1f px; RMS corner error chained %.2f px, solved "
      "%.2f px; worst solved %.2f px at frame %zu (predicted std largest at %zu); near the ends "
      "%.2f px, middle third %.2f px; %d iterations, cost %.4g -> %.4g\n",
      closure, rms_chained, rms_solved, worst, worst_frame, predicted_worst_frame, near_ends,
      middle, solution->iterations, solution->initial_cost, solution->final_cost);
  EXPECT_GT(closure, 10);  // a realistic drift, tens of pixels
  EXPECT_LT(rms_solved, 0.5 * rms_chained);
  EXPECT_GT(worst_frame, static_cast<size_t>(kSteps / 10));
  EXPECT_LT(worst_frame, size_t(9 * kSteps / 10));
  EXPECT_GT(middle, 2 * near_ends);
  EXPECT_GT(predicted_worst_frame, size_t(2 * kSteps / 5));
  EXPECT_LT(predicted_worst_frame, size_t(3 * kSteps / 5));
  EXPECT_LE(solution->iterations, 4);
}

// A chain long enough (1200 steps, closure error in the hundreds of pixels) for the start to come
// from the coarse chain (steps composed 16 at a time): still Ceres's solution.
TEST(ChainSolverTest, LongChainFromTheCoarseStartEqualsCeres) {
  constexpr int kSteps = 1200;
  const std::vector<Eigen::Matrix3d> truth = CurvedFlight(kSteps + 1, 1.6, 1.5);
  const std::vector<ChainStep> steps = MeasureChain(truth, 0.3, 10);
  const StatusOr<ChainSolution> solution =
      SolveChain(truth.front(), truth.back(), steps, kWidth, kHeight);
  ASSERT_TRUE(solution.ok()) << solution.status().ToString();
  CeresChain reference(truth.front(), truth.back(), steps);
  reference.Solve(/*sparse=*/true);
  double worst = 0;
  for (size_t k = 0; k < truth.size(); ++k) {
    worst = std::max(worst, CornerDifferencePx(reference.Frame(k), solution->map_from_frame[k]));
  }
  const double closure = CornerDifferencePx(truth.back(), Chained(truth.front(), steps).back());
  std::printf(
      "  chained closure error %.1f px; SolveChain vs Ceres: worst corner %.3g px; cost %.6g -> "
      "%.10g (Ceres %.10g), %d iterations\n",
      closure, worst, solution->initial_cost, solution->final_cost, reference.final_cost(),
      solution->iterations);
  EXPECT_GT(closure, 100);
  EXPECT_LT(worst, 1e-3);
  EXPECT_LE(solution->final_cost, reference.final_cost() * (1 + 1e-9));
  EXPECT_LE(solution->iterations, 3);
}

// 5. One end only: the chained product, nothing solved.
TEST(ChainSolverTest, OneEndIsTheChainedProduct) {
  const std::vector<Eigen::Matrix3d> truth = CurvedFlight(51, 1.6, 0.7);
  const std::vector<ChainStep> steps = MeasureChain(truth, 0.5, 6);
  const StatusOr<ChainSolution> solution =
      SolveChain(truth.front(), std::nullopt, steps, kWidth, kHeight);
  ASSERT_TRUE(solution.ok()) << solution.status().ToString();
  const std::vector<Eigen::Matrix3d> chained = Chained(truth.front(), steps);
  ASSERT_EQ(solution->map_from_frame.size(), chained.size());
  EXPECT_EQ(solution->map_from_frame.front(), truth.front());
  for (size_t k = 0; k < chained.size(); ++k) {
    EXPECT_LT(CornerDifferencePx(chained[k], solution->map_from_frame[k]), 1e-9) << "frame " << k;
  }
  EXPECT_EQ(solution->iterations, 0);
  EXPECT_LT(solution->final_cost, 1e-12);
  EXPECT_EQ(solution->initial_cost, solution->final_cost);
}

// The analytic Jacobians of the shared link residual and the step's Jacobian against automatic
// differentiation (ceres::Jet) of the templated residual and HomographyStep::Plus.
TEST(ChainSolverTest, AnalyticJacobiansMatchAutomaticDifferentiation) {
  using Jet = ceres::Jet<double, 16>;
  const std::vector<Eigen::Matrix3d> truth = CurvedFlight(8, 1.6, 0.5);
  const std::vector<ChainStep> steps = MeasureChain(truth, 0.5, 7);
  const internal::HomographyStep step = internal::HomographyStep::ForImage(kWidth, kHeight);
  const internal::LinkResidual link = internal::MakeLinkResidual(
      steps[4].next_from_previous, steps[4].covariance, track::ImageCorners(kWidth, kHeight), 0.05);
  // Off the solution, in a map far from the origin, so that no term vanishes.
  Eigen::Matrix3d shift;
  shift << 1, 0, 3000, 0, 1, -2000, 0, 0, 1;
  const Parameters from = ParametersOf(shift * truth[4]);
  Parameters to;
  const Vector8 nudge =
      (Vector8() << 0.01, -0.02, 0.03, 0.015, -0.01, -0.02, 0.005, 0.01).finished();
  ASSERT_TRUE(step.Plus(ParametersOf(shift * truth[5]).data(), nudge.data(), to.data()));

  Eigen::Matrix<double, 8, 1> residual;
  Eigen::Matrix<double, 8, 8> d_from, d_to;
  ASSERT_TRUE(internal::LinkResidualJacobians(link, step, from.data(), to.data(), &residual,
                                              &d_from, &d_to));

  std::array<Jet, 8> from_jet, to_jet, zero_from, zero_to, from_plus, to_plus, residual_jet;
  for (int i = 0; i < 8; ++i) {
    from_jet[static_cast<size_t>(i)] = Jet(from[static_cast<size_t>(i)]);
    to_jet[static_cast<size_t>(i)] = Jet(to[static_cast<size_t>(i)]);
    zero_from[static_cast<size_t>(i)] = Jet(0, i);
    zero_to[static_cast<size_t>(i)] = Jet(0, 8 + i);
  }
  ASSERT_TRUE(step.Plus(from_jet.data(), zero_from.data(), from_plus.data()));
  ASSERT_TRUE(step.Plus(to_jet.data(), zero_to.data(), to_plus.data()));
  ASSERT_TRUE(link(from_plus.data(), to_plus.data(), residual_jet.data()));
  for (int r = 0; r < 8; ++r) {
    EXPECT_NEAR(residual(r), residual_jet[static_cast<size_t>(r)].a,
                1e-9 * (1 + std::abs(residual(r))));
    for (int c = 0; c < 8; ++c) {
      const double f = residual_jet[static_cast<size_t>(r)].v(c),
                   t = residual_jet[static_cast<size_t>(r)].v(8 + c);
      EXPECT_NEAR(d_from(r, c), f, 1e-8 * (1 + std::abs(f))) << r << "," << c;
      EXPECT_NEAR(d_to(r, c), t, 1e-8 * (1 + std::abs(t))) << r << "," << c;
    }
  }

  const Matrix8 plus = step.PlusJacobian(from.data());
  for (int r = 0; r < 8; ++r) {
    for (int c = 0; c < 8; ++c) {
      const double expected = from_plus[static_cast<size_t>(r)].v(c);
      EXPECT_NEAR(plus(r, c), expected, 1e-10 * (1 + std::abs(expected))) << r << "," << c;
    }
  }
}

// 6. Bad inputs: errors, never a crash.
TEST(ChainSolverTest, RejectsBadOptionsAndInputs) {
  const std::vector<Eigen::Matrix3d> truth = CurvedFlight(11, 1.6, 0.5);
  const std::vector<ChainStep> steps = MeasureChain(truth, 0.5, 8);
  const Eigen::Matrix3d first = truth.front(), last = truth.back();
  const double nan = std::numeric_limits<double>::quiet_NaN();

  const auto expect_option = [&](ChainOptions options, const std::string& field) {
    EXPECT_EQ(options.Validate().code(), StatusCode::kInvalidArgument) << field;
    const auto solution = SolveChain(first, last, steps, kWidth, kHeight, options);
    ASSERT_FALSE(solution.ok()) << field;
    EXPECT_EQ(solution.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(solution.status().message().find(field), std::string::npos)
        << solution.status().ToString();
  };
  EXPECT_TRUE(ChainOptions().Validate().ok());
  ChainOptions options;
  options.min_link_sigma_px = 0;
  expect_option(options, "min_link_sigma_px");
  options.min_link_sigma_px = nan;
  expect_option(options, "min_link_sigma_px");
  options = ChainOptions();
  options.max_iterations = 0;
  expect_option(options, "max_iterations");
  options = ChainOptions();
  options.tolerance_px = 0;
  expect_option(options, "tolerance_px");
  options.tolerance_px = std::numeric_limits<double>::infinity();
  expect_option(options, "tolerance_px");

  // Image size.
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{0, kHeight}, {kWidth, 0}, {-5, 7}}) {
    EXPECT_EQ(SolveChain(first, last, steps, w, h).status().code(), StatusCode::kInvalidArgument);
  }

  // Bad steps name their index.
  const auto expect_step = [&](const std::vector<ChainStep>& bad, const std::string& what) {
    for (const bool with_last : {true, false}) {
      const auto solution =
          SolveChain(first, with_last ? std::optional<Eigen::Matrix3d>(last) : std::nullopt, bad,
                     kWidth, kHeight);
      ASSERT_FALSE(solution.ok()) << what;
      EXPECT_EQ(solution.status().code(), StatusCode::kInvalidData) << what;
      EXPECT_NE(solution.status().message().find("step 7 "), std::string::npos)
          << what << ": " << solution.status().ToString();
    }
  };
  std::vector<ChainStep> bad = steps;
  bad[7].next_from_previous(0, 1) = nan;
  expect_step(bad, "NaN homography");
  bad = steps;
  bad[7].next_from_previous(2, 2) = 2;
  expect_step(bad, "unnormalised homography");
  bad = steps;
  bad[7].next_from_previous << 1, 2, 3, 2, 4, 6, 0, 0, 1;
  expect_step(bad, "singular homography");
  bad = steps;
  bad[7].next_from_previous(2, 0) = -1.0 / 600;  // the right-hand corners beyond the horizon
  expect_step(bad, "corner across infinity");
  bad = steps;
  bad[7].covariance(3, 5) = nan;
  expect_step(bad, "NaN covariance");
  bad = steps;
  bad[7].covariance(3, 5) += 1;
  expect_step(bad, "asymmetric covariance");

  // Bad ends name themselves.
  Eigen::Matrix3d broken = first;
  broken(1, 2) = nan;
  auto solution = SolveChain(broken, last, steps, kWidth, kHeight);
  ASSERT_FALSE(solution.ok());
  EXPECT_EQ(solution.status().code(), StatusCode::kInvalidData);
  EXPECT_NE(solution.status().message().find("map_from_first"), std::string::npos);
  solution = SolveChain(first, Eigen::Matrix3d(Eigen::Matrix3d::Zero()), steps, kWidth, kHeight);
  ASSERT_FALSE(solution.ok());
  EXPECT_EQ(solution.status().code(), StatusCode::kInvalidData);
  EXPECT_NE(solution.status().message().find("map_from_last"), std::string::npos);
  Eigen::Matrix3d flat = Eigen::Matrix3d::Zero();
  flat(2, 2) = 1;
  solution = SolveChain(first, flat, steps, kWidth, kHeight);
  ASSERT_FALSE(solution.ok());
  EXPECT_NE(solution.status().message().find("singular"), std::string::npos);
}

// Ends that the steps cannot join (the last end turned by 90 degrees and 500 m off): a solution
// no worse than its start, or an error, never a crash.
TEST(ChainSolverTest, InconsistentEndsDoNotBreakIt) {
  const std::vector<Eigen::Matrix3d> truth = CurvedFlight(21, 1.6, 0.5);
  const std::vector<ChainStep> steps = MeasureChain(truth, 0.5, 11);
  Eigen::Matrix3d moved;
  moved << 0, -1, 500, 1, 0, 0, 0, 0, 1;
  const Eigen::Matrix3d last = Normalised(moved * truth.back());
  const StatusOr<ChainSolution> solution = SolveChain(truth.front(), last, steps, kWidth, kHeight);
  if (solution.ok()) {
    EXPECT_LE(solution->final_cost, solution->initial_cost);
    for (const Eigen::Matrix3d& m : solution->map_from_frame) EXPECT_TRUE(m.allFinite());
    std::printf("  solved: cost %.4g -> %.4g, %d iterations\n", solution->initial_cost,
                solution->final_cost, solution->iterations);
  } else {
    EXPECT_EQ(solution.status().code(), StatusCode::kInvalidData);
    std::printf("  %s\n", solution.status().ToString().c_str());
  }
}

// n = 0 and n = 1, the edge cases.
TEST(ChainSolverTest, EmptyAndSingleStepChains) {
  const std::vector<Eigen::Matrix3d> truth = CurvedFlight(2, 1.6, 0);
  const std::vector<ChainStep> one = MeasureChain(truth, 0.5, 9);
  ChainOptions options;
  options.covariances = true;

  // n = 0 without the last end: frame 0 alone, unchanged.
  auto solution = SolveChain(truth[0], std::nullopt, {}, kWidth, kHeight, options);
  ASSERT_TRUE(solution.ok()) << solution.status().ToString();
  ASSERT_EQ(solution->map_from_frame.size(), 1u);
  EXPECT_EQ(solution->map_from_frame[0], truth[0]);
  ASSERT_EQ(solution->covariances.size(), 1u);
  EXPECT_EQ(solution->covariances[0], Matrix8::Zero());
  EXPECT_EQ(solution->iterations, 0);
  EXPECT_EQ(solution->final_cost, 0);

  // n = 0 with the last end: frame 0 fixed twice.
  solution = SolveChain(truth[0], truth[0], {}, kWidth, kHeight, options);
  ASSERT_FALSE(solution.ok());
  EXPECT_EQ(solution.status().code(), StatusCode::kInvalidArgument);

  // n = 1 with both ends: nothing free, the ends returned, the step's cost reported.
  Eigen::Matrix3d moved = truth[1];
  moved(0, 2) += 0.5;  // half a metre: ~3 px against the step
  solution = SolveChain(truth[0], moved, one, kWidth, kHeight, options);
  ASSERT_TRUE(solution.ok()) << solution.status().ToString();
  ASSERT_EQ(solution->map_from_frame.size(), 2u);
  EXPECT_EQ(solution->map_from_frame[0], truth[0]);
  EXPECT_EQ(solution->map_from_frame[1], moved);
  EXPECT_EQ(solution->iterations, 0);
  EXPECT_GT(solution->final_cost, 1);
  EXPECT_EQ(solution->initial_cost, solution->final_cost);
  ASSERT_EQ(solution->covariances.size(), 2u);
  EXPECT_EQ(solution->covariances[1], Matrix8::Zero());

  // n = 1 with one end: the step inverted, its covariance propagated.
  solution = SolveChain(truth[0], std::nullopt, one, kWidth, kHeight, options);
  ASSERT_TRUE(solution.ok()) << solution.status().ToString();
  EXPECT_LT(CornerDifferencePx(Chained(truth[0], one)[1], solution->map_from_frame[1]), 1e-9);
  EXPECT_GT(solution->covariances[1].trace(), 0);
}

}  // namespace
}  // namespace saker::mosaic
