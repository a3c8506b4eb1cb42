#include "core/track/overlay_mask.h"

#include "core/util/check.h"

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace saker::track {
namespace {

// Frames in `seconds` at `fps`, at least `floor`.
void PutMat(const cv::Mat& m, ByteWriter* out) {
  out->Put<int32_t>(m.rows);
  out->Put<int32_t>(m.cols);
  out->Put<int32_t>(m.type());
  const cv::Mat c = m.isContinuous() ? m : m.clone();
  out->PutBytes(c.data, c.total() * c.elemSize());
}

// The pixels are read before the matrix is made, so a damaged size cannot allocate more than
// the checkpoint holds.
bool GetMat(ByteReader* in, cv::Mat* m) {
  int32_t rows = 0, cols = 0, type = 0;
  std::vector<uint8_t> bytes;
  if (!in->Get(&rows) || !in->Get(&cols) || !in->Get(&type) || !in->GetBytes(&bytes)) return false;
  if (rows < 0 || cols < 0 || rows > 1 << 16 || cols > 1 << 16) return false;
  if (type != CV_8U && type != CV_32F) return false;
  const size_t element = type == CV_8U ? 1 : sizeof(float);
  if (bytes.size() != static_cast<size_t>(rows) * static_cast<size_t>(cols) * element) return false;
  *m = cv::Mat(rows, cols, type);
  if (!bytes.empty()) std::memcpy(m->data, bytes.data(), bytes.size());
  return true;
}

}  // namespace

Status OverlayOptions::Validate() const {
  if (!(window_s > 0 && window_s <= 60) || min_window_frames < 2 || min_window_frames > 1000) {
    return InvalidArgumentError("overlays: the window must be in (0, 60] s and 2..1000 frames");
  }
  if (!(min_evidence_s >= 0 && min_evidence_s <= window_s) || min_evidence_frames < 1 ||
      min_evidence_frames > min_window_frames) {
    return InvalidArgumentError(
        "overlays: the evidence needed must be in [0, window] s and 1..window frames");
  }
  if (!(min_ground_shift_px > 0 && min_ground_shift_px <= 1000) ||
      !(min_feature_flow_px > 0 && min_feature_flow_px <= 1000)) {
    return InvalidArgumentError("overlays: the ground motion needed must be in (0, 1000] px");
  }
  if (!(fixed_fraction > 0 && fixed_fraction < 1)) {
    return InvalidArgumentError("overlays: the fixed fraction must be in (0, 1)");
  }
  if (!(still_window_s > 0 && still_window_s <= 60) || still_min_window_frames < 1 ||
      still_min_window_frames > 1000 || !(still_min_flow_px > 0 && still_min_flow_px <= 1000) ||
      !(still_max_px > 0 && still_max_px <= 1000)) {
    return InvalidArgumentError(
        "overlays: the still features' window must be in (0, 60] s and 1..1000 frames, the "
        "flows in (0, 1000] px");
  }
  if (!(off_fraction >= 0 && off_fraction <= on_fraction && on_fraction > 0 && on_fraction <= 1)) {
    return InvalidArgumentError("overlays: need 0 <= off fraction <= on fraction, 0 < on <= 1");
  }
  if (cell_px < 1 || cell_px > 256 || dilate_cells < 0 || dilate_cells > 16) {
    return InvalidArgumentError("overlays: cells must be 1..256 px, the dilation 0..16 cells");
  }
  if (!(fixed_radius_px >= 0 && fixed_radius_px <= 100) || !(fixed_share > 0 && fixed_share <= 1) ||
      !(fixed_ground_fraction >= 0 && fixed_ground_fraction < 1) ||
      !(fixed_min_ground_px >= 0 && fixed_min_ground_px <= 10000) || fixed_near_cells < 0 ||
      fixed_near_cells > 16) {
    return InvalidArgumentError(
        "overlays: a screen-fixed target needs a radius in [0, 100] px, a share of its "
        "observations in (0, 1], a fraction of the ground's motion in [0, 1), a ground motion in "
        "[0, 10000] px and 0..16 cells around the mask");
  }
  if (!(max_target_fraction > 0 && max_target_fraction <= 1)) {
    return InvalidArgumentError("overlays: the target fraction must be in (0, 1]");
  }
  return Status::Ok();
}

bool OverlayMask::Contains(const Eigen::Vector2d& p) const {
  if (cells.empty() || !(p.x() >= 0 && p.y() >= 0)) return false;
  const int x = static_cast<int>(p.x() + 0.5) / cell_px,
            y = static_cast<int>(p.y() + 0.5) / cell_px;
  return x < cells.cols && y < cells.rows && cells.at<uint8_t>(y, x) != 0;
}

bool OverlayMask::ContainsNear(const Eigen::Vector2d& p, int near_cells) const {
  if (near_cells <= 0) return Contains(p);
  if (cells.empty() || !std::isfinite(p.x()) || !std::isfinite(p.y())) return false;
  const int x = static_cast<int>(std::floor((p.x() + 0.5) / cell_px));
  const int y = static_cast<int>(std::floor((p.y() + 0.5) / cell_px));
  for (int yy = std::max(0, y - near_cells); yy <= std::min(cells.rows - 1, y + near_cells); ++yy) {
    for (int xx = std::max(0, x - near_cells); xx <= std::min(cells.cols - 1, x + near_cells);
         ++xx) {
      if (cells.at<uint8_t>(yy, xx) != 0) return true;
    }
  }
  return false;
}

double OverlayMask::Coverage() const {
  if (cells.empty()) return 0;
  return static_cast<double>(cv::countNonZero(cells)) / static_cast<double>(cells.total());
}

bool OnOverlayMasks(const TargetTrack& target, const std::vector<OverlayMask>& masks,
                    const std::vector<int64_t>& breaks, double max_fraction, int near_cells) {
  if (masks.empty() || target.observations.empty()) return false;
  int64_t on = 0;
  for (const TargetObservation& o : target.observations) {
    // The first mask that ends at the observation's frame or later.
    const auto it =
        std::lower_bound(masks.begin(), masks.end(), o.frame,
                         [](const OverlayMask& m, int64_t frame) { return m.last_frame < frame; });
    if (it == masks.end()) continue;
    // That mask and the segment's later ones (they have more evidence).
    const auto next_break = std::upper_bound(breaks.begin(), breaks.end(), o.frame);
    const int64_t segment_end =
        next_break != breaks.end() ? *next_break : std::numeric_limits<int64_t>::max();
    for (auto m = it; m != masks.end() && m->first_frame < segment_end; ++m) {
      if (m->ContainsNear(o.position, near_cells)) {
        ++on;
        break;
      }
    }
  }
  return static_cast<double>(on) >= max_fraction * static_cast<double>(target.observations.size());
}

bool ScreenFixed(
    const TargetTrack& target, double radius_px, double share, double ground_fraction,
    double min_ground_px,
    const std::function<double(int64_t, int64_t, const Eigen::Vector2d&)>& ground_shift_px) {
  const std::vector<TargetObservation>& obs = target.observations;
  if (obs.size() < 2) return false;
  std::vector<double> xs, ys;
  for (const TargetObservation& o : obs) xs.push_back(o.position.x()), ys.push_back(o.position.y());
  const auto median = [](std::vector<double>& v) {
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  const Eigen::Vector2d centre(median(xs), median(ys));
  const double ground = ground_shift_px(obs.front().frame, obs.back().frame, centre);
  if (ground < min_ground_px) return false;
  const double radius = std::max(radius_px, ground_fraction * ground);
  size_t near = 0;
  for (const TargetObservation& o : obs) near += (o.position - centre).norm() <= radius;
  return static_cast<double>(near) >= share * static_cast<double>(obs.size());
}

OverlayDetector::OverlayDetector(const OverlayOptions& options, FrameRate rate)
    : options_(options) {
  SAKER_CHECK(options_.Validate().ok()) << options_.Validate().message();
  window_frames_ = rate.Frames(options_.window_s, options_.min_window_frames);
  min_evidence_frames_ =
      std::min(window_frames_, rate.Frames(options_.min_evidence_s, options_.min_evidence_frames));
  mask_.cell_px = options_.cell_px;
}

void OverlayDetector::Resize(const cv::Size& full) {
  full_size_ = full;
  const cv::Size cells((full.width + options_.cell_px - 1) / options_.cell_px,
                       (full.height + options_.cell_px - 1) / options_.cell_px);
  fraction_ = cv::Mat::zeros(cells, CV_32F);
  count_ = cv::Mat::zeros(cells, CV_32F);
  on_ = cv::Mat::zeros(cells, CV_8U);
  mask_.cells = cv::Mat::zeros(cells, CV_8U);
  ++version_;
}

void OverlayDetector::Add(int x, int y, bool changed) {
  float& count = count_.at<float>(y, x);
  float& fraction = fraction_.at<float>(y, x);
  count = std::min(count + 1.0F, static_cast<float>(window_frames_));
  fraction += ((changed ? 1.0F : 0.0F) - fraction) / count;
  if (count < static_cast<float>(min_evidence_frames_)) return;
  if (fraction >= options_.on_fraction) {
    on_.at<uint8_t>(y, x) = 255;
  } else if (fraction < options_.off_fraction) {
    on_.at<uint8_t>(y, x) = 0;
  }
}

void OverlayDetector::AddFeatures(const std::vector<Correspondence>& matches,
                                  const Eigen::Matrix3d& current_from_previous,
                                  const cv::Size& frame_size,
                                  const std::optional<HorizonLine>& sky) {
  if (!options_.enabled || frame_size.width <= 0 || frame_size.height <= 0) return;
  if (frame_size != full_size_) Resize(frame_size);
  for (const Correspondence& m : matches) {
    if (sky && m.target.y() < sky->YAt(m.target.x())) continue;
    const Eigen::Vector3d g = current_from_previous * m.source.homogeneous();
    if (!(std::abs(g.z()) > 1e-9)) continue;
    const Eigen::Vector2d ground = g.hnormalized();
    const double flow = (ground - m.source).norm();
    if (!(flow >= options_.min_feature_flow_px)) continue;
    const double limit = options_.fixed_fraction * flow;
    const bool fixed = (m.target - m.source).norm() < limit;
    if (!fixed && (m.target - ground).norm() >= limit) continue;  // neither: a mover, a slip
    const int x = static_cast<int>(m.target.x() + 0.5) / options_.cell_px;
    const int y = static_cast<int>(m.target.y() + 0.5) / options_.cell_px;
    if (m.target.x() < 0 || m.target.y() < 0 || x >= on_.cols || y >= on_.rows) continue;
    Add(x, y, fixed);
  }
  UpdateMask();
}

void OverlayDetector::AddChange(const ChangeFrame& change, int baseline_frames,
                                const std::optional<HorizonLine>& sky) {
  if (!options_.enabled || !change.answered() || change.changed.empty()) return;
  const cv::Size full(static_cast<int>(std::lround(change.changed.cols * change.scale)),
                      static_cast<int>(std::lround(change.changed.rows * change.scale)));
  // The processing size rounds: a frame of the size known within a processing pixel is that size.
  const double slack = std::ceil(change.scale);
  if (std::abs(full.width - full_size_.width) > slack ||
      std::abs(full.height - full_size_.height) > slack) {
    Resize(full);
  }
  // The answer's masks at cell size: a cell changed when any of its pixels did, compared when
  // most of them were.
  cv::resize(change.changed, changed_, fraction_.size(), 0, 0, cv::INTER_AREA);
  cv::resize(change.valid, valid_, fraction_.size(), 0, 0, cv::INTER_AREA);
  const Eigen::Matrix3d& h = change.frame_motion;
  const double cell = options_.cell_px;
  const double min_step = options_.min_ground_shift_px / std::max(1, baseline_frames);
  for (int y = 0; y < fraction_.rows; ++y) {
    const uint8_t* changed = changed_.ptr<uint8_t>(y);
    const uint8_t* valid = valid_.ptr<uint8_t>(y);
    const double py = (y + 0.5) * cell - 0.5;
    for (int x = 0; x < fraction_.cols; ++x) {
      if (valid[x] < 128) continue;
      // The ground's motion at the cell over one frame (the baseline's, spread over its frames):
      // over a hovering camera nothing is learnt.
      const double px = (x + 0.5) * cell - 0.5;
      if (sky && py < sky->YAt(px)) continue;
      const double w = h(2, 0) * px + h(2, 1) * py + h(2, 2);
      if (!(std::abs(w) > 1e-9)) continue;
      const double dx = (h(0, 0) * px + h(0, 1) * py + h(0, 2)) / w - px;
      const double dy = (h(1, 0) * px + h(1, 1) * py + h(1, 2)) / w - py;
      if (dx * dx + dy * dy < min_step * min_step) continue;
      Add(x, y, changed[x] > 0);
    }
  }
  UpdateMask();
}

void OverlayDetector::UpdateMask() {
  cv::Mat grown;
  if (options_.dilate_cells > 0) {
    const int side = 2 * options_.dilate_cells + 1;
    cv::dilate(on_, grown, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(side, side)));
  } else {
    grown = on_.clone();
  }
  if (mask_.cells.size() != grown.size() || cv::countNonZero(mask_.cells != grown) > 0) {
    mask_.cells = grown;
    ++version_;
  }
}

bool OverlayDetector::Covers(const TargetTrack& target) const {
  if (mask_.cells.empty() || target.observations.empty()) return false;
  size_t on = 0;
  for (const TargetObservation& o : target.observations) on += mask_.Contains(o.position);
  return static_cast<double>(on) >=
         options_.max_target_fraction * static_cast<double>(target.observations.size());
}

void OverlayDetector::SaveState(ByteWriter* out) const {
  out->Put<int32_t>(full_size_.width);
  out->Put<int32_t>(full_size_.height);
  out->Put<int64_t>(version_);
  PutMat(fraction_, out);
  PutMat(count_, out);
  PutMat(on_, out);
  PutMat(mask_.cells, out);
}

bool OverlayDetector::RestoreState(ByteReader* in) {
  int32_t width = 0, height = 0;
  if (!in->Get(&width) || !in->Get(&height) || !in->Get(&version_)) return false;
  full_size_ = cv::Size(width, height);
  if (!GetMat(in, &fraction_) || !GetMat(in, &count_) || !GetMat(in, &on_) ||
      !GetMat(in, &mask_.cells)) {
    return false;
  }
  return fraction_.size() == count_.size() && fraction_.size() == on_.size() &&
         (mask_.cells.empty() || mask_.cells.size() == on_.size());
}

std::vector<FeatureTrackId> StillFeatures(const FeatureTracker& tracker,
                                          const std::vector<Correspondence>& matches,
                                          int window_frames, int min_window_frames,
                                          double min_flow_px, double fraction, double max_px) {
  constexpr size_t kMinFeatures = 8;
  std::vector<FeatureTrackId> still;
  // Each match is judged over the longest window it spans (window_frames, its half, and so on
  // down to min_window_frames) whose median motion is known: a young track (a corner found on a
  // digit that just changed) over a shorter one.
  std::vector<bool> judged(matches.size(), false);
  std::vector<double> moved(matches.size()), flows;
  std::vector<size_t> spanning;
  for (int window = window_frames; window >= std::max(1, min_window_frames);
       window = window > min_window_frames ? std::max(min_window_frames, window / 2) : 0) {
    const int64_t then = tracker.last_frame() - window;
    spanning.clear();
    flows.clear();
    for (size_t i = 0; i < matches.size(); ++i) {
      const FeatureTrack* history = tracker.History(matches[i].id);
      const Eigen::Vector2d* before = history != nullptr ? history->PositionAt(then) : nullptr;
      if (before == nullptr) continue;
      moved[i] = (matches[i].target - *before).norm();
      flows.push_back(moved[i]);
      if (!judged[i]) spanning.push_back(i);
    }
    if (flows.size() < kMinFeatures) continue;
    const auto middle = flows.begin() + static_cast<std::ptrdiff_t>(flows.size() / 2);
    std::nth_element(flows.begin(), middle, flows.end());
    if (!(*middle >= min_flow_px)) continue;
    for (const size_t i : spanning) {
      judged[i] = true;
      if (moved[i] < std::min(fraction * *middle, max_px)) still.push_back(matches[i].id);
    }
  }
  std::sort(still.begin(), still.end());
  return still;
}

}  // namespace saker::track
