#include "core/track/horizon.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace saker::track {

namespace {

constexpr int kReducedWidth = 256;  // the reduced image the lines are tried on
constexpr double kTiltStepDeg = 2.5;

// Sums over pixels of 1 and of the gradient.
using Moments = std::array<double, 2>;

}  // namespace

Status HorizonOptions::Validate() const {
  if (!(max_tilt_deg >= 0 && max_tilt_deg <= 45)) {
    return InvalidArgumentError("horizon: the tilt tried must be 0 .. 45 degrees");
  }
  if (!(min_sky_fraction > 0 && min_sky_fraction < max_sky_fraction && max_sky_fraction < 1)) {
    return InvalidArgumentError("horizon: sky fractions must satisfy 0 < min < max < 1");
  }
  if (!(max_texture_ratio > 0 && max_texture_ratio < 1)) {
    return InvalidArgumentError("horizon: the texture ratio must be in (0, 1)");
  }
  if (!(margin_fraction >= 0 && margin_fraction <= 0.5)) {
    return InvalidArgumentError("horizon: the margin must be 0 .. 0.5 of the frame's height");
  }
  if (!(window_s > 0 && window_s <= 60) || min_window_frames < 1) {
    return InvalidArgumentError("horizon: the window must be (0, 60] s and at least one frame");
  }
  return Status::Ok();
}

std::optional<HorizonLine> FindHorizon(const cv::Mat& grey, const HorizonOptions& options) {
  if (grey.empty() || grey.type() != CV_8UC1 || grey.cols < 16 || grey.rows < 16) {
    return std::nullopt;
  }
  // About kReducedWidth across: a large frame that divides by a whole-number factor near its
  // reduction is reduced by that factor (240 across from 1920x1080, 256 from 1280x720), a plain
  // box average (0.06 ms at 1080p, against 2.1 ms for OpenCV's area filter at the fractional
  // 7.5x, which was two thirds of this search); others by the fractional area filter.
  const int factor =
      std::max(1, static_cast<int>(std::lround(static_cast<double>(grey.cols) / kReducedWidth)));
  int width = kReducedWidth;
  int height = std::max(
      16, static_cast<int>(std::lround(static_cast<double>(grey.rows) * width / grey.cols)));
  if (factor >= 4 && grey.cols % factor == 0 && grey.rows % factor == 0 &&
      grey.rows / factor >= 16) {
    width = grey.cols / factor;
    height = grey.rows / factor;
  }
  cv::Mat small, intensity, gx, gy;
  cv::resize(grey, small, cv::Size(width, height), 0, 0, cv::INTER_AREA);
  small.convertTo(intensity, CV_32F);
  // The reduction averages away the noise; no more smoothing, which would spread the ground's
  // texture into the sky and pull the line up.
  cv::Sobel(intensity, gx, CV_32F, 1, 0);
  cv::Sobel(intensity, gy, CV_32F, 0, 1);
  // Column-major, so that each column's pixels add to consecutive buckets below.
  cv::Mat texture;
  cv::transpose(cv::abs(gx) + cv::abs(gy), texture);

  const double centre_x = (width - 1) / 2.0;
  const double pixels = static_cast<double>(width) * height;
  double best_score = 0;
  double best_y = 0, best_slope = 0, best_sky = 0, best_ground = 0;
  const int steps = static_cast<int>(std::floor(options.max_tilt_deg / kTiltStepDeg + 1e-9));
  std::vector<Moments> sums;
  std::vector<double> counts, gradients;
  for (int k = -steps; k <= steps; ++k) {
    const double slope = std::tan(k * kTiltStepDeg * M_PI / 180.0);
    // Each pixel falls in the bucket of its line offset at the centre, y - slope (x - centre_x).
    const int offset = static_cast<int>(std::ceil(std::abs(slope) * centre_x)) + 1;
    const int buckets = height + 2 * offset + 1;
    // Row y's pixel x goes to bucket y + first(x) - 1 (the offset keeps it in 0 .. buckets - 1):
    // the column's part of the rounding is computed once per line, not per pixel, and each column
    // adds its pixels to a run of consecutive buckets (pixel by pixel, with the per-pixel sums,
    // this search took 3 % of the front end's time on a nadir view). The gradients are whole
    // numbers (Sobel of 8-bit grey levels), so the sums are exact in any order.
    counts.assign(static_cast<size_t>(buckets) + 1, 0.0);
    gradients.assign(static_cast<size_t>(buckets) + 1, 0.0);
    for (int x = 0; x < width; ++x) {
      const int first = static_cast<int>(std::floor(0.5 - slope * (x - centre_x))) + offset + 1;
      // The column covers buckets first - 1 .. first + height - 2, counted by their differences.
      counts[static_cast<size_t>(first - 1)] += 1;
      counts[static_cast<size_t>(first - 1 + height)] -= 1;
      const float* column = texture.ptr<float>(x);
      double* run = gradients.data() + (first - 1);
      for (int y = 0; y < height; ++y) run[y] += column[y];
    }
    // sums[b]: the pixels and gradient of buckets 0 .. b - 1 (the bucket's own count is the
    // running sum of its differences).
    sums.assign(static_cast<size_t>(buckets) + 1, Moments{});
    double in_bucket = 0;
    for (size_t b = 0; b < static_cast<size_t>(buckets); ++b) {
      in_bucket += counts[b];
      sums[b + 1] = {sums[b][0] + in_bucket, sums[b][1] + gradients[b]};
    }
    const Moments& total = sums.back();
    // Cut before bucket b: the sky is the buckets below it (rows above the line). The score is the
    // gradient's variance between the two sides (Otsu's criterion), the smoother side above.
    for (int b = 1; b < buckets; ++b) {
      const Moments& sky = sums[static_cast<size_t>(b)];
      const double fraction = sky[0] / pixels;
      if (fraction < options.min_sky_fraction || fraction > options.max_sky_fraction) continue;
      const double sky_texture = sky[1] / sky[0];
      const double ground_texture = (total[1] - sky[1]) / (total[0] - sky[0]);
      const double gap = ground_texture - sky_texture;
      const double score = fraction * (1 - fraction) * gap * gap;
      if (gap > 0 && score > best_score) {
        best_score = score;
        best_y = b - offset - 0.5;
        best_slope = slope;
        best_sky = sky_texture;
        best_ground = ground_texture;
      }
    }
  }
  if (!(best_score > 0) || !(best_sky < options.max_texture_ratio * best_ground)) {
    return std::nullopt;
  }
  // Back to full-resolution pixels (pixel centres at integers in both).
  const double sx = static_cast<double>(grey.cols) / width;
  const double sy = static_cast<double>(grey.rows) / height;
  HorizonLine line;
  line.centre_x = (grey.cols - 1) / 2.0;
  line.y_at_centre = (best_y + 0.5) * sy - 0.5;
  line.slope = best_slope * sy / sx;
  return line;
}

HorizonTracker::HorizonTracker(const HorizonOptions& options, const FrameRate& rate)
    : options_(options), window_frames_(rate.Frames(options.window_s, options.min_window_frames)) {}

std::optional<HorizonLine> HorizonTracker::Add(const cv::Mat& grey, bool on_ground) {
  if (!options_.enabled) return std::nullopt;
  const std::optional<HorizonLine> found = on_ground ? std::nullopt : FindHorizon(grey, options_);
  found_line_ = found;
  margin_px_ = options_.margin_fraction * grey.rows;
  found_.push_back(found.has_value());
  while (static_cast<int>(found_.size()) > window_frames_) found_.pop_front();
  if (found) latest_ = found;
  const auto hits = std::count(found_.begin(), found_.end(), true);
  const bool enough = static_cast<int>(found_.size()) >= std::min(window_frames_, 3) &&
                      2 * hits > static_cast<int64_t>(found_.size());
  line_ = enough ? latest_ : std::nullopt;
  return line_;
}

bool HorizonTracker::Masks(const Eigen::Vector2d& p) const {
  return line_ && p.y() < line_->YAt(p.x()) + margin_px_;
}

void HorizonTracker::Reset() {
  found_.clear();
  latest_.reset();
  found_line_.reset();
  line_.reset();
}

}  // namespace saker::track
