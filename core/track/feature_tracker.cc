#include "core/track/feature_tracker.h"

#include "core/util/byte_io.h"
#include "core/util/check.h"
#include "core/util/timer.h"

#include <Eigen/LU>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include <algorithm>
#include <cmath>
#include <utility>

namespace saker::track {
namespace {

// Harris detector settings (OpenCV's defaults): a 3x3 structure-tensor window on 3x3 Sobel
// gradients, so a corner is placed by the structure right at it.
constexpr int kHarrisBlock = 3;
constexpr double kHarrisK = 0.04;

// LK stops iterating once an update moves the point by less than this (processing pixels): well
// below the sub-pixel accuracy the tracker is tested to (0.1 px).
constexpr double kFlowEpsilonPx = 0.01;

// Patches compared between consecutive frames: 11x11 processing pixels, small enough to notice a
// car covering part of a flow window, large enough for a steady correlation under sensor noise.
constexpr int kPatchHalf = 5;
constexpr int kPatchSide = 2 * kPatchHalf + 1;
constexpr int kPatchArea = kPatchSide * kPatchSide;
// A tracked point whose patch has less contrast than this (grey-level standard deviation) is on
// something flat: there is nothing to correlate, so it cannot be confirmed.
constexpr float kFlatPatchSigma = 0.5f;

// Smaller processing images are not tracked: their pyramid border could not hold a patch, and
// nothing that small is a video frame anyway.
constexpr int kMinProcessingSide = 16;

// Bilinear patches from the level-0 pyramid image. Its buffer extends beyond the image by the
// pyramid border, so patches of points near the edge are read from the mirrored border, and
// positions are clamped so that no read leaves the buffer.
class PatchSampler {
 public:
  explicit PatchSampler(const cv::Mat& image) : image_(image) {
    cv::Size whole;
    cv::Point offset;
    image.locateROI(whole, offset);
    min_x_ = static_cast<float>(kPatchHalf - offset.x);
    min_y_ = static_cast<float>(kPatchHalf - offset.y);
    max_x_ = static_cast<float>(whole.width - offset.x - kPatchHalf - 2);
    max_y_ = static_cast<float>(whole.height - offset.y - kPatchHalf - 2);
  }

  // Writes the patch centred on `p`, normalised to zero mean and unit norm (so a dot product is
  // the correlation), to out[0..kPatchArea), and returns its grey-level standard deviation. A
  // patch with no contrast at all is left at zero.
  float Sample(cv::Point2f p, float* out) const {
    const float x = std::clamp(p.x, min_x_, max_x_), y = std::clamp(p.y, min_y_, max_y_);
    const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
    const float fx = x - static_cast<float>(x0), fy = y - static_cast<float>(y0);
    const float w00 = (1 - fx) * (1 - fy), w01 = fx * (1 - fy), w10 = (1 - fx) * fy, w11 = fx * fy;
    const ptrdiff_t step = static_cast<ptrdiff_t>(image_.step);
    const uchar* top =
        image_.data + static_cast<ptrdiff_t>(y0 - kPatchHalf) * step + (x0 - kPatchHalf);
    float sum = 0;
    for (int r = 0; r < kPatchSide; ++r, top += step) {
      const uchar* bottom = top + step;
      float* row = out + r * kPatchSide;
      for (int c = 0; c < kPatchSide; ++c) {
        row[c] = w00 * static_cast<float>(top[c]) + w01 * static_cast<float>(top[c + 1]) +
                 w10 * static_cast<float>(bottom[c]) + w11 * static_cast<float>(bottom[c + 1]);
        sum += row[c];
      }
    }
    const float mean = sum / static_cast<float>(kPatchArea);
    float squares = 0;
    for (int i = 0; i < kPatchArea; ++i) {
      out[i] -= mean;
      squares += out[i] * out[i];
    }
    if (squares <= 0) return 0;
    const float scale = 1.0f / std::sqrt(squares);
    for (int i = 0; i < kPatchArea; ++i) out[i] *= scale;
    return std::sqrt(squares / static_cast<float>(kPatchArea));
  }

 private:
  const cv::Mat& image_;
  float min_x_, min_y_, max_x_, max_y_;
};

float Dot(const float* a, const float* b) {
  float sum = 0;
  for (int i = 0; i < kPatchArea; ++i) sum += a[i] * b[i];
  return sum;
}

}  // namespace

Status TrackerOptions::Validate() const {
  if (max_corners < 1 || max_corners > 100000) {
    return InvalidArgumentError("tracker: max corners must be between 1 and 100000");
  }
  if (!(quality > 0 && quality < 1)) {
    return InvalidArgumentError("tracker: corner quality must be in (0, 1)");
  }
  if (!(min_distance_px >= 0 && min_distance_px <= 1000)) {
    return InvalidArgumentError("tracker: minimum corner distance must be in [0, 1000] pixels");
  }
  if (processing_width != 0 && (processing_width < 32 || processing_width > 16384)) {
    return InvalidArgumentError("tracker: processing width must be 0 (full) or 32..16384 pixels");
  }
  if (window_px < 5 || window_px > 101 || window_px % 2 == 0) {
    return InvalidArgumentError("tracker: the flow window must be odd, 5..101 pixels");
  }
  if (pyramid_levels < 0 || pyramid_levels > 8) {
    return InvalidArgumentError("tracker: pyramid levels must be between 0 and 8");
  }
  if (max_iterations < 1 || max_iterations > 100) {
    return InvalidArgumentError("tracker: flow iterations must be between 1 and 100");
  }
  if (!(max_forward_backward_px > 0)) {
    return InvalidArgumentError("tracker: the forward-backward tolerance must be positive");
  }
  if (!(min_correlation >= -1 && min_correlation <= 1)) {
    return InvalidArgumentError("tracker: the minimum correlation must be in [-1, 1]");
  }
  if (!(min_contrast >= 0 && min_contrast <= 100)) {
    return InvalidArgumentError("tracker: the minimum corner contrast must be 0..100 grey levels");
  }
  if (grid_cols < 1 || grid_cols > 64 || grid_rows < 1 || grid_rows > 64) {
    return InvalidArgumentError("tracker: the detection grid must have 1..64 columns and rows");
  }
  if (!(redetect_interval_s >= 0 && redetect_interval_s <= 3600)) {
    return InvalidArgumentError("tracker: the re-detection interval must be in [0, 3600] s");
  }
  if (!(refill_fraction > 0 && refill_fraction <= 1)) {
    return InvalidArgumentError("tracker: the refill fraction must be in (0, 1]");
  }
  if (!(max_frame_gap_s >= 0 && max_frame_gap_s <= 3600)) {
    return InvalidArgumentError("tracker: the frame gap must be in [0, 3600] s");
  }
  if (max_history < 1) return InvalidArgumentError("tracker: the history must hold >= 1 position");
  if (min_finished_length < 1) {
    return InvalidArgumentError("tracker: the minimum finished track length must be >= 1");
  }
  return Status::Ok();
}

const Eigen::Vector2d* FeatureTrack::PositionAt(int64_t frame) const {
  if (frame < history_start || frame > last_frame()) return nullptr;
  return &positions[static_cast<size_t>(frame - history_start)];
}

FeatureTracker::FeatureTracker(const TrackerOptions& options, FrameRate rate)
    : options_(options),
      redetect_interval_(rate.Frames(options.redetect_interval_s, 1)),
      max_frame_gap_(rate.Frames(options.max_frame_gap_s, 1)) {
  const Status valid = options_.Validate();
  SAKER_CHECK(valid.ok()) << valid.ToString();
  frames_since_detection_ = redetect_interval_;
}

Eigen::Vector2d FeatureTracker::ToFull(const cv::Point2f& p) const {
  // Pixel centres: processing pixel i covers full-resolution [i * s - 0.5, (i + 1) * s - 0.5).
  return {(p.x + 0.5) * scale_x_ - 0.5, (p.y + 0.5) * scale_y_ - 0.5};
}

// The frame's size, and its processing image's pyramid as the latest (the one before becomes the
// previous); false, with no pyramid, for a frame too small to track.
bool FeatureTracker::SetFrame(const cv::Mat& grey) {
  full_size_ = grey.size();
  small_size_ = full_size_;
  if (options_.processing_width > 0 && options_.processing_width < full_size_.width) {
    small_size_.width = options_.processing_width;
    small_size_.height =
        std::max(1, static_cast<int>(std::lround(static_cast<double>(full_size_.height) *
                                                 small_size_.width / full_size_.width)));
  }
  scale_x_ = static_cast<double>(full_size_.width) / small_size_.width;
  scale_y_ = static_cast<double>(full_size_.height) / small_size_.height;

  if (small_size_.width < kMinProcessingSide || small_size_.height < kMinProcessingSide) {
    return false;
  }

  // Both filters sample at (i + 0.5) * s - 0.5, the convention of ToFull. From 2x down, area
  // averaging is needed against aliasing (an exact 2x2 box at 2x, 0.06 ms for 1920x1080). Below
  // 2x, bilinear sampling already spans a source pixel's footprint, and it takes 0.2 ms where
  // OpenCV's general area filter takes 1.5 ms (1280x720 to 960x540, one core).
  cv::Mat small = grey;
  if (small_size_ != full_size_) {
    const bool area = scale_x_ >= 2 || scale_y_ >= 2;
    cv::resize(grey, small, small_size_, 0, 0, area ? cv::INTER_AREA : cv::INTER_LINEAR);
  }
  std::swap(previous_pyramid_, pyramid_);
  // Never reuse the caller's buffer: a video reader may overwrite it with the next frame while
  // this pyramid is still needed as the previous one.
  cv::buildOpticalFlowPyramid(small, pyramid_, cv::Size(options_.window_px, options_.window_px),
                              options_.pyramid_levels, /*withDerivatives=*/true,
                              cv::BORDER_REFLECT_101, cv::BORDER_CONSTANT,
                              /*tryReuseInputImage=*/false);
  return true;
}

void FeatureTracker::Process(int64_t frame_index, const cv::Mat& grey,
                             const Eigen::Matrix3d* predicted) {
  SAKER_CHECK(!grey.empty() && grey.type() == CV_8UC1) << "the tracker needs a CV_8UC1 image";
  SAKER_CHECK(frame_index >= 0) << "frame index " << frame_index;
  SAKER_CHECK(last_frame_ < 0 || frame_index > last_frame_)
      << "frame " << frame_index << " after frame " << last_frame_;
  const Stopwatch start;
  timing_ = Timing{};

  if (have_previous_ && (grey.size() != full_size_ ||
                         frame_index - last_frame_ - 1 > static_cast<int64_t>(max_frame_gap_))) {
    EndAll();
  }
  if (!SetFrame(grey)) {
    EndAll();
    last_frame_ = frame_index;
    points_.clear();
    timing_.total_ms = start.ElapsedMs();
    return;
  }
  timing_.pyramid_ms = start.ElapsedMs();

  const Stopwatch flow_start;
  TrackPoints(frame_index, predicted);
  timing_.flow_ms = flow_start.ElapsedMs();
  last_frame_ = frame_index;
  have_previous_ = true;

  // Refill on schedule, or at once when many tracks were lost together (the camera swung, a
  // cloud passed), rather than flying on with half the corners for several frames. The count to
  // compare with is taken one frame after a detection: corners that do not survive their first
  // step (on water, say) must not set off a detection every frame.
  if (frames_since_detection_ == 0) reference_count_ = live_.size();
  ++frames_since_detection_;
  if (frames_since_detection_ >= redetect_interval_ ||
      static_cast<double>(live_.size()) <
          options_.refill_fraction * static_cast<double>(reference_count_)) {
    const Stopwatch detect_start;
    Detect(frame_index);
    timing_.detect_ms = detect_start.ElapsedMs();
    frames_since_detection_ = 0;
  }

  points_.clear();
  points_.reserve(live_.size());
  for (const FeatureTrack& t : live_) points_.push_back({t.id, t.positions.back(), t.first_frame});
  timing_.total_ms = start.ElapsedMs();
}

void FeatureTracker::TrackPoints(int64_t frame_index, const Eigen::Matrix3d* predicted) {
  matches_.clear();
  if (live_.empty() || !have_previous_) return;
  const cv::Size window(options_.window_px, options_.window_px);
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS,
                                  options_.max_iterations, kFlowEpsilonPx);
  // Processing pixel q is full-resolution ((q + 0.5) s - 0.5); a prediction maps between them.
  Eigen::Matrix3d small_from_full = Eigen::Matrix3d::Identity(), predicted_small;
  small_from_full << 1 / scale_x_, 0, 0.5 / scale_x_ - 0.5, 0, 1 / scale_y_, 0.5 / scale_y_ - 0.5,
      0, 0, 1;
  const bool guided =
      predicted != nullptr && predicted->allFinite() && std::abs(predicted->determinant()) > 1e-9;
  const auto apply = [](const Eigen::Matrix3d& h, const cv::Point2f& p) {
    const Eigen::Vector3d q = h * Eigen::Vector3d(p.x, p.y, 1);
    return std::abs(q.z()) > 1e-12
               ? cv::Point2f(static_cast<float>(q.x() / q.z()), static_cast<float>(q.y() / q.z()))
               : p;
  };
  int flags = 0;
  if (guided) {
    predicted_small = small_from_full * *predicted * small_from_full.inverse();
    forward_.resize(live_small_.size());
    for (size_t i = 0; i < live_small_.size(); ++i) {
      forward_[i] = apply(predicted_small, live_small_[i]);
    }
    flags = cv::OPTFLOW_USE_INITIAL_FLOW;
  }
  cv::calcOpticalFlowPyrLK(previous_pyramid_, pyramid_, live_small_, forward_, forward_status_,
                           cv::noArray(), window, options_.pyramid_levels, criteria, flags);

  // Only points that arrived inside the image and still look like themselves go back. The
  // backward flow starts from where the point arrived (no initial guess): starting it at the known
  // origin would let a flow that cannot move (no texture left) pass the check by standing still.
  const bool correlate = options_.min_correlation > -1;
  const PatchSampler sampler(pyramid_[0]);
  const float max_x = static_cast<float>(small_size_.width - 1),
              max_y = static_cast<float>(small_size_.height - 1);
  std::vector<int> sent;
  sent.reserve(live_.size());
  std::vector<cv::Point2f> arrived;
  arrived.reserve(live_.size());
  new_patches_.resize(correlate ? live_.size() * kPatchArea : 0);
  for (size_t i = 0; i < live_.size(); ++i) {
    const cv::Point2f& p = forward_[i];
    if (!forward_status_[i] || !(p.x >= 0 && p.y >= 0 && p.x <= max_x && p.y <= max_y)) continue;
    if (correlate) {
      float* patch = &new_patches_[sent.size() * kPatchArea];
      if (sampler.Sample(p, patch) < kFlatPatchSigma ||
          Dot(patch, &live_patches_[i * kPatchArea]) < options_.min_correlation) {
        continue;
      }
    }
    sent.push_back(static_cast<int>(i));
    arrived.push_back(p);
  }
  if (!arrived.empty()) {
    // Guided, the way back starts from the prediction's inverse: not the known origin (see
    // above), where the prediction says it came from.
    if (guided) {
      const Eigen::Matrix3d back = predicted_small.inverse();
      backward_.resize(arrived.size());
      for (size_t k = 0; k < arrived.size(); ++k) backward_[k] = apply(back, arrived[k]);
    }
    cv::calcOpticalFlowPyrLK(pyramid_, previous_pyramid_, arrived, backward_, backward_status_,
                             cv::noArray(), window, options_.pyramid_levels, criteria, flags);
  }
  // For each live track, its index in `sent` (and new_patches_), or -1 when it ends.
  std::vector<int> keep(live_.size(), -1);
  const double tolerance2 = options_.max_forward_backward_px * options_.max_forward_backward_px;
  for (size_t k = 0; k < sent.size(); ++k) {
    if (!backward_status_[k]) continue;
    const cv::Point2f& origin = live_small_[static_cast<size_t>(sent[k])];
    const double dx = (backward_[k].x - origin.x) * scale_x_;
    const double dy = (backward_[k].y - origin.y) * scale_y_;
    if (dx * dx + dy * dy <= tolerance2) keep[static_cast<size_t>(sent[k])] = static_cast<int>(k);
  }

  // Survivors move to the front, in id order; the others end.
  const int64_t steps = frame_index - last_frame_;
  const size_t block = std::max<size_t>(1, static_cast<size_t>(options_.max_history) / 4);
  size_t kept = 0;
  for (size_t i = 0; i < live_.size(); ++i) {
    FeatureTrack& track = live_[i];
    if (keep[i] < 0) {
      Finish(std::move(track));
      continue;
    }
    const Eigen::Vector2d before = track.positions.back();
    const Eigen::Vector2d now = ToFull(forward_[i]);
    for (int64_t k = 1; k < steps; ++k) {
      track.positions.push_back(before + (now - before) *
                                             (static_cast<double>(k) / static_cast<double>(steps)));
    }
    track.positions.push_back(now);
    // Trim in blocks so the erase (a move of the whole vector) is rare.
    if (track.positions.size() >= static_cast<size_t>(options_.max_history) + block) {
      const size_t drop = track.positions.size() - static_cast<size_t>(options_.max_history);
      track.positions.erase(track.positions.begin(),
                            track.positions.begin() + static_cast<ptrdiff_t>(drop));
      track.history_start += static_cast<int64_t>(drop);
    }
    matches_.push_back({track.id, before, now});
    if (kept != i) live_[kept] = std::move(track);
    live_small_[kept] = forward_[i];
    if (correlate) {
      std::copy_n(&new_patches_[static_cast<size_t>(keep[i]) * kPatchArea], kPatchArea,
                  &live_patches_[kept * kPatchArea]);
    }
    ++kept;
  }
  live_.resize(kept);
  live_small_.resize(kept);
  if (correlate) live_patches_.resize(kept * kPatchArea);
}

void FeatureTracker::Detect(int64_t frame_index) {
  const int cols = options_.grid_cols, rows = options_.grid_rows, cells = cols * rows;
  const int width = small_size_.width, height = small_size_.height;
  const auto cell_rect = [&](int c) {
    const int i = c % cols, j = c / cols;
    const int x0 = i * width / cols, x1 = (i + 1) * width / cols;
    const int y0 = j * height / rows, y1 = (j + 1) * height / rows;
    return cv::Rect(x0, y0, x1 - x0, y1 - y0);
  };
  // Each cell's share of max_corners (the remainder goes to the first cells).
  const auto share = [&](int c) {
    return options_.max_corners / cells + (c < options_.max_corners % cells ? 1 : 0);
  };
  std::vector<int> count(static_cast<size_t>(cells), 0);
  for (const cv::Point2f& p : live_small_) {
    const int i = std::clamp(
        static_cast<int>(p.x * static_cast<float>(cols) / static_cast<float>(width)), 0, cols - 1);
    const int j = std::clamp(
        static_cast<int>(p.y * static_cast<float>(rows) / static_cast<float>(height)), 0, rows - 1);
    ++count[static_cast<size_t>(j * cols + i)];
  }
  std::vector<int> needy;
  for (int c = 0; c < cells; ++c) {
    const cv::Rect r = cell_rect(c);
    if (share(c) > 0 && r.area() > 0 &&
        count[static_cast<size_t>(c)] < options_.refill_fraction * share(c)) {
      needy.push_back(c);
    }
  }
  if (needy.empty()) return;

  // Corners closer to the border than half a flow window would be tracked with a window that
  // reaches into the pyramid's mirrored border, which moves the wrong way: keep them out.
  const int border = options_.window_px / 2;
  const double scale = 0.5 * (scale_x_ + scale_y_);
  const double min_distance = options_.min_distance_px / scale;
  const int radius = std::max(0, static_cast<int>(std::lround(min_distance)) - 1);
  mask_.create(small_size_, CV_8UC1);
  mask_.setTo(0);
  if (width > 2 * border && height > 2 * border) {
    mask_(cv::Rect(border, border, width - 2 * border, height - 2 * border)).setTo(255);
  }
  const auto block = [&](const cv::Point2f& p) {
    if (radius > 0) {
      cv::circle(mask_,
                 cv::Point(static_cast<int>(std::lround(p.x)), static_cast<int>(std::lround(p.y))),
                 radius, cv::Scalar(0), cv::FILLED);
    } else {
      const int x = std::clamp(static_cast<int>(std::lround(p.x)), 0, width - 1);
      const int y = std::clamp(static_cast<int>(std::lround(p.y)), 0, height - 1);
      mask_.at<uchar>(y, x) = 0;
    }
  };
  for (const cv::Point2f& p : live_small_) block(p);

  // Each cell is a view into the level-0 image, so Harris near a cell's edge sees the real pixels
  // beyond it, and patches near the image edge are read from the pyramid's border.
  const cv::Mat& image = pyramid_[0];
  const bool correlate = options_.min_correlation > -1;
  const PatchSampler sampler(image);
  float patch[kPatchArea];
  const float min_contrast =
      static_cast<float>(std::max<double>(options_.min_contrast, kFlatPatchSigma));
  std::vector<cv::Point2f> corners;
  for (int c : needy) {
    const cv::Rect r = cell_rect(c);
    if (cv::countNonZero(mask_(r)) == 0) continue;
    const int budget = options_.max_corners - static_cast<int>(live_.size());
    if (budget <= 0) break;
    cv::goodFeaturesToTrack(image(r), corners,
                            std::min(budget, share(c) - count[static_cast<size_t>(c)]),
                            options_.quality, min_distance, mask_(r), kHarrisBlock,
                            /*useHarrisDetector=*/true, kHarrisK);
    for (cv::Point2f p : corners) {
      p.x += static_cast<float>(r.x);
      p.y += static_cast<float>(r.y);
      if (sampler.Sample(p, patch) < min_contrast) continue;
      // Later cells must keep their distance from these too.
      block(p);
      if (correlate) live_patches_.insert(live_patches_.end(), patch, patch + kPatchArea);
      FeatureTrack track;
      track.id = static_cast<FeatureTrackId>(next_id_++);
      track.first_frame = frame_index;
      track.history_start = frame_index;
      track.positions.reserve(16);
      track.positions.push_back(ToFull(p));
      live_.push_back(std::move(track));
      live_small_.push_back(p);
    }
  }
}

const FeatureTrack* FeatureTracker::History(FeatureTrackId id) const {
  const auto it =
      std::lower_bound(live_.begin(), live_.end(), id, [](const FeatureTrack& t, FeatureTrackId v) {
        return static_cast<int64_t>(t.id) < static_cast<int64_t>(v);
      });
  return it != live_.end() && it->id == id ? &*it : nullptr;
}

std::vector<FeatureTrack> FeatureTracker::TakeFinished() { return std::exchange(finished_, {}); }

void FeatureTracker::Finish(FeatureTrack track) {
  if (!options_.keep_finished) return;
  if (track.last_frame() - track.first_frame + 1 < options_.min_finished_length) return;
  finished_.push_back(std::move(track));
}

void FeatureTracker::EndAll() {
  for (FeatureTrack& t : live_) Finish(std::move(t));
  live_.clear();
  live_small_.clear();
  live_patches_.clear();
  matches_.clear();
  have_previous_ = false;
  frames_since_detection_ = redetect_interval_;
  reference_count_ = 0;
}

void FeatureTracker::Reset() {
  EndAll();
  points_.clear();
  last_frame_ = -1;
}

void FeatureTracker::SaveState(ByteWriter* out) const {
  out->Put<int64_t>(last_frame_);
  out->Put<int64_t>(next_id_);
  out->Put<int32_t>(frames_since_detection_);
  out->Put<uint64_t>(reference_count_);
  out->Put<uint8_t>(have_previous_);
  out->Put<uint64_t>(live_.size());
  for (size_t i = 0; i < live_.size(); ++i) {
    const FeatureTrack& t = live_[i];
    out->Put<int64_t>(static_cast<int64_t>(t.id));
    out->Put<int64_t>(t.first_frame);
    out->Put<int64_t>(t.history_start);
    out->Put<uint64_t>(t.positions.size());
    for (const Eigen::Vector2d& p : t.positions) out->PutMatrix(p);
    out->Put<float>(live_small_[i].x);
    out->Put<float>(live_small_[i].y);
  }
  out->PutVector(live_patches_);
}

bool FeatureTracker::RestoreState(ByteReader* in, const cv::Mat& grey) {
  Reset();
  uint8_t have_previous = 0;
  uint64_t reference_count = 0;
  size_t live = 0;
  if (!in->Get(&last_frame_) || !in->Get(&next_id_) || !in->Get(&frames_since_detection_) ||
      !in->Get(&reference_count) || !in->Get(&have_previous) || !in->GetCount(48, &live)) {
    return false;
  }
  reference_count_ = static_cast<size_t>(reference_count);
  have_previous_ = have_previous != 0;
  live_.resize(live);
  live_small_.resize(live);
  for (size_t i = 0; i < live; ++i) {
    FeatureTrack& t = live_[i];
    int64_t id = 0;
    size_t positions = 0;
    if (!in->Get(&id) || !in->Get(&t.first_frame) || !in->Get(&t.history_start) ||
        !in->GetCount(16, &positions) || positions == 0) {
      return false;
    }
    t.id = static_cast<FeatureTrackId>(id);
    t.positions.resize(positions);
    for (Eigen::Vector2d& p : t.positions) {
      if (!in->GetMatrix(&p)) return false;
    }
    if (!in->Get(&live_small_[i].x) || !in->Get(&live_small_[i].y) ||
        !std::isfinite(live_small_[i].x) || !std::isfinite(live_small_[i].y)) {
      return false;
    }
  }
  // One patch per live track when the tracker correlates them (TrackPoints reads them so).
  const size_t patches = options_.min_correlation > -1 ? live * static_cast<size_t>(kPatchArea) : 0;
  if (!in->GetVector(&live_patches_) || live_patches_.size() != patches) return false;
  if (have_previous_ && !SetFrame(grey)) return false;
  points_.clear();
  for (const FeatureTrack& t : live_) points_.push_back({t.id, t.positions.back(), t.first_frame});
  return true;
}

}  // namespace saker::track
