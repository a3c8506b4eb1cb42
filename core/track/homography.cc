#include "core/track/homography.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>

namespace saker::track {
namespace {

using Jacobian28 = Eigen::Matrix<double, 2, 8>;
using Matrix8d = Eigen::Matrix<double, 8, 8>;
using Vector8d = Eigen::Matrix<double, 8, 1>;

// Below this reciprocal condition number (of the column-scaled normal matrix) the points do not
// determine the 8 parameters: collinear points, or all in one spot.
constexpr double kMinReciprocalCondition = 1e-13;

// Relative size under which the normalising element of a product or inverse counts as zero.
constexpr double kTinyRelative = 1e-12;

std::string Describe(const char* name, double value) {
  std::ostringstream text;
  text << name << " = " << value;
  return text.str();
}

bool AllFinite(const std::vector<Correspondence>& correspondences) {
  return std::all_of(correspondences.begin(), correspondences.end(), [](const Correspondence& c) {
    return c.source.allFinite() && c.target.allFinite();
  });
}

int CvMethod(RobustMethod method, bool fundamental) {
  switch (method) {
    case RobustMethod::kRansac:
      return fundamental ? static_cast<int>(cv::FM_RANSAC) : static_cast<int>(cv::RANSAC);
    case RobustMethod::kMagsac:
      return cv::USAC_MAGSAC;
  }
  return cv::RANSAC;
}

void SplitPoints(const std::vector<Correspondence>& correspondences,
                 std::vector<cv::Point2d>* source, std::vector<cv::Point2d>* target) {
  source->clear();
  target->clear();
  source->reserve(correspondences.size());
  target->reserve(correspondences.size());
  for (const Correspondence& c : correspondences) {
    source->emplace_back(c.source.x(), c.source.y());
    target->emplace_back(c.target.x(), c.target.y());
  }
}

Eigen::Matrix3d ToEigen(const cv::Mat& m) {
  cv::Mat m64;
  m.convertTo(m64, CV_64F);
  Eigen::Matrix3d result;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) result(r, c) = m64.at<double>(r, c);
  }
  return result;
}

// Row-major position of parameter k (0..7) in H.
constexpr int Row(int k) { return k / 3; }
constexpr int Col(int k) { return k % 3; }

// Parameters of P / P(2,2) differentiated, given dP for each of `columns` input parameters:
// d(P / p22) = (dP - (P / p22) dp22) / p22.
template <int kColumns>
Eigen::Matrix<double, 8, kColumns> NormalisedJacobian(
    const Eigen::Matrix3d& p, const std::array<Eigen::Matrix3d, kColumns>& dp) {
  const double p22 = p(2, 2);
  const Eigen::Matrix3d normalised = p / p22;
  Eigen::Matrix<double, 8, kColumns> jacobian;
  for (int column = 0; column < kColumns; ++column) {
    const Eigen::Matrix3d d = (dp[column] - normalised * dp[column](2, 2)) / p22;
    for (int k = 0; k < 8; ++k) jacobian(k, column) = d(Row(k), Col(k));
  }
  return jacobian;
}

// The weighted least-squares quantities of the transfer error at one H over a set of points.
struct NormalEquations {
  Matrix8d normal = Matrix8d::Zero();    // sum J^T W J (W without the sigma^2)
  Vector8d gradient = Vector8d::Zero();  // sum J^T W r, r = target - H source
  double cost = 0;                       // sum r^T W r
  double sum_squared_px = 0;             // sum |r|^2
  bool valid = true;                     // false when a point maps to or beyond infinity
};

NormalEquations Accumulate(const Eigen::Matrix3d& h, const std::vector<Correspondence>& points,
                           bool count_source_noise) {
  NormalEquations result;
  for (const Correspondence& c : points) {
    const double w = h(2, 0) * c.source.x() + h(2, 1) * c.source.y() + h(2, 2);
    // All source points lie in front of the camera for a real frame pair: w keeps one sign over
    // the image (positive with H(2,2) = 1 when the source origin is in front). A candidate that
    // flips it has swung a point through infinity.
    if (!(w > 1e-9)) {
      result.valid = false;
      return result;
    }
    const Eigen::Vector2d residual = c.target - Transfer(h, c.source);
    const Jacobian28 j = TransferJacobian(h, c.source);
    Eigen::Matrix2d weight = Eigen::Matrix2d::Identity();
    if (count_source_noise) {
      // Residual covariance / sigma^2 = I (target noise) + A A^T (source noise carried through
      // the transfer); its inverse weights the residual.
      const Eigen::Matrix2d a = TransferPointJacobian(h, c.source);
      weight = (Eigen::Matrix2d::Identity() + a * a.transpose()).inverse();
    }
    const Eigen::Matrix<double, 8, 2> jt_w = j.transpose() * weight;
    result.normal.noalias() += jt_w * j;
    result.gradient.noalias() += jt_w * residual;
    result.cost += residual.dot(weight * residual);
    result.sum_squared_px += residual.squaredNorm();
  }
  return result;
}

// Levenberg-Marquardt on the 8 parameters, in column-scaled coordinates (the parameters differ
// by six orders of magnitude in size: h02 is pixels, h20 is per pixel).
Eigen::Matrix3d Refine(Eigen::Matrix3d h, const std::vector<Correspondence>& points,
                       const HomographyOptions& options) {
  NormalEquations current = Accumulate(h, points, options.count_source_noise);
  if (!current.valid) return h;
  double lambda = 1e-4;
  for (int iteration = 0; iteration < options.refine_iterations; ++iteration) {
    const Vector8d scale = current.normal.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
    Matrix8d scaled = scale.asDiagonal() * current.normal * scale.asDiagonal();
    bool improved = false;
    while (lambda < 1e10) {
      Matrix8d damped = scaled;
      damped.diagonal().array() += lambda;
      const Vector8d step_scaled = damped.ldlt().solve(scale.cwiseProduct(current.gradient));
      const Vector8d step = scale.cwiseProduct(step_scaled);
      if (!step.allFinite()) break;
      const Eigen::Matrix3d candidate =
          HomographyFromParameters(ParametersFromHomography(h) + step);
      const NormalEquations next = Accumulate(candidate, points, options.count_source_noise);
      if (next.valid && next.cost <= current.cost) {
        const double decrease = current.cost - next.cost;
        h = candidate;
        current = next;
        lambda = std::max(lambda * 0.1, 1e-12);
        improved = true;
        // Converged: the cost no longer moves at the level of rounding.
        if (decrease <= 1e-9 * (next.cost + 1e-30) || step_scaled.norm() < 1e-12) return h;
        break;
      }
      lambda *= 10;
    }
    if (!improved) break;
  }
  return h;
}

std::vector<Correspondence> SelectInliers(const Eigen::Matrix3d& h,
                                          const std::vector<Correspondence>& correspondences,
                                          double threshold_px) {
  std::vector<Correspondence> inliers;
  inliers.reserve(correspondences.size());
  for (const Correspondence& c : correspondences) {
    const double w = h(2, 0) * c.source.x() + h(2, 1) * c.source.y() + h(2, 2);
    if (!(w > 1e-9)) continue;
    if ((c.target - Transfer(h, c.source)).norm() <= threshold_px) inliers.push_back(c);
  }
  return inliers;
}

bool SameIds(const std::vector<Correspondence>& a, const std::vector<Correspondence>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i].id != b[i].id || a[i].source != b[i].source) return false;
  }
  return true;
}

// The options every robust first pass (homography or fundamental matrix) shares.
Status ValidateRobustPass(double ransac_threshold_px, double confidence, int max_iterations) {
  if (!(ransac_threshold_px > 0 && ransac_threshold_px <= 100)) {
    return InvalidArgumentError(Describe("ransac_threshold_px", ransac_threshold_px) +
                                " must be in (0, 100] px");
  }
  if (!(confidence > 0 && confidence < 1)) {
    return InvalidArgumentError(Describe("confidence", confidence) + " must be in (0, 1)");
  }
  if (max_iterations < 1) {
    return InvalidArgumentError(Describe("max_iterations", max_iterations) + " must be >= 1");
  }
  return Status::Ok();
}

}  // namespace

Status HomographyOptions::Validate() const {
  SAKER_RETURN_IF_ERROR(ValidateRobustPass(ransac_threshold_px, confidence, max_iterations));
  if (min_inliers < 5) {
    return InvalidArgumentError(Describe("min_inliers", min_inliers) +
                                " must be >= 5 (4 points fit exactly and say nothing about noise)");
  }
  if (!(measurement_sigma_px > 0 && measurement_sigma_px <= 100)) {
    return InvalidArgumentError(Describe("measurement_sigma_px", measurement_sigma_px) +
                                " must be in (0, 100] px");
  }
  if (refine_iterations < 0 || refine_iterations > 1000) {
    return InvalidArgumentError(Describe("refine_iterations", refine_iterations) +
                                " must be in [0, 1000]");
  }
  return Status::Ok();
}

Status FundamentalOptions::Validate() const {
  SAKER_RETURN_IF_ERROR(ValidateRobustPass(ransac_threshold_px, confidence, max_iterations));
  if (min_inliers < 8) {
    return InvalidArgumentError(Describe("min_inliers", min_inliers) + " must be >= 8");
  }
  return Status::Ok();
}

HomographyParameters ParametersFromHomography(const Eigen::Matrix3d& h) {
  SAKER_CHECK(h(2, 2) != 0) << "homography with H(2,2) = 0 has no 8-parameter form";
  const Eigen::Matrix3d n = h / h(2, 2);
  HomographyParameters parameters;
  for (int k = 0; k < 8; ++k) parameters(k) = n(Row(k), Col(k));
  return parameters;
}

Eigen::Matrix3d HomographyFromParameters(const HomographyParameters& parameters) {
  Eigen::Matrix3d h;
  for (int k = 0; k < 8; ++k) h(Row(k), Col(k)) = parameters(k);
  h(2, 2) = 1;
  return h;
}

Eigen::Vector2d Transfer(const Eigen::Matrix3d& h, const Eigen::Vector2d& p) {
  const Eigen::Vector3d q = h * p.homogeneous();
  SAKER_CHECK(q.z() != 0) << "point (" << p.x() << ", " << p.y() << ") maps to infinity";
  return q.hnormalized();
}

Eigen::Matrix<double, 2, 8> TransferJacobian(const Eigen::Matrix3d& h, const Eigen::Vector2d& p) {
  const Eigen::Vector3d q = h * p.homogeneous();
  SAKER_CHECK(q.z() != 0) << "point (" << p.x() << ", " << p.y() << ") maps to infinity";
  const double inv_w = 1.0 / q.z();
  const double u = q.x() * inv_w;
  const double v = q.y() * inv_w;
  const double x = p.x() * inv_w;
  const double y = p.y() * inv_w;
  Jacobian28 j;
  j << x, y, inv_w, 0, 0, 0, -u * x, -u * y,  //
      0, 0, 0, x, y, inv_w, -v * x, -v * y;
  return j;
}

Eigen::Matrix2d TransferPointJacobian(const Eigen::Matrix3d& h, const Eigen::Vector2d& p) {
  const Eigen::Vector3d q = h * p.homogeneous();
  SAKER_CHECK(q.z() != 0) << "point (" << p.x() << ", " << p.y() << ") maps to infinity";
  const double u = q.x() / q.z();
  const double v = q.y() / q.z();
  Eigen::Matrix2d a;
  a << h(0, 0) - u * h(2, 0), h(0, 1) - u * h(2, 1),  //
      h(1, 0) - v * h(2, 0), h(1, 1) - v * h(2, 1);
  return a / q.z();
}

Eigen::Matrix2d TransferCovariance(const Eigen::Matrix3d& h, const HomographyCovariance& cov,
                                   const Eigen::Vector2d& p) {
  const Jacobian28 j = TransferJacobian(h, p);
  const Eigen::Matrix2d result = j * cov * j.transpose();
  return 0.5 * (result + result.transpose());
}

namespace {

// H / H(2,2): the matrix whose 8 parameters a covariance describes.
Eigen::Matrix3d Normalised(const Eigen::Matrix3d& h) {
  SAKER_CHECK(h(2, 2) != 0) << "a homography with H(2,2) = 0 has no parameters";
  return h / h(2, 2);
}

}  // namespace

Eigen::Matrix<double, 8, 16> ComposeJacobian(const Eigen::Matrix3d& c_from_b_in,
                                             const Eigen::Matrix3d& b_from_a_in) {
  // The derivatives are taken with respect to the parameters of the normalised inputs (the ones
  // the covariances describe), so a scaled input must not scale them.
  const Eigen::Matrix3d c_from_b = Normalised(c_from_b_in);
  const Eigen::Matrix3d b_from_a = Normalised(b_from_a_in);
  const Eigen::Matrix3d product = c_from_b * b_from_a;
  SAKER_CHECK(product(2, 2) != 0) << "composed homography has H(2,2) = 0";
  // d(C B) / dC_ij = E_ij B (row i of the product gets row j of B);
  // d(C B) / dB_ij = C E_ij (column j of the product gets column i of C).
  std::array<Eigen::Matrix3d, 16> dp;
  for (int k = 0; k < 8; ++k) {
    dp[k].setZero();
    dp[k].row(Row(k)) = b_from_a.row(Col(k));
    dp[8 + k].setZero();
    dp[8 + k].col(Col(k)) = c_from_b.col(Row(k));
  }
  return NormalisedJacobian<16>(product, dp);
}

StatusOr<HomographyWithCovariance> Compose(const Eigen::Matrix3d& c_from_b,
                                           const HomographyCovariance& cov_cb,
                                           const Eigen::Matrix3d& b_from_a,
                                           const HomographyCovariance& cov_ba) {
  const Eigen::Matrix3d product = c_from_b * b_from_a;
  if (!product.allFinite() || !(std::abs(product(2, 2)) > kTinyRelative * product.norm())) {
    return InvalidDataError(
        "composed homography maps the source origin to infinity (H(2,2) ~ 0) or is not finite");
  }
  const Eigen::Matrix<double, 8, 16> j = ComposeJacobian(c_from_b, b_from_a);
  HomographyWithCovariance result;
  result.target_from_source = product / product(2, 2);
  result.covariance = j.leftCols<8>() * cov_cb * j.leftCols<8>().transpose() +
                      j.rightCols<8>() * cov_ba * j.rightCols<8>().transpose();
  result.covariance = 0.5 * (result.covariance + result.covariance.transpose());
  return result;
}

Eigen::Matrix<double, 8, 8> InverseJacobian(const Eigen::Matrix3d& target_from_source) {
  const Eigen::Matrix3d g = Normalised(target_from_source).inverse();
  SAKER_CHECK(g.allFinite() && g(2, 2) != 0) << "homography has no normalised inverse";
  // d(H^-1) = -H^-1 dH H^-1, with dH = E_ij: the outer product of column i and row j of H^-1.
  std::array<Eigen::Matrix3d, 8> dp;
  for (int k = 0; k < 8; ++k) dp[k] = -g.col(Row(k)) * g.row(Col(k));
  return NormalisedJacobian<8>(g, dp);
}

StatusOr<HomographyWithCovariance> Invert(const Eigen::Matrix3d& target_from_source,
                                          const HomographyCovariance& cov) {
  const double det = target_from_source.determinant();
  const double scale = target_from_source.norm();
  if (!target_from_source.allFinite() || !(std::abs(det) > kTinyRelative * scale * scale * scale)) {
    return InvalidDataError("homography is singular or not finite: no inverse");
  }
  const Eigen::Matrix3d g = target_from_source.inverse();
  if (!(std::abs(g(2, 2)) > kTinyRelative * g.norm())) {
    return InvalidDataError("inverse homography maps the target origin to infinity (H(2,2) ~ 0)");
  }
  const Matrix8d j = InverseJacobian(target_from_source);
  HomographyWithCovariance result;
  result.target_from_source = g / g(2, 2);
  result.covariance = j * cov * j.transpose();
  result.covariance = 0.5 * (result.covariance + result.covariance.transpose());
  return result;
}

StatusOr<HomographyEstimate> EstimateHomography(const std::vector<Correspondence>& correspondences,
                                                const HomographyOptions& options) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  const int n = static_cast<int>(correspondences.size());
  if (n < options.min_inliers) {
    return InvalidDataError("homography: " + std::to_string(n) + " correspondences, at least " +
                            std::to_string(options.min_inliers) + " needed");
  }
  if (!AllFinite(correspondences)) {
    return InvalidDataError("homography: a correspondence has a non-finite coordinate");
  }

  std::vector<cv::Point2d> source;
  std::vector<cv::Point2d> target;
  SplitPoints(correspondences, &source, &target);
  std::vector<uchar> mask;
  const cv::Mat cv_h = cv::findHomography(source, target, CvMethod(options.method, false),
                                          options.ransac_threshold_px, mask, options.max_iterations,
                                          options.confidence);
  if (cv_h.empty()) {
    return InvalidDataError("homography: the robust fit found no model among " + std::to_string(n) +
                            " correspondences (degenerate points?)");
  }
  Eigen::Matrix3d h = ToEigen(cv_h);
  if (!h.allFinite() || !(std::abs(h(2, 2)) > kTinyRelative * h.norm())) {
    return InvalidDataError("homography: the robust fit is not finite or has H(2,2) ~ 0");
  }
  h /= h(2, 2);

  HomographyEstimate estimate;
  estimate.ransac_inliers = static_cast<int>(std::count(mask.begin(), mask.end(), uchar{1}));
  if (estimate.ransac_inliers < options.min_inliers) {
    return InvalidDataError("homography: " + std::to_string(estimate.ransac_inliers) +
                            " inliers of " + std::to_string(n) + ", at least " +
                            std::to_string(options.min_inliers) + " needed");
  }
  std::vector<Correspondence> inliers;
  inliers.reserve(static_cast<size_t>(estimate.ransac_inliers));
  for (int i = 0; i < n; ++i) {
    if (mask[static_cast<size_t>(i)]) inliers.push_back(correspondences[static_cast<size_t>(i)]);
  }

  // Refine on the robust inliers, then let the refined H choose the inliers once more (the
  // robust pass scores a minimal-sample model, or MAGSAC's soft weights, not our threshold) and
  // refine again if that changed them. The last refinement always runs on the final inliers.
  constexpr int kRounds = 3;
  for (int round = 0;; ++round) {
    h = Refine(h, inliers, options);
    if (round + 1 == kRounds) break;
    std::vector<Correspondence> reselected =
        SelectInliers(h, correspondences, options.ransac_threshold_px);
    if (SameIds(reselected, inliers)) break;
    inliers = std::move(reselected);
    if (static_cast<int>(inliers.size()) < options.min_inliers) {
      return InvalidDataError("homography: " + std::to_string(inliers.size()) + " inliers of " +
                              std::to_string(n) + " after refinement, at least " +
                              std::to_string(options.min_inliers) + " needed");
    }
  }

  const NormalEquations final_state = Accumulate(h, inliers, options.count_source_noise);
  if (!final_state.valid || !h.allFinite()) {
    return InvalidDataError("homography: the refined model sends inliers through infinity");
  }
  const Vector8d scale = final_state.normal.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
  const Matrix8d scaled = scale.asDiagonal() * final_state.normal * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Matrix8d> eigen(scaled);
  const double largest = eigen.eigenvalues()(7);
  const double smallest = eigen.eigenvalues()(0);
  if (!(largest > 0) || !(smallest > kMinReciprocalCondition * largest)) {
    return InvalidDataError(
        "homography: the inliers do not determine the 8 parameters (collinear or coincident "
        "points)");
  }
  const Matrix8d scaled_inverse = eigen.eigenvectors() *
                                  eigen.eigenvalues().cwiseInverse().asDiagonal() *
                                  eigen.eigenvectors().transpose();

  const int m = static_cast<int>(inliers.size());
  const double dof = 2.0 * m - 8.0;
  estimate.a_posteriori_sigma_px = std::sqrt(final_state.cost / dof);
  switch (options.noise_scale) {
    case NoiseScale::kAPriori:
      estimate.sigma_px = options.measurement_sigma_px;
      break;
    case NoiseScale::kAPosteriori:
      estimate.sigma_px = estimate.a_posteriori_sigma_px;
      break;
    case NoiseScale::kLarger:
      estimate.sigma_px = std::max(options.measurement_sigma_px, estimate.a_posteriori_sigma_px);
      break;
  }
  estimate.target_from_source = h;
  estimate.covariance = estimate.sigma_px * estimate.sigma_px * scale.asDiagonal() *
                        scaled_inverse * scale.asDiagonal();
  estimate.covariance = 0.5 * (estimate.covariance + estimate.covariance.transpose());
  estimate.rms_px = std::sqrt(final_state.sum_squared_px / m);
  estimate.inliers = std::move(inliers);
  return estimate;
}

double SampsonDistance(const Eigen::Matrix3d& fundamental, const Eigen::Vector2d& p,
                       const Eigen::Vector2d& q) {
  const Eigen::Vector3d fp = fundamental * p.homogeneous();
  const Eigen::Vector3d ftq = fundamental.transpose() * q.homogeneous();
  const double algebraic = q.homogeneous().dot(fp);
  const double gradient2 = fp.head<2>().squaredNorm() + ftq.head<2>().squaredNorm();
  if (!(gradient2 > 0)) return algebraic == 0 ? 0 : std::numeric_limits<double>::infinity();
  return std::abs(algebraic) / std::sqrt(gradient2);
}

StatusOr<FundamentalEstimate> EstimateFundamental(
    const std::vector<Correspondence>& correspondences, const FundamentalOptions& options) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  const int n = static_cast<int>(correspondences.size());
  if (n < options.min_inliers) {
    return InvalidDataError("fundamental matrix: " + std::to_string(n) +
                            " correspondences, at least " + std::to_string(options.min_inliers) +
                            " needed");
  }
  if (!AllFinite(correspondences)) {
    return InvalidDataError("fundamental matrix: a correspondence has a non-finite coordinate");
  }
  std::vector<cv::Point2d> source;
  std::vector<cv::Point2d> target;
  SplitPoints(correspondences, &source, &target);
  std::vector<uchar> mask;
  const cv::Mat cv_f = cv::findFundamentalMat(source, target, CvMethod(options.method, true),
                                              options.ransac_threshold_px, options.confidence,
                                              options.max_iterations, mask);
  if (cv_f.empty() || cv_f.rows != 3 || cv_f.cols != 3) {
    return InvalidDataError("fundamental matrix: the robust fit found no model among " +
                            std::to_string(n) + " correspondences");
  }
  Eigen::Matrix3d f = ToEigen(cv_f);
  std::vector<bool> inliers(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) inliers[static_cast<size_t>(i)] = mask[static_cast<size_t>(i)] != 0;

  // The robust pass keeps the best minimal-sample model; the normalised 8-point fit on all its
  // inliers averages their noise. Two rounds of refit and reselection settle the inlier set.
  for (int round = 0; round < 2; ++round) {
    std::vector<cv::Point2d> in_source;
    std::vector<cv::Point2d> in_target;
    for (int i = 0; i < n; ++i) {
      if (!inliers[static_cast<size_t>(i)]) continue;
      in_source.push_back(source[static_cast<size_t>(i)]);
      in_target.push_back(target[static_cast<size_t>(i)]);
    }
    if (in_source.size() < 8) break;
    const cv::Mat refit = cv::findFundamentalMat(in_source, in_target, cv::FM_8POINT);
    if (refit.rows != 3 || refit.cols != 3) break;
    const Eigen::Matrix3d candidate = ToEigen(refit);
    if (!candidate.allFinite()) break;
    f = candidate;
    for (int i = 0; i < n; ++i) {
      const Correspondence& c = correspondences[static_cast<size_t>(i)];
      inliers[static_cast<size_t>(i)] =
          SampsonDistance(f, c.source, c.target) <= options.ransac_threshold_px;
    }
  }

  FundamentalEstimate estimate;
  estimate.inlier_count = static_cast<int>(std::count(inliers.begin(), inliers.end(), true));
  if (estimate.inlier_count < options.min_inliers) {
    return InvalidDataError("fundamental matrix: " + std::to_string(estimate.inlier_count) +
                            " inliers of " + std::to_string(n) + ", at least " +
                            std::to_string(options.min_inliers) + " needed");
  }
  if (!(f.norm() > 0)) return InvalidDataError("fundamental matrix: the fit is zero");
  f /= f.norm();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(f, Eigen::ComputeFullU | Eigen::ComputeFullV);
  // The fit is rank 2 already; dropping the third singular value again keeps F e = 0 exact.
  Eigen::Vector3d singular = svd.singularValues();
  singular(2) = 0;
  f = svd.matrixU() * singular.asDiagonal() * svd.matrixV().transpose();
  f /= f.norm();
  // A fixed sign (last coordinate >= 0, else the first non-zero one positive) so the epipole
  // reads the same whatever the SVD returns.
  auto canonical = [](Eigen::Vector3d e) {
    e.normalize();
    if (e.z() < 0 || (e.z() == 0 && (e.x() < 0 || (e.x() == 0 && e.y() < 0)))) e = -e;
    return e;
  };
  estimate.fundamental = f;
  estimate.epipole_source = canonical(svd.matrixV().col(2));
  estimate.epipole_target = canonical(svd.matrixU().col(2));
  estimate.inliers = std::move(inliers);
  return estimate;
}

}  // namespace saker::track
