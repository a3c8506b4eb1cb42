#include "core/mosaic/loop_closure.h"

#include "core/track/homography.h"
#include "core/track/image_geometry.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>
#include <string>

namespace saker::mosaic {
namespace {

std::string Describe(const char* name, double value) {
  std::ostringstream text;
  text << name << " = " << value;
  return text.str();
}

constexpr int kOrientationBins = 36;
constexpr int kSelectionGrid = 8;  // max_features selection: cells per side

// Half the side of the SIFT descriptor square for a keypoint of `size` (OpenCV: 4 cells of
// 3 * size / 2 pixels).
double DescriptorHalfSide(double size) { return 3.0 * size; }

struct Orientation {
  double angle_deg = 0;  // OpenCV SIFT convention (KeyPoint::angle)
  double strength = 0;   // the histogram's total weight
};

// Dominant gradient orientations of points of one image: the peak of a Gaussian-weighted 36-bin
// histogram of gradient directions, smoothed and refined by a parabola, as SIFT's detector does.
// Gradients use SIFT's signs (y up), and the angle is stored as SIFT's detector stores it
// (360 - direction), so cv::SIFT::compute turns its grid the same way. Gradient magnitudes and
// bins are computed once per image, the Gaussian window once per call.
class OrientationEstimator {
 public:
  OrientationEstimator(const cv::Mat& grey, double blur_sigma, double window_sigma)
      : radius_(std::max(1, static_cast<int>(std::lround(3 * window_sigma)))) {
    cv::Mat blurred;
    grey.convertTo(blurred, CV_32F);
    if (blur_sigma > 0) cv::GaussianBlur(blurred, blurred, cv::Size(), blur_sigma);
    // Central differences, y up; zero on the outermost rows and columns.
    cv::Mat gx = cv::Mat::zeros(blurred.size(), CV_32F),
            gy = cv::Mat::zeros(blurred.size(), CV_32F);
    if (blurred.cols > 2 && blurred.rows > 2) {
      const cv::Rect inner(1, 1, blurred.cols - 2, blurred.rows - 2);
      cv::subtract(blurred(inner + cv::Point(1, 0)), blurred(inner - cv::Point(1, 0)), gx(inner));
      cv::subtract(blurred(inner - cv::Point(0, 1)), blurred(inner + cv::Point(0, 1)), gy(inner));
    }
    cv::Mat angle;
    cv::cartToPolar(gx, gy, magnitude_, angle);  // radians in [0, 2 pi)
    bin_.create(angle.size(), CV_8U);
    for (int v = 0; v < angle.rows; ++v) {
      const float* a = angle.ptr<float>(v);
      uint8_t* b = bin_.ptr<uint8_t>(v);
      for (int u = 0; u < angle.cols; ++u) {
        const int k = static_cast<int>(
            std::floor(a[u] * static_cast<float>(kOrientationBins / (2 * M_PI)) + 0.5f));
        b[u] = static_cast<uint8_t>(((k % kOrientationBins) + kOrientationBins) % kOrientationBins);
      }
    }
    const int side = 2 * radius_ + 1;
    weight_.assign(static_cast<size_t>(side) * side, 0.0f);
    for (int dv = -radius_; dv <= radius_; ++dv) {
      for (int du = -radius_; du <= radius_; ++du) {
        const double r2 = du * du + dv * dv;
        if (r2 > static_cast<double>(radius_) * radius_) continue;
        weight_[static_cast<size_t>(dv + radius_) * side + static_cast<size_t>(du + radius_)] =
            static_cast<float>(std::exp(-r2 / (2 * window_sigma * window_sigma)));
      }
    }
  }

  Orientation At(int x, int y) const {
    std::array<double, kOrientationBins> hist{};
    const int side = 2 * radius_ + 1;
    const int x0 = std::max(0, x - radius_), x1 = std::min(bin_.cols - 1, x + radius_);
    const int y0 = std::max(0, y - radius_), y1 = std::min(bin_.rows - 1, y + radius_);
    for (int v = y0; v <= y1; ++v) {
      const float* m = magnitude_.ptr<float>(v);
      const uint8_t* b = bin_.ptr<uint8_t>(v);
      // The window's entry for (x0, v).
      const float* w =
          weight_.data() + static_cast<ptrdiff_t>(v - y + radius_) * side + (x0 - x + radius_);
      for (int u = x0; u <= x1; ++u) hist[b[u]] += static_cast<double>(m[u] * w[u - x0]);
    }
    std::array<double, kOrientationBins> smooth{};
    double total = 0;
    auto at = [&](int k) {
      return hist[static_cast<size_t>((k + kOrientationBins) % kOrientationBins)];
    };
    for (int i = 0; i < kOrientationBins; ++i) {
      smooth[static_cast<size_t>(i)] = (at(i - 2) + at(i + 2)) * (1.0 / 16) +
                                       (at(i - 1) + at(i + 1)) * (4.0 / 16) + at(i) * (6.0 / 16);
      total += at(i);
    }
    const int peak =
        static_cast<int>(std::max_element(smooth.begin(), smooth.end()) - smooth.begin());
    const double left =
        smooth[static_cast<size_t>((peak + kOrientationBins - 1) % kOrientationBins)];
    const double right = smooth[static_cast<size_t>((peak + 1) % kOrientationBins)];
    const double denominator = left - 2 * smooth[static_cast<size_t>(peak)] + right;
    const double offset = denominator < 0 ? 0.5 * (left - right) / denominator : 0.0;
    const double direction_deg =
        std::fmod((peak + offset) * (360.0 / kOrientationBins) + 360.0, 360.0);
    double angle = 360.0 - direction_deg;
    if (angle >= 360.0) angle -= 360.0;
    return {angle, total};
  }

 private:
  int radius_;
  cv::Mat magnitude_;          // CV_32F
  cv::Mat bin_;                // CV_8U, orientation bin of each pixel's gradient
  std::vector<float> weight_;  // Gaussian window, (2 radius + 1)^2, zero outside the circle
};

float SquaredDistance(const float* a, const float* b, int n) {
  return (Eigen::Map<const Eigen::VectorXf>(a, n) - Eigen::Map<const Eigen::VectorXf>(b, n))
      .squaredNorm();
}

bool UsableFeatures(const KeyFrameFeatures& f) {
  return !f.points.empty() && f.descriptors.type() == CV_32F &&
         f.descriptors.rows == static_cast<int>(f.points.size()) &&
         f.track_ids.size() == f.points.size();
}

track::HomographyOptions EstimateOptions(const MatchOptions& options) {
  track::HomographyOptions h;
  h.ransac_threshold_px = options.ransac_threshold_px;
  h.min_inliers = options.min_inliers;
  // The robust threshold at 6 sigmas (homography.h); kLarger inflates it when the residuals of
  // two separate Harris detections say the points are noisier.
  h.measurement_sigma_px = options.ransac_threshold_px / 6.0;
  h.noise_scale = track::NoiseScale::kLarger;
  return h;
}

std::optional<Link> Verify(const KeyFrameFeatures& a, const KeyFrameFeatures& b,
                           const std::vector<track::Correspondence>& matches, LinkKind kind,
                           int width, int height, const MatchOptions& options) {
  if (static_cast<int>(matches.size()) < options.min_inliers) return std::nullopt;
  StatusOr<track::HomographyEstimate> estimate =
      track::EstimateHomography(matches, EstimateOptions(options));
  if (!estimate.ok()) return std::nullopt;
  if (static_cast<int>(estimate->inliers.size()) < options.min_inliers) return std::nullopt;
  if (!PlausibleHomography(estimate->target_from_source, width, height, options)) {
    return std::nullopt;
  }
  Link link;
  link.from = a.id;
  link.to = b.id;
  link.kind = kind;
  link.to_from_from = estimate->target_from_source;
  link.covariance = estimate->covariance;
  link.correspondences = std::move(estimate).value().inliers;
  return link;
}

// Area of the convex polygon `polygon` clipped to [x0, x1] x [y0, y1] (Sutherland-Hodgman).
double ClippedArea(std::vector<Eigen::Vector2d> polygon, double x0, double y0, double x1,
                   double y1) {
  // Keep the side where dot(normal, p) <= limit, for the four half-planes of the rectangle.
  const std::array<std::pair<Eigen::Vector2d, double>, 4> planes = {
      std::pair{Eigen::Vector2d(-1, 0), -x0}, std::pair{Eigen::Vector2d(1, 0), x1},
      std::pair{Eigen::Vector2d(0, -1), -y0}, std::pair{Eigen::Vector2d(0, 1), y1}};
  for (const auto& [normal, limit] : planes) {
    std::vector<Eigen::Vector2d> out;
    for (size_t i = 0; i < polygon.size(); ++i) {
      const Eigen::Vector2d& p = polygon[i];
      const Eigen::Vector2d& q = polygon[(i + 1) % polygon.size()];
      const double dp = normal.dot(p) - limit, dq = normal.dot(q) - limit;
      if (dp <= 0) out.push_back(p);
      if ((dp < 0 && dq > 0) || (dp > 0 && dq < 0)) out.push_back(p + (q - p) * (dp / (dp - dq)));
    }
    polygon = std::move(out);
    if (polygon.empty()) return 0;
  }
  double twice = 0;
  for (size_t i = 0; i < polygon.size(); ++i) {
    const Eigen::Vector2d& p = polygon[i];
    const Eigen::Vector2d& q = polygon[(i + 1) % polygon.size()];
    twice += p.x() * q.y() - q.x() * p.y();
  }
  return 0.5 * std::abs(twice);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Options

Status DescribeOptions::Validate() const {
  if (!(keypoint_size_px >= 1 && keypoint_size_px <= 100)) {
    return InvalidArgumentError(Describe("keypoint_size_px", keypoint_size_px) +
                                " must be in [1, 100] px");
  }
  if (max_features < 1) {
    return InvalidArgumentError(Describe("max_features", max_features) + " must be >= 1");
  }
  if (!(orientation_blur_sigma_px >= 0 && orientation_blur_sigma_px <= 10)) {
    return InvalidArgumentError(Describe("orientation_blur_sigma_px", orientation_blur_sigma_px) +
                                " must be in [0, 10] px");
  }
  return Status::Ok();
}

Status MatchOptions::Validate() const {
  if (!(ratio > 0 && ratio <= 1)) {
    return InvalidArgumentError(Describe("ratio", ratio) + " must be in (0, 1]");
  }
  if (min_inliers < 5) {
    return InvalidArgumentError(Describe("min_inliers", min_inliers) + " must be >= 5");
  }
  if (!(ransac_threshold_px > 0 && ransac_threshold_px <= 100)) {
    return InvalidArgumentError(Describe("ransac_threshold_px", ransac_threshold_px) +
                                " must be in (0, 100] px");
  }
  if (!(confidence > 0 && confidence < 1)) {
    return InvalidArgumentError(Describe("confidence", confidence) + " must be in (0, 1)");
  }
  if (!(point_sigma_px >= 0 && point_sigma_px <= 100)) {
    return InvalidArgumentError(Describe("point_sigma_px", point_sigma_px) +
                                " must be in [0, 100] px");
  }
  if (!(max_descriptor_distance > 0)) {
    return InvalidArgumentError(Describe("max_descriptor_distance", max_descriptor_distance) +
                                " must be > 0");
  }
  if (!(min_scale > 0 && min_scale <= 1)) {
    return InvalidArgumentError(Describe("min_scale", min_scale) + " must be in (0, 1]");
  }
  if (!(max_scale >= 1 && std::isfinite(max_scale))) {
    return InvalidArgumentError(Describe("max_scale", max_scale) + " must be finite and >= 1");
  }
  if (!(max_anisotropy >= 1 && std::isfinite(max_anisotropy))) {
    return InvalidArgumentError(Describe("max_anisotropy", max_anisotropy) +
                                " must be finite and >= 1");
  }
  if (!(max_perspective >= 1 && std::isfinite(max_perspective))) {
    return InvalidArgumentError(Describe("max_perspective", max_perspective) +
                                " must be finite and >= 1");
  }
  if (!(min_overlap_fraction >= 0 && min_overlap_fraction <= 1)) {
    return InvalidArgumentError(Describe("min_overlap_fraction", min_overlap_fraction) +
                                " must be in [0, 1]");
  }
  return Status::Ok();
}

Status AppearanceIndexOptions::Validate() const {
  if (words < 2) return InvalidArgumentError(Describe("words", words) + " must be >= 2");
  if (training_key_frames < 1) {
    return InvalidArgumentError(Describe("training_key_frames", training_key_frames) +
                                " must be >= 1");
  }
  if (kmeans_iterations < 1) {
    return InvalidArgumentError(Describe("kmeans_iterations", kmeans_iterations) + " must be >= 1");
  }
  if (max_training_descriptors < words) {
    return InvalidArgumentError(Describe("max_training_descriptors", max_training_descriptors) +
                                " must be >= words");
  }
  return Status::Ok();
}

// ---------------------------------------------------------------------------------------------
// Descriptors

KeyFrameFeatures DescribeKeyFrame(KeyFrameId id, const cv::Mat& grey_in, double scale,
                                  const std::vector<track::StationaryPoint>& points,
                                  const DescribeOptions& options) {
  SAKER_CHECK(options.Validate().ok()) << options.Validate().ToString();
  SAKER_CHECK(scale > 0 && std::isfinite(scale)) << "scale = " << scale;
  KeyFrameFeatures features;
  features.id = id;
  features.descriptors = cv::Mat(0, 128, CV_32F);
  if (grey_in.empty() || points.empty()) return features;

  cv::Mat grey = grey_in;
  if (grey.channels() == 3) {
    cv::cvtColor(grey_in, grey, cv::COLOR_BGR2GRAY);
  } else if (grey.channels() == 4) {
    cv::cvtColor(grey_in, grey, cv::COLOR_BGRA2GRAY);
  } else if (grey.channels() != 1) {
    return features;
  }
  if (grey.depth() != CV_8U) grey.convertTo(grey, CV_8U);

  const double size = options.keypoint_size_px;
  const double margin = DescriptorHalfSide(size);
  struct Candidate {
    size_t input;  // index into points
    cv::Point2f at;
    Orientation orientation;
  };
  std::vector<Candidate> candidates;
  candidates.reserve(points.size());
  // SIFT's orientation window: sigma 1.5 x the keypoint scale (size / 2).
  const OrientationEstimator orientation(grey, options.orientation_blur_sigma_px, 0.75 * size);
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector2d& p = points[i].second;
    if (!p.allFinite()) continue;
    // cv::resize(full, 1 / scale) maps pixel centres x_full -> (x_full + 0.5) / scale - 0.5.
    const double x = (p.x() + 0.5) / scale - 0.5, y = (p.y() + 0.5) / scale - 0.5;
    if (x < margin || y < margin || x > grey.cols - 1 - margin || y > grey.rows - 1 - margin) {
      continue;
    }
    const Orientation o =
        orientation.At(static_cast<int>(std::lround(x)), static_cast<int>(std::lround(y)));
    candidates.push_back({i, cv::Point2f(static_cast<float>(x), static_cast<float>(y)), o});
  }
  if (candidates.empty()) return features;

  if (static_cast<int>(candidates.size()) > options.max_features) {
    // Round robin over a grid: every cell's strongest first, then every cell's second...
    std::vector<std::vector<size_t>> cells(kSelectionGrid * kSelectionGrid);
    for (size_t k = 0; k < candidates.size(); ++k) {
      const int cx = std::clamp(static_cast<int>(candidates[k].at.x * kSelectionGrid / grey.cols),
                                0, kSelectionGrid - 1);
      const int cy = std::clamp(static_cast<int>(candidates[k].at.y * kSelectionGrid / grey.rows),
                                0, kSelectionGrid - 1);
      cells[cy * kSelectionGrid + cx].push_back(k);
    }
    std::vector<std::pair<size_t, double>> rank;  // (candidate, rank key)
    for (std::vector<size_t>& cell : cells) {
      std::stable_sort(cell.begin(), cell.end(), [&](size_t l, size_t r) {
        return candidates[l].orientation.strength > candidates[r].orientation.strength;
      });
      for (size_t r = 0; r < cell.size(); ++r) rank.emplace_back(cell[r], static_cast<double>(r));
    }
    std::stable_sort(rank.begin(), rank.end(), [&](const auto& l, const auto& r) {
      if (l.second != r.second) return l.second < r.second;
      return candidates[l.first].orientation.strength > candidates[r.first].orientation.strength;
    });
    std::vector<size_t> keep;
    for (int k = 0; k < options.max_features; ++k) keep.push_back(rank[k].first);
    std::sort(keep.begin(), keep.end());  // back to input order
    std::vector<Candidate> kept;
    kept.reserve(keep.size());
    for (size_t k : keep) kept.push_back(candidates[k]);
    candidates = std::move(kept);
  }

  std::vector<cv::KeyPoint> keypoints;
  keypoints.reserve(candidates.size());
  for (size_t k = 0; k < candidates.size(); ++k) {
    cv::KeyPoint kp(candidates[k].at, static_cast<float>(size),
                    static_cast<float>(candidates[k].orientation.angle_deg));
    kp.octave = 0;  // octave 0, layer 0: the image itself at SIFT's base blur
    kp.class_id = static_cast<int>(k);
    keypoints.push_back(kp);
  }
  cv::Mat descriptors;
  cv::Ptr<cv::SIFT> sift = cv::SIFT::create();
  sift->compute(grey, keypoints, descriptors);
  if (descriptors.empty() || descriptors.rows != static_cast<int>(keypoints.size()))
    return features;
  if (descriptors.type() != CV_32F) descriptors.convertTo(descriptors, CV_32F);

  features.points.reserve(keypoints.size());
  features.track_ids.reserve(keypoints.size());
  features.descriptors = cv::Mat(static_cast<int>(keypoints.size()), descriptors.cols, CV_32F);
  for (size_t r = 0; r < keypoints.size(); ++r) {
    const int k = keypoints[r].class_id;
    SAKER_CHECK(k >= 0 && static_cast<size_t>(k) < candidates.size());
    const track::StationaryPoint& p = points[candidates[k].input];
    features.points.push_back(p.second);
    features.track_ids.push_back(p.first);
    descriptors.row(static_cast<int>(r)).copyTo(features.descriptors.row(static_cast<int>(r)));
  }
  return features;
}

// ---------------------------------------------------------------------------------------------
// Matching

bool PlausibleHomography(const Eigen::Matrix3d& b_from_a_in, int width, int height,
                         const MatchOptions& options) {
  if (width <= 0 || height <= 0 || !b_from_a_in.allFinite()) return false;
  const double norm = b_from_a_in.norm();
  if (!(norm > 0)) return false;
  Eigen::Matrix3d h = b_from_a_in / norm;
  const std::array<Eigen::Vector2d, 4> corners = track::ImageCorners(width, height);
  std::array<double, 4> w{};
  for (int i = 0; i < 4; ++i) w[i] = h.row(2).transpose().dot(corners[i].homogeneous());
  // A homography is defined up to scale, sign included: make w positive if it can be.
  if (w[0] < 0) {
    h = -h;
    for (double& v : w) v = -v;
  }
  const double w_min = *std::min_element(w.begin(), w.end());
  const double w_max = *std::max_element(w.begin(), w.end());
  // All corners in front (w is linear, so then the whole image is) and little perspective.
  if (!(w_min > 1e-12) || w_max > options.max_perspective * w_min) return false;
  const double det = h.determinant();
  if (!(det > 0)) return false;  // mirrored (or degenerate)

  auto jacobian = [&](const Eigen::Vector2d& p, double wp) {
    const Eigen::Vector2d q = (h.topRows<2>() * p.homogeneous()) / wp;
    return Eigen::Matrix2d((h.topLeftCorner<2, 2>() - q * h.block<1, 2>(2, 0)) / wp);
  };
  for (int i = 0; i < 4; ++i) {
    // det J = det(H) / w^3: its extremes over the image are at the corners.
    const double local_scale = std::sqrt(det / (w[i] * w[i] * w[i]));
    if (local_scale < options.min_scale || local_scale > options.max_scale) return false;
  }
  std::vector<Eigen::Vector2d> checks(corners.begin(), corners.end());
  checks.emplace_back(0.5 * (width - 1), 0.5 * (height - 1));
  for (const Eigen::Vector2d& p : checks) {
    const double wp = h.row(2).transpose().dot(p.homogeneous());
    const Eigen::Vector2d s = Eigen::JacobiSVD<Eigen::Matrix2d>(jacobian(p, wp)).singularValues();
    if (!(s(1) > 0) || s(0) > options.max_anisotropy * s(1)) return false;
  }
  // Overlap: a's image (pixel edges) mapped into b, clipped to b's image.
  const double x0 = -0.5, y0 = -0.5, x1 = width - 0.5, y1 = height - 0.5;
  std::vector<Eigen::Vector2d> quad;
  for (const Eigen::Vector2d& c : {Eigen::Vector2d(x0, y0), Eigen::Vector2d(x1, y0),
                                   Eigen::Vector2d(x1, y1), Eigen::Vector2d(x0, y1)}) {
    const Eigen::Vector3d m = h * c.homogeneous();
    if (!(m.z() > 0)) return false;
    quad.push_back(m.head<2>() / m.z());
  }
  const double overlap =
      ClippedArea(std::move(quad), x0, y0, x1, y1) / (static_cast<double>(width) * height);
  return overlap >= options.min_overlap_fraction;
}

std::optional<Link> MatchGeometric(
    const KeyFrameFeatures& a, const KeyFrameFeatures& b, const Eigen::Matrix3d& b_from_a_predicted,
    const std::function<Eigen::Matrix2d(const Eigen::Vector2d&)>& covariance_in_b, int width,
    int height, const MatchOptions& options) {
  SAKER_CHECK(options.Validate().ok()) << options.Validate().ToString();
  if (!UsableFeatures(a) || !UsableFeatures(b) || a.descriptors.cols != b.descriptors.cols ||
      width <= 0 || height <= 0 || !b_from_a_predicted.allFinite() || !covariance_in_b) {
    return std::nullopt;
  }
  if (static_cast<int>(a.size()) < options.min_inliers ||
      static_cast<int>(b.size()) < options.min_inliers) {
    return std::nullopt;
  }
  // b's points on a grid of cells, so an ellipse visits only the cells of its bounding box.
  constexpr double kCell = 32;
  const int grid_cols = static_cast<int>(std::ceil(width / kCell)),
            grid_rows = static_cast<int>(std::ceil(height / kCell));
  std::vector<std::vector<int>> grid(static_cast<size_t>(grid_cols) * grid_rows);
  auto cell_of = [&](double v, int cells) {
    return std::clamp(static_cast<int>(v / kCell), 0, cells - 1);
  };
  for (size_t j = 0; j < b.size(); ++j) {
    const Eigen::Vector2d& q = b.points[j];
    if (!q.allFinite()) continue;
    grid[static_cast<size_t>(cell_of(q.y(), grid_rows)) * grid_cols + cell_of(q.x(), grid_cols)]
        .push_back(static_cast<int>(j));
  }
  const double gate = -2.0 * std::log(1.0 - options.confidence);  // chi-square, 2 dof
  const double sigma2 = options.point_sigma_px * options.point_sigma_px;
  const float max_distance2 =
      static_cast<float>(options.max_descriptor_distance * options.max_descriptor_distance);
  const float ratio2 = static_cast<float>(options.ratio * options.ratio);
  const int dims = a.descriptors.cols;

  std::vector<int> best_of_b(b.size(), -1);  // a index claiming each b feature
  std::vector<float> best_distance_of_b(b.size(), std::numeric_limits<float>::max());
  for (size_t i = 0; i < a.size(); ++i) {
    const Eigen::Vector2d& p = a.points[i];
    if (!p.allFinite()) continue;
    const double wp = b_from_a_predicted.row(2).transpose().dot(p.homogeneous());
    if (!(std::abs(wp) > 1e-12)) continue;
    const Eigen::Vector2d predicted = (b_from_a_predicted.topRows<2>() * p.homogeneous()) / wp;
    const Eigen::Matrix2d j = track::TransferPointJacobian(b_from_a_predicted, p);
    const Eigen::Matrix2d cov =
        covariance_in_b(p) + sigma2 * (Eigen::Matrix2d::Identity() + j * j.transpose());
    if (!cov.allFinite() || !predicted.allFinite()) continue;
    const double det = cov.determinant();
    if (!(cov(0, 0) > 0 && det > 0)) continue;
    const Eigen::Matrix2d info = cov.inverse();
    const double half_x = std::sqrt(gate * cov(0, 0)), half_y = std::sqrt(gate * cov(1, 1));
    if (predicted.x() + half_x < 0 || predicted.x() - half_x > width - 1 ||
        predicted.y() + half_y < 0 || predicted.y() - half_y > height - 1) {
      continue;
    }
    const int c0 = cell_of(predicted.x() - half_x, grid_cols);
    const int c1 = cell_of(predicted.x() + half_x, grid_cols);
    const int r0 = cell_of(predicted.y() - half_y, grid_rows);
    const int r1 = cell_of(predicted.y() + half_y, grid_rows);
    const float* da = a.descriptors.ptr<float>(static_cast<int>(i));
    float best = std::numeric_limits<float>::max(), second = best;
    int best_j = -1;
    for (int r = r0; r <= r1; ++r) {
      for (int c = c0; c <= c1; ++c) {
        for (int jb : grid[static_cast<size_t>(r) * grid_cols + c]) {
          const Eigen::Vector2d d = b.points[jb] - predicted;
          if (d.dot(info * d) > gate) continue;
          const float distance2 = SquaredDistance(da, b.descriptors.ptr<float>(jb), dims);
          if (distance2 < best) {
            second = best;
            best = distance2;
            best_j = jb;
          } else if (distance2 < second) {
            second = distance2;
          }
        }
      }
    }
    if (best_j < 0 || best > max_distance2) continue;
    if (second < std::numeric_limits<float>::max() && best > ratio2 * second) continue;
    if (best < best_distance_of_b[best_j]) {
      best_distance_of_b[best_j] = best;
      best_of_b[best_j] = static_cast<int>(i);
    }
  }
  std::vector<track::Correspondence> matches;
  for (size_t jb = 0; jb < b.size(); ++jb) {
    if (best_of_b[jb] < 0) continue;
    const size_t i = static_cast<size_t>(best_of_b[jb]);
    matches.push_back({a.track_ids[i], a.points[i], b.points[jb]});
  }
  return Verify(a, b, matches, LinkKind::kGeometric, width, height, options);
}

std::optional<Link> MatchAppearance(const KeyFrameFeatures& a, const KeyFrameFeatures& b, int width,
                                    int height, const MatchOptions& options) {
  SAKER_CHECK(options.Validate().ok()) << options.Validate().ToString();
  if (!UsableFeatures(a) || !UsableFeatures(b) || a.descriptors.cols != b.descriptors.cols ||
      width <= 0 || height <= 0) {
    return std::nullopt;
  }
  if (static_cast<int>(a.size()) < options.min_inliers ||
      static_cast<int>(b.size()) < options.min_inliers) {
    return std::nullopt;
  }
  cv::BFMatcher matcher(cv::NORM_L2);
  std::vector<std::vector<cv::DMatch>> forward;
  std::vector<cv::DMatch> backward;
  matcher.knnMatch(a.descriptors, b.descriptors, forward, 2);
  matcher.match(b.descriptors, a.descriptors, backward);
  std::vector<int> nearest_in_a(b.size(), -1);
  for (const cv::DMatch& m : backward) nearest_in_a[static_cast<size_t>(m.queryIdx)] = m.trainIdx;

  std::vector<track::Correspondence> matches;
  for (const std::vector<cv::DMatch>& knn : forward) {
    if (knn.empty()) continue;
    const cv::DMatch& best = knn[0];
    if (best.distance > options.max_descriptor_distance) continue;
    if (knn.size() > 1 && best.distance > options.ratio * knn[1].distance) continue;
    if (nearest_in_a[static_cast<size_t>(best.trainIdx)] != best.queryIdx) continue;
    const size_t i = static_cast<size_t>(best.queryIdx), j = static_cast<size_t>(best.trainIdx);
    matches.push_back({a.track_ids[i], a.points[i], b.points[j]});
  }
  return Verify(a, b, matches, LinkKind::kAppearance, width, height, options);
}

// ---------------------------------------------------------------------------------------------
// Appearance index

AppearanceIndex::AppearanceIndex(const AppearanceIndexOptions& options) : options_(options) {
  SAKER_CHECK(options.Validate().ok()) << options.Validate().ToString();
}

void AppearanceIndex::Add(const KeyFrameFeatures& features) {
  const uint32_t frame = static_cast<uint32_t>(ids_.size());
  ids_.push_back(features.id);
  cv::Mat descriptors = features.descriptors;
  if (!descriptors.empty() && descriptors.type() != CV_32F) {
    descriptors.convertTo(descriptors, CV_32F);
  }
  if (trained()) {
    Index(frame, descriptors);
    return;
  }
  pending_.push_back(descriptors.empty() ? cv::Mat() : descriptors.clone());
  int total = 0;
  for (const cv::Mat& d : pending_) total += d.rows;
  if (static_cast<int>(ids_.size()) >= options_.training_key_frames && total >= options_.words) {
    if (Train()) {
      for (uint32_t f = 0; f < pending_.size(); ++f) Index(f, pending_[f]);
      pending_.clear();
    }
  }
}

bool AppearanceIndex::Train() {
  int total = 0, cols = 0;
  for (const cv::Mat& d : pending_) {
    total += d.rows;
    if (!d.empty()) cols = d.cols;
  }
  // Every step-th descriptor over the frames in order, at most max_training_descriptors.
  const int step =
      (total + options_.max_training_descriptors - 1) / options_.max_training_descriptors;
  cv::Mat data(0, cols, CV_32F);
  data.reserve(static_cast<size_t>(total / step + 1));
  int index = 0;
  for (const cv::Mat& d : pending_) {
    if (d.cols != cols) {
      index += d.rows;
      continue;
    }
    for (int r = 0; r < d.rows; ++r, ++index) {
      if (index % step == 0) data.push_back(d.row(r));
    }
  }
  if (data.rows < options_.words) return false;
  // cv::kmeans draws from cv::theRNG() (thread-local): seed it for a deterministic vocabulary,
  // then give the caller's generator back.
  cv::RNG& rng = cv::theRNG();
  const cv::RNG saved = rng;
  rng.state = options_.seed != 0 ? options_.seed : 0x9E3779B97F4A7C15ull;
  cv::Mat labels, centres;
  cv::kmeans(data, options_.words, labels,
             cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS,
                              options_.kmeans_iterations, 1e-3),
             1, cv::KMEANS_PP_CENTERS, centres);
  rng = saved;
  vocabulary_ = centres;
  postings_.assign(static_cast<size_t>(vocabulary_.rows), {});
  return true;
}

std::vector<std::pair<int, float>> AppearanceIndex::Histogram(const cv::Mat& descriptors) const {
  std::vector<std::pair<int, float>> histogram;
  if (descriptors.empty() || descriptors.cols != vocabulary_.cols) return histogram;
  cv::Mat query = descriptors;
  if (query.type() != CV_32F) query.convertTo(query, CV_32F);
  cv::Mat distances, nearest;
  cv::batchDistance(query, vocabulary_, distances, CV_32F, nearest, cv::NORM_L2SQR, 1);
  std::vector<int> counts(static_cast<size_t>(vocabulary_.rows), 0);
  for (int r = 0; r < nearest.rows; ++r) {
    const int word = nearest.at<int>(r, 0);
    if (word >= 0 && word < vocabulary_.rows) ++counts[static_cast<size_t>(word)];
  }
  const float inv_total = 1.0f / static_cast<float>(std::max(1, query.rows));
  for (size_t w = 0; w < counts.size(); ++w) {
    if (counts[w] > 0)
      histogram.emplace_back(static_cast<int>(w), static_cast<float>(counts[w]) * inv_total);
  }
  return histogram;
}

void AppearanceIndex::Index(uint32_t frame, const cv::Mat& descriptors) {
  for (const auto& [word, tf] : Histogram(descriptors)) {
    postings_[static_cast<size_t>(word)].push_back({frame, tf});
  }
}

std::vector<std::pair<KeyFrameId, double>> AppearanceIndex::Query(
    const KeyFrameFeatures& features, int count,
    const std::function<bool(KeyFrameId)>& skip) const {
  std::vector<std::pair<KeyFrameId, double>> result;
  if (count <= 0) return result;
  auto skipped = [&](KeyFrameId id) { return id == features.id || (skip && skip(id)); };
  if (!trained()) {
    for (size_t f = ids_.size(); f-- > 0 && static_cast<int>(result.size()) < count;) {
      if (!skipped(ids_[f])) result.emplace_back(ids_[f], 0.0);
    }
    return result;
  }
  const double frames = static_cast<double>(ids_.size());
  std::vector<double> scores(ids_.size(), 0.0);
  std::vector<uint32_t> touched;
  for (const auto& [word, tf] : Histogram(features.descriptors)) {
    const std::vector<Posting>& postings = postings_[static_cast<size_t>(word)];
    if (postings.empty()) continue;
    const double idf = std::log(1.0 + frames / static_cast<double>(postings.size()));
    for (const Posting& p : postings) {
      if (scores[p.frame] == 0) touched.push_back(p.frame);
      scores[p.frame] += idf * std::min(tf, p.tf);
    }
  }
  std::vector<std::pair<KeyFrameId, double>> candidates;
  candidates.reserve(touched.size());
  for (uint32_t f : touched) {
    if (!skipped(ids_[f])) candidates.emplace_back(ids_[f], scores[f]);
  }
  const auto better = [](const auto& l, const auto& r) {
    if (l.second != r.second) return l.second > r.second;
    return static_cast<int>(l.first) < static_cast<int>(r.first);
  };
  const size_t keep = std::min(candidates.size(), static_cast<size_t>(count));
  std::partial_sort(candidates.begin(), candidates.begin() + static_cast<ptrdiff_t>(keep),
                    candidates.end(), better);
  candidates.resize(keep);
  return candidates;
}

}  // namespace saker::mosaic
