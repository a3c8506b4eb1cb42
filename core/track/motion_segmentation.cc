#include "core/track/motion_segmentation.h"

#include "core/util/statistics.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <iterator>

namespace saker::track {

Status SegmentationOptions::Validate() const {
  if (!(residual_threshold_px > 0)) {
    return InvalidArgumentError("segmentation: the residual threshold must be positive");
  }
  if (!(window_s > 0 && window_s <= 10)) {
    return InvalidArgumentError("segmentation: the window must be in (0, 10] s");
  }
  if (!(short_s > 0 && short_s <= window_s)) {
    return InvalidArgumentError("segmentation: the short window must be in (0 s, the window]");
  }
  if (!(min_significant_fraction > 0 && min_significant_fraction <= 1) ||
      !(release_fraction >= 0 && release_fraction < min_significant_fraction)) {
    return InvalidArgumentError(
        "segmentation: need 0 <= release fraction < significant fraction <= 1");
  }
  if (!(min_window_displacement_px >= 0)) {
    return InvalidArgumentError("segmentation: the window displacement must be >= 0");
  }
  if (!(max_parallax_fraction >= 0 && max_parallax_fraction < 1)) {
    return InvalidArgumentError("segmentation: the parallax fraction must be in [0, 1)");
  }
  if (!(epipolar_angle_deg >= 0 && epipolar_angle_deg <= 90)) {
    return InvalidArgumentError("segmentation: the epipolar angle must be in [0, 90] degrees");
  }
  if (!(noise_multiple >= 0 && noise_multiple <= 100) ||
      !(window_noise_multiple >= 0 && window_noise_multiple <= 100)) {
    return InvalidArgumentError("segmentation: the noise multiples must be in [0, 100]");
  }
  if (!(noise_time_s > 0 && noise_time_s <= 600) || min_noise_features < 1) {
    return InvalidArgumentError(
        "segmentation: the noise time must be in (0, 600] s and at least one feature counted");
  }
  return Status::Ok();
}

const char* MotionLabelName(MotionLabel label) {
  switch (label) {
    case MotionLabel::kUnknown:
      return "unknown";
    case MotionLabel::kStationary:
      return "stationary";
    case MotionLabel::kMoving:
      return "moving";
  }
  return "unknown";
}

MotionSegmenter::MotionSegmenter(const SegmentationOptions& options, FrameRate rate)
    : options_(options),
      short_frames_(std::min(rate.Frames(options.short_s, 1), 250)),
      window_frames_(std::clamp(rate.Frames(options.window_s, 3), short_frames_, 250)),
      noise_weight_(1.0 / rate.Frames(options.noise_time_s, 1)) {}

void MotionSegmenter::Reset() {
  tracks_.clear();
  moving_.clear();
}

double MotionSegmenter::residual_threshold_px() const {
  return std::max(options_.residual_threshold_px, options_.noise_multiple * noise_short_);
}

double MotionSegmenter::window_displacement_px() const {
  return std::max(options_.min_window_displacement_px,
                  options_.window_noise_multiple * noise_window_);
}

namespace {

// A running mean that starts at its first sample.
void Smooth(double sample, double weight, double* mean) {
  *mean = *mean > 0 ? *mean + weight * (sample - *mean) : sample;
}

}  // namespace

void MotionSegmenter::AddFrame(const std::vector<Correspondence>& matches,
                               const Eigen::Matrix3d& current_from_previous,
                               const std::optional<Eigen::Vector3d>& epipole) {
  ++calls_;
  moving_.clear();
  const size_t window = static_cast<size_t>(window_frames_);
  const size_t short_frames = static_cast<size_t>(short_frames_);

  // Pass 1: every track's new step, its stage-1 motion and its window displacement; the samples
  // of the feature noise from the tracks with full histories.
  pending_.clear();
  short_samples_.clear();
  window_samples_.clear();
  for (const Correspondence& m : matches) {
    TrackState& state = tracks_[static_cast<int64_t>(m.id)];
    state.updated = calls_;

    const Eigen::Vector2d predicted =
        (current_from_previous * m.source.homogeneous()).hnormalized();
    Step step;
    step.residual = m.target - predicted;
    step.flow = predicted - m.source;
    // The new step replaces the oldest once the window is full.
    size_t newest = state.steps.size();
    if (newest < window) {
      state.steps.push_back(step);
    } else {
      newest = state.first;
      state.first = (state.first + 1) % window;
    }
    state.steps[newest] = step;
    const size_t held = state.steps.size();

    Pending p;
    p.state = &state;
    p.id = m.id;
    p.newest = newest;
    p.position = m.target;
    // Stage 1: motion relative to the ground over the last short_frames_ frames.
    const size_t n = std::min(held, short_frames);
    for (size_t k = held - n; k < held; ++k) {
      const Step& s = state.at(k);
      p.motion += s.residual;
      p.flow += s.flow;
      p.largest_step = std::max(p.largest_step, s.residual.norm());
    }
    for (size_t k = 0; k < held; ++k) {
      p.window_sum += state.at(k).residual;
      if (k + 1 < held) p.significant_before += state.at(k).significant;
    }
    if (n == short_frames) short_samples_.push_back(p.motion.norm());
    if (held == window) window_samples_.push_back(p.window_sum.norm());
    pending_.push_back(p);
  }
  if (options_.noise_multiple > 0 &&
      short_samples_.size() >= static_cast<size_t>(options_.min_noise_features)) {
    Smooth(Median(short_samples_), noise_weight_, &noise_short_);
  }
  if (options_.window_noise_multiple > 0 &&
      window_samples_.size() >= static_cast<size_t>(options_.min_noise_features)) {
    Smooth(Median(window_samples_), noise_weight_, &noise_window_);
  }
  const double threshold = residual_threshold_px();
  const double displacement = window_displacement_px();

  // Pass 2: the labels.
  const double cos_limit = std::cos(options_.epipolar_angle_deg * M_PI / 180.0);
  for (const Pending& p : pending_) {
    TrackState& state = *p.state;
    const size_t held = state.steps.size();
    const Eigen::Vector2d& motion = p.motion;
    // Real motion is spread over the frames; a single jump (the tracker slipping onto another
    // corner) is not motion, however large.
    bool significant = motion.norm() > threshold && p.largest_step <= 0.5 * motion.norm() + 0.5;
    if (significant && epipole.has_value()) {
      // Parallax of a point above the ground: along the line from the epipole, and small next to
      // the ground's own flow at that point.
      const Eigen::Vector3d& e = *epipole;
      const Eigen::Vector2d radial = std::abs(e.z()) > 1e-12
                                         ? Eigen::Vector2d(p.position - e.hnormalized())
                                         : Eigen::Vector2d(e.x(), e.y());
      if (radial.norm() > 1e-9 && p.flow.norm() > 1e-9) {
        const double alignment = std::abs(radial.normalized().dot(motion.normalized()));
        significant = !(alignment >= cos_limit &&
                        motion.norm() <= options_.max_parallax_fraction * p.flow.norm());
      }
    }
    state.steps[p.newest].significant = significant;

    // Stage 2: consistency over the window.
    const int count = p.significant_before + (significant ? 1 : 0);
    const double fraction = static_cast<double>(count) / static_cast<double>(window);
    if (state.label == MotionLabel::kMoving) {
      // Released when it has mostly stopped over the window, or at once when the last few
      // verdicts all say still (corners left behind on the road by a passing car).
      const size_t recent = std::min<size_t>(4, held);
      bool recently_still = recent == 4;
      for (size_t k = held - recent; k < held; ++k) recently_still &= !state.at(k).significant;
      if (fraction <= options_.release_fraction || recently_still)
        state.label = MotionLabel::kStationary;
    } else if (fraction >= options_.min_significant_fraction &&
               p.window_sum.norm() >= displacement) {
      state.label = MotionLabel::kMoving;
    } else if (held >= window / 2) {
      state.label = MotionLabel::kStationary;
    }

    if (state.label == MotionLabel::kMoving) {
      moving_.push_back({p.id, p.position, p.window_sum / static_cast<double>(held)});
    }
  }
  // Tracks not in this frame's matches have ended.
  for (auto it = tracks_.begin(); it != tracks_.end();) {
    it = it->second.updated == calls_ ? std::next(it) : tracks_.erase(it);
  }
}

MotionLabel MotionSegmenter::LabelOf(FeatureTrackId id) const {
  const auto it = tracks_.find(static_cast<int64_t>(id));
  return it == tracks_.end() ? MotionLabel::kUnknown : it->second.label;
}

void MotionSegmenter::SaveState(ByteWriter* out) const {
  out->Put<int64_t>(calls_);
  std::vector<int64_t> ids;
  ids.reserve(tracks_.size());
  for (const auto& [id, state] : tracks_) ids.push_back(id);
  std::sort(ids.begin(), ids.end());  // the same bytes whatever the map's order
  out->Put<uint64_t>(ids.size());
  for (const int64_t id : ids) {
    const TrackState& state = tracks_.at(id);
    out->Put<int64_t>(id);
    out->Put<uint64_t>(state.first);
    out->Put<int64_t>(state.updated);
    out->Put<int32_t>(static_cast<int32_t>(state.label));
    out->Put<uint64_t>(state.steps.size());
    for (const Step& step : state.steps) {
      out->PutMatrix(step.residual);
      out->PutMatrix(step.flow);
      out->Put<uint8_t>(step.significant);
    }
  }
}

bool MotionSegmenter::RestoreState(ByteReader* in) {
  Reset();
  size_t count = 0;
  if (!in->Get(&calls_) || !in->GetCount(36, &count)) return false;
  for (size_t i = 0; i < count; ++i) {
    int64_t id = 0;
    uint64_t first = 0;
    int32_t label = 0;
    size_t steps = 0;
    TrackState state;
    if (!in->Get(&id) || !in->Get(&first) || !in->Get(&state.updated) || !in->Get(&label) ||
        !in->GetCount(33, &steps) || label < 0 ||
        label > static_cast<int32_t>(MotionLabel::kMoving) ||
        steps > static_cast<size_t>(window_frames_) || (steps > 0 && first >= steps)) {
      return false;
    }
    state.first = static_cast<size_t>(first);
    state.label = static_cast<MotionLabel>(label);
    state.steps.resize(steps);
    for (Step& step : state.steps) {
      uint8_t significant = 0;
      if (!in->GetMatrix(&step.residual) || !in->GetMatrix(&step.flow) || !in->Get(&significant)) {
        return false;
      }
      step.significant = significant != 0;
    }
    tracks_.emplace(id, std::move(state));
  }
  return true;
}

void MotionSegmenter::SaveNoise(ByteWriter* out) const {
  out->Put<double>(noise_short_);
  out->Put<double>(noise_window_);
}

bool MotionSegmenter::RestoreNoise(ByteReader* in) {
  double short_px = 0, window_px = 0;
  if (!in->Get(&short_px) || !in->Get(&window_px) || !std::isfinite(short_px) ||
      !std::isfinite(window_px) || short_px < 0 || window_px < 0) {
    return false;
  }
  noise_short_ = short_px;
  noise_window_ = window_px;
  return true;
}

}  // namespace saker::track
