#include "core/track/change_detector.h"

#include "core/track/homography.h"
#include "core/util/byte_io.h"
#include "core/util/check.h"
#include "core/util/statistics.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <tuple>

namespace saker::track {
namespace {

// Full-resolution pixel homography to one between images scaled by 1/scale (pixel centres at
// integer coordinates, as cv::resize places them).
Eigen::Matrix3d ToSmallPixels(const Eigen::Matrix3d& full, double scale) {
  Eigen::Matrix3d small_from_full;
  const double s = 1.0 / scale, o = 0.5 * s - 0.5;
  small_from_full << s, 0, o, 0, s, o, 0, 0, 1;
  return small_from_full * full * small_from_full.inverse();
}

// A full-resolution point in the pixels of the copy scaled by 1/scale.
Eigen::Vector2d ToProcessing(const Eigen::Vector2d& p, double scale) {
  return {(p.x() + 0.5) / scale - 0.5, (p.y() + 0.5) / scale - 0.5};
}

// The largest squared gradient (central differences) in the 3x3 neighbourhood of (x, y).
float GradientSquared(const cv::Mat& image, int x, int y) {
  float largest = 0;
  for (int yy = std::max(1, y - 1); yy <= std::min(image.rows - 2, y + 1); ++yy) {
    const uint8_t* above = image.ptr<uint8_t>(yy - 1);
    const uint8_t* row = image.ptr<uint8_t>(yy);
    const uint8_t* below = image.ptr<uint8_t>(yy + 1);
    for (int xx = std::max(1, x - 1); xx <= std::min(image.cols - 2, x + 1); ++xx) {
      const float gx = 0.5f * (static_cast<float>(row[xx + 1]) - static_cast<float>(row[xx - 1]));
      const float gy = 0.5f * (static_cast<float>(below[xx]) - static_cast<float>(above[xx]));
      largest = std::max(largest, gx * gx + gy * gy);
    }
  }
  return largest;
}

// The mean squared gradient (central differences) of `image` where `cover` is set, on a sparse
// grid (every `step` rows and columns); 0 where nothing is covered.
double MeanSquaredGradient(const cv::Mat& image, const cv::Mat& cover, int step) {
  double sum = 0;
  int64_t count = 0;
  for (int y = 1; y + 1 < image.rows; y += step) {
    const uint8_t* above = image.ptr<uint8_t>(y - 1);
    const uint8_t* row = image.ptr<uint8_t>(y);
    const uint8_t* below = image.ptr<uint8_t>(y + 1);
    const uint8_t* v = cover.ptr<uint8_t>(y);
    for (int x = 1; x + 1 < image.cols; x += step) {
      if (v[x] == 0) continue;
      const double gx = 0.5 * (static_cast<double>(row[x + 1]) - static_cast<double>(row[x - 1]));
      const double gy = 0.5 * (static_cast<double>(below[x]) - static_cast<double>(above[x]));
      sum += gx * gx + gy * gy;
      ++count;
    }
  }
  return count > 0 ? sum / static_cast<double>(count) : 0;
}

// The sparse grid's step for an image: about 20 000 points, every fifth row and column at most.
int SparseStep(const cv::Mat& image) {
  return std::clamp(static_cast<int>(std::sqrt(static_cast<double>(image.total()) / 20000.0)), 1,
                    5);
}

// The gain that matches `warped`'s mean grey to `centre`'s where `cover` is set (gain drift);
// means over every fourth row and column: plenty for a gain.
float MeanGain(const cv::Mat& centre, const cv::Mat& warped, const cv::Mat& cover) {
  double sum_centre = 0, sum_other = 0;
  for (int y = 0; y < centre.rows; y += 4) {
    const uint8_t* c = centre.ptr<uint8_t>(y);
    const uint8_t* o = warped.ptr<uint8_t>(y);
    const uint8_t* v = cover.ptr<uint8_t>(y);
    for (int x = 0; x < centre.cols; x += 4) {
      if (v[x] == 0) continue;
      sum_centre += c[x];
      sum_other += o[x];
    }
  }
  return sum_other > 0 ? static_cast<float>(sum_centre / sum_other) : 1.0f;
}

}  // namespace

Status ChangeOptions::Validate() const {
  if (!(baseline_s > 0 && baseline_s <= 60) ||
      !(evidence_baseline_s >= 0 && evidence_baseline_s <= 60)) {
    return InvalidArgumentError(
        "change detection: the baseline must be in (0, 60] s and the evidence baseline in [0, 60] "
        "s");
  }
  if (processing_width < 0 || !(max_processing_gsd_m >= 0 && max_processing_gsd_m <= 1000)) {
    return InvalidArgumentError(
        "change detection: the processing width must be >= 0 and the largest processing pixel "
        "on the ground in [0, 1000] m");
  }
  if (!(measured_noise_multiple >= 0 && measured_noise_multiple <= 100) ||
      !(measured_registration_multiple >= 0 && measured_registration_multiple <= 100)) {
    return InvalidArgumentError(
        "change detection: the measured noise multiples must be in [0, 100]");
  }
  if (!(noise_grey > 0 && threshold > 0 && registration_px >= 0 && clean_registration_px > 0 &&
        min_contrast_grey >= 0)) {
    return InvalidArgumentError(
        "change detection: noise, threshold and clean video's registration allowance must be "
        "positive, the registration allowance and contrast >= 0");
  }
  if (!(sharpness_match_ratio == 0 ||
        (sharpness_match_ratio > 1 && sharpness_match_ratio <= 100))) {
    return InvalidArgumentError(
        "change detection: the sharpness ratio must be 0 (off) or in (1, 100]");
  }
  if (!(one_sided_min_uncovered >= 0 && one_sided_min_uncovered <= 1)) {
    return InvalidArgumentError(
        "change detection: the part of the frame left uncovered for one-sided comparisons must "
        "be in [0, 1]");
  }
  if (border_px < 0 || min_area_px < 1 || max_area_px < min_area_px) {
    return InvalidArgumentError("change detection: need border >= 0 and 1 <= min area <= max area");
  }
  return Status::Ok();
}

int ChangeOptions::ProcessingWidth(const cv::Size& size, const GroundScale* scale) const {
  if (size.width <= 0) return processing_width;  // unknown: the video's frames will tell
  if (processing_width <= 0 || processing_width >= size.width) return size.width;
  if (scale == nullptr || max_processing_gsd_m <= 0) return processing_width;
  const double full_gsd =
      scale->MetresPerPixel(Eigen::Vector2d(size.width - 1, size.height - 1) / 2);
  // (A thousandth of a pixel below a whole width is that width: the corners' rounding.)
  const double needed = std::ceil(size.width * full_gsd / max_processing_gsd_m - 1e-3);
  if (!(needed > processing_width)) return processing_width;
  return needed >= size.width ? size.width : static_cast<int>(needed);
}

ChangeDetector::ChangeDetector(const ChangeOptions& options, FrameRate rate) : options_(options) {
  SAKER_CHECK(options_.Validate().ok()) << options_.Validate().message();
  for (const int b : BaselineFrames(options, rate)) baselines_.push_back(static_cast<size_t>(b));
  lag_ = static_cast<size_t>(LagFrames(options, rate));
  history_frames_ = static_cast<size_t>(HistoryFrames(options, rate));
}

std::vector<int> ChangeDetector::BaselineFrames(const ChangeOptions& options, FrameRate rate) {
  constexpr int kMaxBaselineFrames = 100;
  std::vector<int> frames = {std::min(rate.Frames(options.baseline_s, 1), kMaxBaselineFrames)};
  if (options.evidence_baseline_s > 0 && !options.one_sided_edges) {
    const int evidence = std::min(rate.Frames(options.evidence_baseline_s, 1), kMaxBaselineFrames);
    if (evidence > frames[0]) frames.push_back(evidence);
  }
  return frames;
}

int ChangeDetector::LagFrames(const ChangeOptions& options, FrameRate rate) {
  const int b = BaselineFrames(options, rate).front();
  return options.one_sided_edges ? 2 * b : b;
}

int ChangeDetector::HistoryFrames(const ChangeOptions& options, FrameRate rate) {
  const int lag = LagFrames(options, rate);
  return std::max(lag, BaselineFrames(options, rate).back()) + 1 + lag;
}

void ChangeDetector::Reset() { history_.clear(); }

Eigen::Vector2d ChangeDetector::ToFull(double x, double y) const {
  return {(x + 0.5) * scale_ - 0.5, (y + 0.5) * scale_ - 0.5};
}

ChangeFrame ChangeDetector::Process(int64_t frame, const cv::Mat& grey,
                                    const std::optional<Eigen::Matrix3d>& current_from_previous) {
  SAKER_CHECK(grey.type() == CV_8UC1) << "change detection needs 8-bit grey frames";
  ChangeFrame result;
  if (!options_.enabled || grey.empty()) return result;
  if (grey.size() != full_size_) SetFrameSize(grey.size());
  if (!current_from_previous || !current_from_previous->allFinite()) history_.clear();

  // The centre frame is the one lag_ back, compared with the frames a baseline before and after
  // it; the history also holds the frames an evidence baseline before it.
  Remember(frame, grey, current_from_previous, history_frames_);
  if (history_.size() < 2 * lag_ + 1) return result;
  const size_t c = history_.size() - 1 - lag_;
  const size_t b = baselines_.front();
  const Entry& centre = history_[c];

  // Per pair: the two frames, and where both cover the centre frame. The centred pair first.
  // The answer's masks are its own (allocated here, never reused by the detector).
  cv::Mat valid;
  const auto compare = [&](size_t i, size_t first, size_t second) {
    if (!Warp(first, c, &pairs_[i][0]) || !Warp(second, c, &pairs_[i][1])) return false;
    cv::bitwise_and(pairs_[i][0].cover, pairs_[i][1].cover, covers_[i]);
    return true;
  };
  pairs_.resize(1);
  covers_.resize(1);
  if (!compare(0, c - b, c + b)) return result;  // a degenerate motion: no answer for this frame
  covers_[0].copyTo(valid);
  // The evidence pair: the frame an evidence baseline before and the one a baseline after, the
  // centred pair's, already warped (shared, not copied, as below). Where the centred pair cannot
  // look, the evidence pair does not count as looking (`valid`).
  evidence_pair_ = -1;
  if (baselines_.size() == 2 && c >= baselines_.back()) {
    pairs_.resize(2);
    covers_.resize(2);
    pairs_[1][1] = pairs_[0][1];
    if (Warp(c - baselines_.back(), c, &pairs_[1][0])) {
      cv::bitwise_and(pairs_[1][0].cover, pairs_[1][1].cover, covers_[1]);
      evidence_pair_ = 1;
    } else {
      pairs_.resize(1);
      covers_.resize(1);
    }
  }
  // The one-sided pairs, only where the centred ones cannot look and only when that is a good part
  // of the frame; the frame two baselines away has twice the allowance.
  const double uncovered =
      1.0 - static_cast<double>(cv::countNonZero(valid)) / static_cast<double>(valid.total());
  if (options_.one_sided_edges && uncovered >= options_.one_sided_min_uncovered) {
    const size_t before = pairs_.size(), after = before + 1;
    pairs_.resize(before + 2);
    covers_.resize(before + 2);
    // The frames a baseline away are the short centred pair's, already warped (shared, not
    // copied: they are warped again into that pair's buffers before they are shared next time).
    pairs_[before][1] = pairs_[0][0];
    pairs_[after][0] = pairs_[0][1];
    if (Warp(c - 2 * b, c, &pairs_[before][0], &valid) &&
        Warp(c + 2 * b, c, &pairs_[after][1], &valid)) {
      cv::bitwise_and(pairs_[before][0].cover, pairs_[before][1].cover, covers_[before]);
      cv::bitwise_and(pairs_[after][0].cover, pairs_[after][1].cover, covers_[after]);
      pairs_[before][0].allowance = pairs_[after][1].allowance = 2;
      covers_[before].setTo(0, valid);
      covers_[after].setTo(0, valid);
      cv::bitwise_or(valid, covers_[before], valid);
      cv::bitwise_or(valid, covers_[after], valid);
    } else {
      pairs_.resize(before);  // a degenerate motion that far: the centred answer alone
      covers_.resize(before);
    }
  }
  const cv::Mat& centre_image = MatchSharpness(centre.grey);
  MeasureNoise(centre_image, &history_[c], pairs_[0][0], pairs_[0][1], covers_[0]);
  SetAllowances(history_[c]);
  cv::Mat evidence_changed;
  cv::Mat changed = MarkChanged(centre_image, &evidence_changed);
  result.noise_grey = noise_;
  result.registration_px = allowance_;
  result.allowances_raised = noise_ > static_cast<float>(options_.noise_grey) ||
                             allowance_ > static_cast<float>(options_.clean_registration_px);
  result.blobs = FindBlobs(changed);
  result.frame = centre.frame;
  result.frame_motion = centre.motion;
  result.changed = std::move(changed);
  result.evidence_changed = std::move(evidence_changed);
  result.valid = std::move(valid);
  result.scale = scale_;
  return result;
}

void ChangeDetector::SetFrameSize(const cv::Size& size) {
  Reset();
  full_size_ = size;
  const int width =
      options_.processing_width > 0 ? std::min(options_.processing_width, size.width) : size.width;
  small_size_ =
      cv::Size(width, std::max(1, static_cast<int>(std::lround(static_cast<double>(size.height) *
                                                               width / size.width))));
  scale_ = static_cast<double>(size.width) / width;
}

void ChangeDetector::Remember(int64_t frame, const cv::Mat& grey,
                              const std::optional<Eigen::Matrix3d>& current_from_previous,
                              size_t capacity) {
  // The new frame takes the oldest one's buffer when the history is full.
  Entry entry;
  while (history_.size() >= capacity) {
    entry.grey = std::move(history_.front().grey);
    history_.pop_front();
  }
  entry.frame = frame;
  if (small_size_ == full_size_) {
    grey.copyTo(entry.grey);
  } else {
    // Area averaging: a walker is a pixel or two, bilinear sampling would skip half of it (it
    // cost one person of the demo's 25 for 0.8 ms a frame).
    cv::resize(grey, entry.grey, small_size_, 0, 0, cv::INTER_AREA);
  }
  if (current_from_previous) {
    entry.motion = *current_from_previous;
    entry.small_motion = ToSmallPixels(*current_from_previous, scale_);
  }
  history_.push_back(std::move(entry));
}

// The frame history_[index] warped onto the centre frame history_[centre], its mean grey matched
// to the centre's (gain drift), and where it covers the centre frame (inside its border). With
// `only_outside`, only where that mask is zero (and a few pixels round it, for the gradients) is
// warped, covered and counted for the gain: a one-sided pair is looked at only where the centred
// one cannot look, a band at the edge. The buffers are members, reused from frame to frame. False
// for a degenerate motion.
bool ChangeDetector::Warp(size_t index, size_t centre, Other* other, const cv::Mat* only_outside) {
  const int b = options_.border_px;
  Eigen::Matrix3d centre_from_other = Eigen::Matrix3d::Identity();
  if (index < centre) {
    for (size_t i = index + 1; i <= centre; ++i) {
      centre_from_other = history_[i].small_motion * centre_from_other;
    }
  } else {
    Eigen::Matrix3d other_from_centre = Eigen::Matrix3d::Identity();
    for (size_t i = centre + 1; i <= index; ++i) {
      other_from_centre = history_[i].small_motion * other_from_centre;
    }
    centre_from_other = other_from_centre.inverse();
  }
  const double w = small_size_.width - 1 - b, h = small_size_.height - 1 - b;
  std::array<cv::Point, 4> outline;
  const std::array<Eigen::Vector2d, 4> corners = {Eigen::Vector2d(b, b), Eigen::Vector2d(w, b),
                                                  Eigen::Vector2d(w, h), Eigen::Vector2d(b, h)};
  for (size_t k = 0; k < 4; ++k) {
    const Eigen::Vector3d p = centre_from_other * corners[k].homogeneous();
    if (!(p.z() > 0) || !p.allFinite()) return false;
    outline[k] = cv::Point(static_cast<int>(std::lround(std::clamp(p.x() / p.z(), -1e6, 1e6))),
                           static_cast<int>(std::lround(std::clamp(p.y() / p.z(), -1e6, 1e6))));
  }
  other->cover.create(small_size_, CV_8U);
  other->cover.setTo(0);
  cv::fillConvexPoly(other->cover, outline.data(), 4, cv::Scalar(255));
  if (b > 0) {
    cv::rectangle(other->cover, cv::Rect(0, 0, small_size_.width, small_size_.height),
                  cv::Scalar(0), 2 * b);
  }
  // Into `region` of the full-size buffer, the matrix shifted by its origin. A new buffer starts
  // black: a one-sided pair's comparison pass reads the rows of its band beyond the strips warped
  // (and ignores them), which must hold some grey level, if only an earlier frame's.
  const uint8_t* const previous_buffer = other->warped.data;
  other->warped.create(small_size_, CV_8U);
  if (other->warped.data != previous_buffer) other->warped.setTo(0);
  const auto warp_into = [&](const cv::Rect& region) {
    Eigen::Matrix3d region_from_other = centre_from_other;
    region_from_other.row(0) -= static_cast<double>(region.x) * centre_from_other.row(2);
    region_from_other.row(1) -= static_cast<double>(region.y) * centre_from_other.row(2);
    cv::Mat m(3, 3, CV_64F);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) m.at<double>(r, c) = region_from_other(r, c);
    }
    cv::Mat target = other->warped(region);
    cv::warpPerspective(history_[index].grey, target, m, region.size(), cv::INTER_LINEAR,
                        cv::BORDER_CONSTANT);
    SAKER_CHECK(target.data == other->warped(region).data) << "the warp reallocated its target";
  };
  const cv::Rect frame(0, 0, small_size_.width, small_size_.height);
  if (only_outside == nullptr) {
    warp_into(frame);
  } else {
    // Covered only outside the mask, and warped there, strip by strip (an L-shaped band at two
    // edges would have the whole frame for its bounding box), with the pixels round it that the
    // gradient test reads.
    cv::Mat outside;
    cv::bitwise_not(*only_outside, outside);
    cv::bitwise_and(outside, other->cover, other->cover);
    constexpr int kStripRows = 32, kReach = 3;
    for (int y = 0; y < small_size_.height; y += kStripRows) {
      const cv::Rect strip(0, y, small_size_.width, std::min(kStripRows, small_size_.height - y));
      cv::Rect needed = cv::boundingRect(other->cover(strip));
      if (needed.empty()) continue;
      needed.y += y;
      warp_into(cv::Rect(needed.x - kReach, needed.y - kReach, needed.width + 2 * kReach,
                         needed.height + 2 * kReach) &
                frame);
    }
  }
  other->gain = MeanGain(history_[centre].grey, other->warped, other->cover);
  return true;
}

const cv::Mat& ChangeDetector::MatchSharpness(const cv::Mat& centre) {
  const double ratio = options_.sharpness_match_ratio;
  if (ratio <= 0) return centre;
  const cv::Mat& cover = covers_[0];
  const int step = SparseStep(centre);
  const double own = MeanSquaredGradient(centre, cover, step);
  // The frame of the centred pair closest to the centre in sharpness: matching one of them is
  // enough, since a change is marked only where both differences are significant.
  Other* nearest = nullptr;
  double other = 0;
  for (Other& o : pairs_[0]) {
    const double s = MeanSquaredGradient(o.warped, cover, step);
    const auto apart = [own](double v) {
      return std::max(own, v) / std::max(1e-9, std::min(own, v));
    };
    if (nearest == nullptr || apart(s) < apart(other)) nearest = &o, other = s;
  }
  if (!(own > 0 && other > 0) || std::max(own, other) <= ratio * std::min(own, other)) {
    return centre;
  }
  // Blur the sharper one with the first of a few widths that brings it down to the other
  // (at most the widest: a frame blurred more than that has nothing left to compare).
  // A warped neighbour is blurred inside its cover only (normalised: the blur of the image times
  // its cover over the blur of the cover), so the black outside does not bleed a few pixels in and
  // make changes along its edge.
  const bool centre_sharper = own > other;
  const double target = std::min(own, other);
  if (!centre_sharper) {
    nearest->warped.convertTo(masked_, CV_32F);
    nearest->cover.convertTo(weight_, CV_32F, 1.0 / 255.0);
    cv::multiply(masked_, weight_, masked_);
    cv::compare(nearest->cover, 0, outside_, cv::CMP_EQ);
  }
  for (const double sigma : {0.5, 0.7, 1.0, 1.4, 2.0}) {
    if (centre_sharper) {
      cv::GaussianBlur(centre, blurred_, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
    } else {
      cv::GaussianBlur(masked_, blurred_masked_, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
      cv::GaussianBlur(weight_, blurred_weight_, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
      cv::max(blurred_weight_, 1e-3, blurred_weight_);
      cv::divide(blurred_masked_, blurred_weight_, blurred_masked_);
      blurred_masked_.convertTo(blurred_, CV_8U);  // rounds and saturates
      blurred_.setTo(0, outside_);
    }
    if (MeanSquaredGradient(blurred_, cover, step) <= target) break;
  }
  if (centre_sharper) {
    std::swap(matched_centre_, blurred_);
    return matched_centre_;
  }
  blurred_.copyTo(nearest->warped);
  return centre;
}

// Sparse: on a grid of about 20 000 points (every fifth row and column at 960x540, 0.3 ms a
// frame compared). The noise and misregistration of `other` against the centre frame, each
// negative when too few pixels were flat or steep.
ChangeDetector::Mismatch ChangeDetector::MeasureMismatch(const cv::Mat& image, const Other& other,
                                                         const cv::Mat& cover) {
  constexpr float kFlatGradient = 3, kSteepGradient = 15;  // grey levels a pixel
  constexpr size_t kMinSamples = 100;
  const int step = SparseStep(image);
  std::vector<double> flat, steep;
  for (int y = 1; y + 1 < image.rows; y += step) {
    const uint8_t* c = image.ptr<uint8_t>(y);
    const uint8_t* w = other.warped.ptr<uint8_t>(y);
    const uint8_t* v = cover.ptr<uint8_t>(y);
    for (int x = 1; x + 1 < image.cols; x += step) {
      if (v[x] == 0) continue;
      const float d = std::abs(static_cast<float>(c[x]) - other.gain * static_cast<float>(w[x]));
      const float g = std::sqrt(GradientSquared(other.warped, x, y));
      if (g < kFlatGradient) {
        flat.push_back(d);
      } else if (g > kSteepGradient) {
        steep.push_back(d / g);
      }
    }
  }
  // The robust spread of a zero-mean difference: 1.4826 times its median absolute value.
  constexpr double kMadToSigma = 1.4826;
  Mismatch m;
  if (flat.size() >= kMinSamples) {
    m.noise = static_cast<float>(kMadToSigma * Median(std::move(flat)));
  }
  if (steep.size() >= kMinSamples) {
    m.registration = static_cast<float>(kMadToSigma * Median(std::move(steep)));
  }
  return m;
}

// The centre frame against each frame of the centred pair; the smaller of the two counts (a
// change is marked only where both differences exceed their allowance, so the better-matched
// frame bounds what the worse one can mark), and nothing when either could not be measured.
void ChangeDetector::MeasureNoise(const cv::Mat& image, Entry* centre, const Other& before,
                                  const Other& after, const cv::Mat& cover) {
  centre->noise = centre->registration = -1;
  if (options_.measured_noise_multiple <= 0 && options_.measured_registration_multiple <= 0) return;
  const Mismatch a = MeasureMismatch(image, before, cover);
  const Mismatch b = MeasureMismatch(image, after, cover);
  // Unknown when either is (too few flat or steep pixels on one side).
  const auto smaller = [](float x, float y) { return x < 0 || y < 0 ? -1.0f : std::min(x, y); };
  centre->noise = smaller(a.noise, b.noise);
  centre->registration = smaller(a.registration, b.registration);
}

void ChangeDetector::SetAllowances(const Entry& centre) {
  noise_ = static_cast<float>(options_.noise_grey);
  allowance_ = static_cast<float>(options_.registration_px);
  // The median of the measured frames held (from the frame after the centre on nothing is
  // measured yet), or the centre's own where larger: a frame misregistered against both its
  // neighbours differs from them with one sign on every edge, and the median of its quieter
  // neighbours would let that through as a thousand blobs. A resumed run holds the same frames,
  // so it measures the same.
  const auto measured = [this, &centre](float Entry::*field) {
    std::vector<double> values;
    for (const Entry& e : history_) {
      if (e.*field >= 0) values.push_back(e.*field);
    }
    return std::max(static_cast<float>(Median(std::move(values))), centre.*field);  // 0: none
  };
  noise_ = std::max(noise_,
                    static_cast<float>(options_.measured_noise_multiple) * measured(&Entry::noise));
  allowance_ = std::max(allowance_, static_cast<float>(options_.measured_registration_multiple) *
                                        measured(&Entry::registration));
}

// A pixel changed when both differences exceed their noise with the same sign. The noise of a
// difference adds the other frame's local gradient (the largest of its 3x3 neighbourhood) times
// the registration allowance: where the ground is misregistered by d, the difference is about d
// times that gradient. The other frame's, not the centre's: a walker is itself all edges in the
// centre frame, while the ground it walked onto is what the others show there. The gradient is
// computed only where the sensor noise alone is exceeded: a small part of the frame. Returns the
// mask of changed pixels; strength_ holds their signed change.
cv::Mat ChangeDetector::MarkChanged(const cv::Mat& image, cv::Mat* evidence_changed) {
  const float noise = noise_, allowance = allowance_;
  const float threshold = static_cast<float>(options_.threshold);
  const float quick = threshold * noise;
  const auto significant = [&](float d, const Other& other, int x, int y) {
    const float a = allowance * other.allowance;
    return d * d >
           threshold * threshold * (noise * noise + a * a * GradientSquared(other.warped, x, y));
  };
  cv::Mat changed(small_size_, CV_8U, cv::Scalar(0));
  if (evidence_pair_ >= 0) evidence_changed->create(small_size_, CV_8U), evidence_changed->setTo(0);
  strength_.create(small_size_, CV_32F);
  strength_.setTo(0);
  // Two passes per row: a branch-free one marks the pixels whose differences agree in sign and
  // exceed the sensor noise (the two signs agree at random on flat ground, so a branch there is
  // mispredicted half the time); the gradient test then runs on those few. 2.9 -> 1.1 ms a frame
  // at 960x540, with the same answer.
  std::vector<uint8_t> candidate(static_cast<size_t>(small_size_.width));
  const cv::Mat no_strength(1, small_size_.width, CV_32F, cv::Scalar(0));
  for (size_t i = 0; i < pairs_.size(); ++i) {
    const Other& before = pairs_[i][0];
    const Other& after = pairs_[i][1];
    // The evidence pair's changes go to their own mask, never to the blobs.
    const bool evidence_only = static_cast<int>(i) == evidence_pair_;
    cv::Mat& mask = evidence_only ? *evidence_changed : changed;
    // Only where the pair compares: the whole frame for a centred pair, a band at an edge for a
    // one-sided one.
    const cv::Rect area = cv::boundingRect(covers_[i]);
    for (int y = area.y; y < area.y + area.height; ++y) {
      const uint8_t* c = image.ptr<uint8_t>(y);
      const uint8_t* w0 = before.warped.ptr<uint8_t>(y);
      const uint8_t* w1 = after.warped.ptr<uint8_t>(y);
      const uint8_t* v = covers_[i].ptr<uint8_t>(y);
      uint8_t* out = mask.ptr<uint8_t>(y);
      // The strongest change marked so far (none for the evidence, which has its own mask).
      const float* s = evidence_only ? no_strength.ptr<float>(0) : strength_.ptr<float>(y);
      float* strength = strength_.ptr<float>(y);
      for (int x = area.x; x < area.x + area.width; ++x) {
        const float d0 = static_cast<float>(c[x]) - before.gain * static_cast<float>(w0[x]);
        const float d1 = static_cast<float>(c[x]) - after.gain * static_cast<float>(w1[x]);
        const float a = std::min(std::abs(d0), std::abs(d1));
        candidate[static_cast<size_t>(x)] =
            static_cast<uint8_t>((v[x] != 0) & (d0 * d1 > 0) & (a > quick) & (a > std::abs(s[x])));
      }
      for (int x = area.x; x < area.x + area.width; ++x) {
        if (candidate[static_cast<size_t>(x)] == 0) continue;
        const float d0 = static_cast<float>(c[x]) - before.gain * static_cast<float>(w0[x]);
        const float d1 = static_cast<float>(c[x]) - after.gain * static_cast<float>(w1[x]);
        if (!significant(d0, before, x, y) || !significant(d1, after, x, y)) {
          continue;
        }
        out[x] = 255;
        if (evidence_only) continue;
        const float a = std::min(std::abs(d0), std::abs(d1));
        strength[x] = d0 > 0 ? a : -a;
      }
    }
  }
  return changed;
}

// The changed pixels' 8-connected components, in raster order of their first pixel, each filled
// from there; those of a blob's size and contrast are the blobs. The mask is sparse (a few hundred
// pixels of half a million), so the fill visits only those: 0.3 ms a frame at 960x540, where
// labelling the whole image (cv::connectedComponentsWithStats) took 3.2 ms.
std::vector<ChangeBlob> ChangeDetector::FindBlobs(const cv::Mat& changed) {
  std::vector<ChangeBlob> blobs;
  changed.copyTo(unvisited_);
  cv::findNonZero(changed, seeds_);
  const int width = small_size_.width, height = small_size_.height;
  for (const cv::Point& seed : seeds_) {
    if (unvisited_.at<uint8_t>(seed) == 0) continue;
    unvisited_.at<uint8_t>(seed) = 0;
    fill_.assign(1, seed);
    int area = 0, x0 = seed.x, x1 = seed.x, y0 = seed.y, y1 = seed.y;
    double weight = 0, sx = 0, sy = 0, peak = 0;
    while (!fill_.empty()) {
      const cv::Point p = fill_.back();
      fill_.pop_back();
      ++area;
      x0 = std::min(x0, p.x);
      x1 = std::max(x1, p.x);
      y0 = std::min(y0, p.y);
      y1 = std::max(y1, p.y);
      const double st = strength_.at<float>(p);
      weight += std::abs(st);
      sx += std::abs(st) * p.x;
      sy += std::abs(st) * p.y;
      if (std::abs(st) > std::abs(peak)) peak = st;
      for (int yy = std::max(0, p.y - 1); yy <= std::min(height - 1, p.y + 1); ++yy) {
        uint8_t* row = unvisited_.ptr<uint8_t>(yy);
        for (int xx = std::max(0, p.x - 1); xx <= std::min(width - 1, p.x + 1); ++xx) {
          if (row[xx] == 0) continue;
          row[xx] = 0;
          fill_.emplace_back(xx, yy);
        }
      }
    }
    if (area < options_.min_area_px || area > options_.max_area_px) continue;
    if (std::abs(peak) < options_.min_contrast_grey || weight <= 0) continue;
    ChangeBlob blob;
    blob.position = ToFull(sx / weight, sy / weight);
    blob.box_min = ToFull(x0 - 0.5, y0 - 0.5);
    blob.box_max = ToFull(x1 + 0.5, y1 + 0.5);
    blob.area_px = area;
    blob.contrast = peak;
    blobs.push_back(blob);
  }
  return blobs;
}

bool ChangeFrame::Compared(const Eigen::Vector2d& p) const {
  if (frame < 0) return false;
  const Eigen::Vector2d q = ToProcessing(p, scale);
  const int x = static_cast<int>(std::lround(q.x())), y = static_cast<int>(std::lround(q.y()));
  return x >= 0 && y >= 0 && x < valid.cols && y < valid.rows && valid.at<uint8_t>(y, x) != 0;
}

bool ChangeFrame::ChangedNear(const Eigen::Vector2d& p, double radius_px) const {
  if (frame < 0) return false;
  const Eigen::Vector2d q = ToProcessing(p, scale);
  const double r = radius_px / scale;
  const int x0 = std::max(0, static_cast<int>(std::floor(q.x() - r))),
            x1 = std::min(changed.cols - 1, static_cast<int>(std::ceil(q.x() + r)));
  const int y0 = std::max(0, static_cast<int>(std::floor(q.y() - r))),
            y1 = std::min(changed.rows - 1, static_cast<int>(std::ceil(q.y() + r)));
  for (int y = y0; y <= y1; ++y) {
    const uint8_t* row = changed.ptr<uint8_t>(y);
    const uint8_t* row_long = evidence_changed.empty() ? row : evidence_changed.ptr<uint8_t>(y);
    for (int x = x0; x <= x1; ++x) {
      if ((row[x] | row_long[x]) != 0 && (Eigen::Vector2d(x, y) - q).squaredNorm() <= r * r) {
        return true;
      }
    }
  }
  return false;
}

Status BlobTrackOptions::Validate() const {
  if (!(gate_px > 0 && min_travel_px >= 0 && max_fit_rms_px > 0 && noisy_fit_rms_px > 0 &&
        max_speed_px_s > 0 && box_margin_px >= 0 && gate_growth_px_s >= 0 &&
        new_track_speed_px_s >= 0 && max_speed_m_s >= 0 && max_speed_m_s <= 1000)) {
    return InvalidArgumentError(
        "blob tracks: gate, fit RMS and speed must be positive, travel, margin, the gate's "
        "growth and the new tracks' speed >= 0, the top speed on the ground in [0, 1000] m/s");
  }
  if (!(gate_speed_fraction >= 0 && gate_speed_fraction <= 5)) {
    return InvalidArgumentError("blob tracks: the gate's speed fraction must be in [0, 5]");
  }
  if (noisy_max_area_px < 0 || !(noisy_area_scale >= 1)) {
    return InvalidArgumentError(
        "blob tracks: the largest blob in noisy video must be >= 0 pixels and the noise scale "
        "above which it applies >= 1");
  }
  if (!(max_gap_s >= 0 && max_gap_s <= 3600) || !(min_duration_s >= 0 && min_duration_s <= 3600) ||
      !(min_hit_fraction > 0 && min_hit_fraction <= 1)) {
    return InvalidArgumentError(
        "blob tracks: need the gap and the duration in [0, 3600] s and a hit fraction in (0, 1]");
  }
  return Status::Ok();
}

BlobTracker::BlobTracker(const BlobTrackOptions& options, FrameRate rate)
    : options_(options),
      gate_growth_px_(rate.PerFrame(options.gate_growth_px_s)),
      max_gap_frames_(rate.Frames(options.max_gap_s, 2)),
      min_frames_(rate.Frames(options.min_duration_s, 3)),
      max_speed_px_(rate.PerFrame(options.max_speed_px_s)),
      new_track_speed_px_(rate.PerFrame(options.new_track_speed_px_s)),
      max_speed_m_(rate.PerFrame(options.max_speed_m_s)) {
  SAKER_CHECK(options_.Validate().ok()) << options_.Validate().message();
}

void BlobTracker::LineFit::Add(double t, const Eigen::Vector2d& p) {
  n += 1;
  st += t;
  stt += t * t;
  sp += p;
  stp += t * p;
  spp += p.squaredNorm();
}

Eigen::Vector2d BlobTracker::LineFit::Velocity() const {
  const double centred_tt = stt - st * st / n;
  return centred_tt > 0 ? Eigen::Vector2d((stp - st * sp / n) / centred_tt) : Eigen::Vector2d(0, 0);
}

double BlobTracker::LineFit::Rms() const {
  // The residual sum of squares of a least-squares line: the spread of p less what the line
  // explains, |v|^2 times the spread of t.
  const double centred_tt = stt - st * st / n;
  const double centred_pp = spp - sp.squaredNorm() / n;
  return std::sqrt(std::max(0.0, centred_pp - Velocity().squaredNorm() * centred_tt) / n);
}

void BlobTracker::AddFrame(int64_t frame, const std::vector<ChangeBlob>& blobs,
                           const Eigen::Matrix3d& current_from_previous, double noise_scale,
                           const GroundScale* scale) {
  if (options_.noisy_max_area_px > 0 && noise_scale > options_.noisy_area_scale) {
    std::vector<ChangeBlob> small;
    for (const ChangeBlob& b : blobs) {
      if (b.area_px <= options_.noisy_max_area_px) small.push_back(b);
    }
    Follow(frame, small, current_from_previous, noise_scale, scale);
  } else {
    Follow(frame, blobs, current_from_previous, noise_scale, scale);
  }
}

void BlobTracker::Follow(int64_t frame, const std::vector<ChangeBlob>& blobs,
                         const Eigen::Matrix3d& current_from_previous, double noise_scale,
                         const GroundScale* scale) {
  // The top speed in pixels a frame at an image point: the ground's where its scale is known.
  const bool on_ground = scale != nullptr && max_speed_m_ > 0;
  const auto top_speed = [&](const Eigen::Vector2d& at, double pixels) {
    return on_ground ? max_speed_m_ / scale->MetresPerPixel(at) : pixels;
  };
  const double min_travel = options_.min_travel_px * std::max(1.0, noise_scale);
  const double max_fit_rms = std::min(
      options_.max_fit_rms_px,
      std::max(options_.noisy_fit_rms_px, options_.max_fit_rms_px / std::max(1.0, noise_scale)));
  // Predict every track into this frame: its last hit moved by its velocity (in anchor
  // coordinates), then through the ground motion to now.
  std::vector<Eigen::Vector2d> predicted(active_.size());
  for (size_t i = 0; i < active_.size(); ++i) {
    Track& t = active_[i];
    t.current_from_anchor = current_from_previous * t.current_from_anchor;
    predicted[i] =
        Transfer(t.current_from_anchor,
                 t.last_anchored + t.velocity * static_cast<double>(frame - t.target.last_frame()));
  }
  // Greedy nearest pairs within the gate (wider the longer a track has gone unseen).
  std::vector<std::tuple<double, size_t, size_t>> pairs;
  for (size_t i = 0; i < active_.size(); ++i) {
    const double gap = static_cast<double>(frame - active_[i].target.last_frame() - 1);
    // A fast mover's prediction misses by a part of its own displacement when it turns.
    double gate = options_.gate_px + gate_growth_px_ * gap +
                  options_.gate_speed_fraction * active_[i].velocity.norm() * (gap + 1);
    if (active_[i].hits < 2 && new_track_speed_px_ > 0) {
      gate = std::max(gate,
                      options_.gate_px + top_speed(predicted[i], new_track_speed_px_) * (gap + 1));
    }
    for (size_t j = 0; j < blobs.size(); ++j) {
      const double d = (blobs[j].position - predicted[i]).norm();
      if (d <= gate) pairs.emplace_back(d, i, j);
    }
  }
  std::sort(pairs.begin(), pairs.end());
  std::vector<bool> track_used(active_.size(), false), blob_used(blobs.size(), false);
  const auto observe = [&](Track* t, const ChangeBlob& blob) {
    TargetObservation o;
    o.frame = frame;
    o.position = blob.position;
    const Eigen::Vector2d margin = Eigen::Vector2d::Constant(options_.box_margin_px);
    o.box_min = blob.box_min - margin;
    o.box_max = blob.box_max + margin;
    o.change = ChangeEvidence::kChanged;
    t->last_anchored = Transfer(t->current_from_anchor.inverse(), blob.position);
    t->fit.Add(static_cast<double>(frame - t->first_frame), t->last_anchored);
    ++t->hits;
    t->velocity = t->fit.Velocity();
    o.velocity = t->velocity;  // anchor pixels: close to image pixels over a track's life
    t->target.observations.push_back(std::move(o));
    if (!t->confirmed && t->hits >= min_frames_) {
      const double span = static_cast<double>(frame - t->first_frame + 1);
      const double travel = t->velocity.norm() * static_cast<double>(frame - t->first_frame);
      t->confirmed = static_cast<double>(t->hits) / span >= options_.min_hit_fraction &&
                     travel >= min_travel && t->fit.Rms() <= max_fit_rms &&
                     t->velocity.norm() <= top_speed(blob.position, max_speed_px_);
      t->target.confirmed = t->confirmed;
    }
  };
  for (const auto& [d, i, j] : pairs) {
    if (track_used[i] || blob_used[j]) continue;
    track_used[i] = blob_used[j] = true;
    observe(&active_[i], blobs[j]);
  }

  // Tracks unseen too long end; unpaired blobs start tracks.
  std::vector<Track> still;
  for (Track& t : active_) {
    if (frame - t.target.last_frame() > max_gap_frames_) {
      End(&t);
    } else {
      still.push_back(std::move(t));
    }
  }
  active_ = std::move(still);
  for (size_t j = 0; j < blobs.size(); ++j) {
    if (blob_used[j]) continue;
    Track t;
    t.target.id = static_cast<TargetTrackId>(next_id_++);
    t.first_frame = frame;
    active_.push_back(std::move(t));
    observe(&active_.back(), blobs[j]);
  }
}

void BlobTracker::End(Track* track) {
  if (track->confirmed) finished_.push_back(std::move(track->target));
}

std::vector<TargetTrack> BlobTracker::TakeFinished() {
  std::vector<TargetTrack> out = std::move(finished_);
  finished_.clear();
  return out;
}

void BlobTracker::FinishAll() {
  for (Track& t : active_) End(&t);
  active_.clear();
}

bool SupportedByChange(const TargetTrack& track, double min_fraction) {
  int looked = 0, changed = 0;
  for (const TargetObservation& o : track.observations) {
    looked += o.change != ChangeEvidence::kNotLooked;
    changed += o.change == ChangeEvidence::kChanged;
  }
  return looked == 0 || static_cast<double>(changed) >= min_fraction * static_cast<double>(looked);
}

Status ChangeEchoOptions::Validate() const {
  if (!(distance_px > 0 && piece_distance_px > 0 && velocity_px_s > 0 &&
        min_mover_speed_px_s >= 0 && min_fraction > 0 && piece_min_fraction > 0 &&
        piece_min_fraction <= 1 && min_fraction <= 1)) {
    return InvalidArgumentError(
        "change echoes: distances and velocity must be positive, the mover's speed >= 0 and the "
        "fraction in (0, 1]");
  }
  return Status::Ok();
}

namespace {

bool FoundByChangeOnly(const TargetTrack& track) {
  for (const TargetObservation& o : track.observations) {
    if (!o.features.empty()) return false;
  }
  return true;
}

// `tracks` less those that ride along movers (tracks of at least `min_mover_speed_px_s`): on at
// least `min_fraction` of a track's frames, one of the movers `near(track, mover)` returns a
// distance for is within that distance of it, moving alike.
std::vector<TargetTrack> DropAlongside(
    std::vector<TargetTrack> tracks, const ChangeEchoOptions& options, FrameRate rate,
    double min_fraction, double velocity_px_s,
    const std::function<std::optional<double>(const TargetTrack&, const TargetTrack&)>& near) {
  if (!options.enabled) return tracks;
  const double velocity_px = rate.PerFrame(velocity_px_s);  // per frame, as tracks keep it
  std::vector<const TargetTrack*> movers;
  for (const TargetTrack& t : tracks) {
    if (!t.observations.empty() && MeanSpeed(t) >= rate.PerFrame(options.min_mover_speed_px_s)) {
      movers.push_back(&t);
    }
  }
  std::vector<bool> dropped(tracks.size(), false);
  for (size_t i = 0; i < tracks.size(); ++i) {
    const TargetTrack& t = tracks[i];
    if (t.observations.empty()) continue;
    std::vector<bool> along(t.observations.size(), false);
    for (const TargetTrack* m : movers) {
      if (m == &t || m->observations.back().frame < t.observations.front().frame ||
          m->observations.front().frame > t.observations.back().frame) {
        continue;
      }
      const std::optional<double> distance_px = near(t, *m);
      if (!distance_px) continue;
      ForCommonFrames(t, *m, [&](const TargetObservation& e, const TargetObservation& o) {
        if ((o.position - e.position).norm() < *distance_px &&
            (o.velocity - e.velocity).norm() < velocity_px) {
          along[static_cast<size_t>(&e - t.observations.data())] = true;
        }
      });
    }
    const auto count = static_cast<double>(std::count(along.begin(), along.end(), true));
    dropped[i] = count >= min_fraction * static_cast<double>(along.size());
  }
  std::vector<TargetTrack> kept;
  kept.reserve(tracks.size());
  for (size_t i = 0; i < tracks.size(); ++i) {
    if (!dropped[i]) kept.push_back(std::move(tracks[i]));
  }
  return kept;
}

}  // namespace

std::vector<TargetTrack> DropChangeEchoes(std::vector<TargetTrack> tracks,
                                          const ChangeEchoOptions& options, FrameRate rate) {
  return DropAlongside(
      std::move(tracks), options, rate, options.min_fraction, options.velocity_px_s,
      [&](const TargetTrack& t, const TargetTrack& m) -> std::optional<double> {
        if (!FoundByChangeOnly(t)) return std::nullopt;
        if (FoundByChangeOnly(m) && m.observations.size() <= t.observations.size()) {
          return std::nullopt;
        }
        return options.distance_px;
      });
}

std::vector<TargetTrack> DropCarPieces(std::vector<TargetTrack> tracks,
                                       const ChangeEchoOptions& options, FrameRate rate) {
  // Any velocity: the corners of a car and its change blob move alike only on average.
  return DropAlongside(std::move(tracks), options, rate, options.piece_min_fraction,
                       std::numeric_limits<double>::infinity(),
                       [&](const TargetTrack& t, const TargetTrack& m) -> std::optional<double> {
                         if (m.observations.size() <= t.observations.size()) return std::nullopt;
                         return options.piece_distance_px;
                       });
}

void BlobTracker::SaveState(ByteWriter* out) const {
  out->Put<int64_t>(next_id_);
  out->Put<uint64_t>(active_.size());
  for (const Track& t : active_) {
    SaveTargetTrack(t.target, out);
    out->PutMatrix(t.current_from_anchor);
    out->PutMatrix(t.last_anchored);
    for (const double v : {t.fit.n, t.fit.st, t.fit.stt, t.fit.spp}) out->Put<double>(v);
    out->PutMatrix(t.fit.sp);
    out->PutMatrix(t.fit.stp);
    out->PutMatrix(t.velocity);
    out->Put<int64_t>(t.first_frame);
    out->Put<int32_t>(t.hits);
    out->Put<uint8_t>(t.confirmed);
  }
  out->Put<uint64_t>(finished_.size());
  for (const TargetTrack& t : finished_) SaveTargetTrack(t, out);
}

bool BlobTracker::RestoreState(ByteReader* in) {
  size_t count = 0;
  if (!in->Get(&next_id_) || !in->GetCount(49, &count)) return false;
  active_.resize(count);
  for (Track& t : active_) {
    uint8_t confirmed = 0;
    if (!RestoreTargetTrack(in, &t.target) || !in->GetMatrix(&t.current_from_anchor) ||
        !in->GetMatrix(&t.last_anchored) || !in->Get(&t.fit.n) || !in->Get(&t.fit.st) ||
        !in->Get(&t.fit.stt) || !in->Get(&t.fit.spp) || !in->GetMatrix(&t.fit.sp) ||
        !in->GetMatrix(&t.fit.stp) || !in->GetMatrix(&t.velocity) || !in->Get(&t.first_frame) ||
        !in->Get(&t.hits) || !in->Get(&confirmed)) {
      return false;
    }
    t.confirmed = confirmed != 0;
  }
  if (!in->GetCount(49, &count)) return false;
  finished_.resize(count);
  for (TargetTrack& t : finished_) {
    if (!RestoreTargetTrack(in, &t)) return false;
  }
  return true;
}

}  // namespace saker::track
