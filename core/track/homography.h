#pragma once

// Robust homographies between two frames with their 8x8 parameter covariance, the first-order
// propagation of that covariance (point transfer, composition, inversion), and a fundamental
// matrix helper for the moving / stationary separation. Formulas and the noise model:
// docs/homography-covariance.md.

#include "core/track/types.h"
#include "core/util/status.h"

#include <Eigen/Core>

#include <vector>

namespace saker::track {

// The robust first pass. Both are cv::findHomography / cv::findFundamentalMat methods; the
// measured trade-off is in docs/homography-covariance.md.
enum class RobustMethod {
  kRansac,  // cv::RANSAC / cv::FM_RANSAC
  kMagsac,  // cv::USAC_MAGSAC (MAGSAC++)
};

// Which sigma scales the covariance.
enum class NoiseScale {
  kAPriori,      // HomographyOptions::measurement_sigma_px as given.
  kAPosteriori,  // Estimated from the weighted inlier residuals (variance factor).
  kLarger,       // The larger of the two: never more confident than the tracker's accuracy,
                 // but inflated when the residuals say the plane model fits worse (parallax).
};

struct HomographyOptions {
  // MAGSAC++ measured (once, during development) 2.2x faster than RANSAC at 30 % outliers, 3x at 50
  // %, 13x at 70 %, as accurate after the refinement (docs/homography-covariance.md).
  RobustMethod method = RobustMethod::kMagsac;
  // A correspondence is an inlier when its transfer error in the target image is at most this.
  // Keep it at 6 measurement sigmas or more: tighter, the inlier choice follows the estimate's
  // own errors and the covariance comes out optimistic (by 3-12 % at 4 sigmas, 40-55 % at 2.5).
  double ransac_threshold_px = 3.0;
  double confidence = 0.999;
  int max_iterations = 2000;  // RANSAC iterations
  // Fewer inliers than this is a failure (at least 5, so that the residuals say something).
  int min_inliers = 15;
  // Standard deviation of each coordinate of a tracked point (pixels, isotropic, independent).
  double measurement_sigma_px = 0.5;
  // Count the noise of the source points too (propagated through the transfer), not only the
  // target points'. Both come from the same tracker, so both are noisy.
  bool count_source_noise = true;
  NoiseScale noise_scale = NoiseScale::kLarger;
  // Levenberg-Marquardt iterations of the refinement on the inliers.
  int refine_iterations = 20;

  Status Validate() const;
};

struct HomographyEstimate {
  Eigen::Matrix3d target_from_source = Eigen::Matrix3d::Identity();  // H(2,2) = 1
  HomographyCovariance covariance = HomographyCovariance::Zero();    // types.h parameter order
  std::vector<Correspondence> inliers;                               // those the refinement used
  double rms_px = 0;    // RMS transfer error of the inliers in the target image (per point)
  double sigma_px = 0;  // the measurement sigma the covariance was scaled with
  double a_posteriori_sigma_px = 0;  // the sigma the residuals imply (variance factor)
  int ransac_inliers = 0;            // inliers of the robust first pass
};

// Robust estimation of target_from_source: a robust first pass (options.method), then
// Levenberg-Marquardt on the inliers minimising the transfer error in the target image, weighted
// by each residual's covariance, then the covariance (J^T W J)^-1 sigma^2. Fails with
// InvalidArgument on bad options and InvalidData when the points are too few, not finite or
// degenerate (collinear, all alike), or the robust pass finds too few inliers.
StatusOr<HomographyEstimate> EstimateHomography(const std::vector<Correspondence>& correspondences,
                                                const HomographyOptions& options);

// H <-> its 8 parameters (types.h order). ParametersFromHomography divides by H(2,2), which must
// not be zero.
HomographyParameters ParametersFromHomography(const Eigen::Matrix3d& h);
Eigen::Matrix3d HomographyFromParameters(const HomographyParameters& parameters);

// H p (p in the source image, the result in the target image). The point must not map to
// infinity (SAKER_CHECK).
Eigen::Vector2d Transfer(const Eigen::Matrix3d& h, const Eigen::Vector2d& p);
// d(H p) / d(parameters): 2x8, for H with H(2,2) = 1.
Eigen::Matrix<double, 2, 8> TransferJacobian(const Eigen::Matrix3d& h, const Eigen::Vector2d& p);
// d(H p) / d(p): 2x2, how source point noise reaches the target image.
Eigen::Matrix2d TransferPointJacobian(const Eigen::Matrix3d& h, const Eigen::Vector2d& p);
// Pixel covariance in the target image of H p due to the uncertainty of H alone:
// J cov J^T with J = TransferJacobian(h, p). Its eigen-decomposition is the uncertainty ellipse.
Eigen::Matrix2d TransferCovariance(const Eigen::Matrix3d& h, const HomographyCovariance& cov,
                                   const Eigen::Vector2d& p);

struct HomographyWithCovariance {
  Eigen::Matrix3d target_from_source = Eigen::Matrix3d::Identity();  // H(2,2) = 1
  HomographyCovariance covariance = HomographyCovariance::Zero();
};

// c_from_a = c_from_b * b_from_a (normalised), its covariance propagated to first order assuming
// the two inputs are independent. InvalidData when the product has H(2,2) ~ 0 (the source
// origin maps to infinity, no H(2,2) = 1 parametrisation).
StatusOr<HomographyWithCovariance> Compose(const Eigen::Matrix3d& c_from_b,
                                           const HomographyCovariance& cov_cb,
                                           const Eigen::Matrix3d& b_from_a,
                                           const HomographyCovariance& cov_ba);
// The 16 columns [d/d(c_from_b params) | d/d(b_from_a params)] of the normalised product's
// parameters; Compose uses them. Inputs may be any scale (they are normalised first: the
// covariances describe normalised parameters); inputs and product must have H(2,2) != 0
// (SAKER_CHECK).
Eigen::Matrix<double, 8, 16> ComposeJacobian(const Eigen::Matrix3d& c_from_b,
                                             const Eigen::Matrix3d& b_from_a);

// source_from_target = H^-1 (normalised) and its covariance. InvalidData when H is singular or
// the inverse has H(2,2) ~ 0.
StatusOr<HomographyWithCovariance> Invert(const Eigen::Matrix3d& target_from_source,
                                          const HomographyCovariance& cov);
// d(parameters of H^-1) / d(parameters of H). H must be invertible with (H^-1)(2,2) != 0.
Eigen::Matrix<double, 8, 8> InverseJacobian(const Eigen::Matrix3d& target_from_source);

// ---------------------------------------------------------------------------------------------
// Fundamental matrix (two views of a 3-D scene): target^T F source = 0 in homogeneous pixels.

struct FundamentalOptions {
  // MAGSAC++ measured (once, during development) 7x faster than RANSAC at 30 % outliers and 20x at
  // 50 %, as accurate.
  RobustMethod method = RobustMethod::kMagsac;
  // Inlier when the Sampson distance (pixels, SampsonDistance below) is at most this.
  double ransac_threshold_px = 1.0;
  double confidence = 0.999;
  int max_iterations = 2000;
  int min_inliers = 15;  // at least 8

  Status Validate() const;
};

struct FundamentalEstimate {
  Eigen::Matrix3d fundamental = Eigen::Matrix3d::Zero();  // rank 2, Frobenius norm 1
  std::vector<bool> inliers;  // one per input correspondence, in input order
  int inlier_count = 0;
  // F e = 0 and F^T e' = 0: the epipoles in homogeneous pixels, unit norm, with a non-negative
  // last coordinate. At infinity (the camera moved parallel to the image plane) the last
  // coordinate is ~0 and (x, y) is the direction of the epipolar lines.
  Eigen::Vector3d epipole_source = Eigen::Vector3d::Zero();
  Eigen::Vector3d epipole_target = Eigen::Vector3d::Zero();
};

// Robust pass (options.method), then the normalised 8-point fit on its inliers, then the inliers
// reselected with the refit F by Sampson distance. A planar scene (or a camera that only rotates)
// does not determine F: the fit then succeeds but F is one of a family; use a homography there.
// InvalidArgument on bad options, InvalidData on too few points or inliers.
StatusOr<FundamentalEstimate> EstimateFundamental(
    const std::vector<Correspondence>& correspondences, const FundamentalOptions& options);

// First-order geometric distance (pixels) of the pair (p source, q target) from satisfying
// q^T F p = 0: the square root of Sampson's error
// (q^T F p)^2 / ((F p)_x^2 + (F p)_y^2 + (F^T q)_x^2 + (F^T q)_y^2). Independent of F's scale.
double SampsonDistance(const Eigen::Matrix3d& fundamental, const Eigen::Vector2d& p,
                       const Eigen::Vector2d& q);

}  // namespace saker::track
