#include "core/track/scene_cut.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <iterator>

namespace saker::track {

cv::Mat SceneContinuity::Look(const cv::Mat& grey) const {
  if (grey.empty()) return {};
  const int width = std::max(4, options_.look_width);
  const int height = std::max(2, static_cast<int>(std::lround(static_cast<double>(width) *
                                                              grey.rows / std::max(1, grey.cols))));
  cv::Mat small;
  cv::resize(grey, small, cv::Size(width, height), 0, 0, cv::INTER_AREA);
  small.convertTo(small, CV_32F);
  cv::Scalar mean, spread;
  cv::meanStdDev(small, mean, spread);
  if (!(spread[0] >= options_.min_contrast_grey)) return {};
  small -= mean[0];
  small /= cv::norm(small);
  return small;
}

void SceneContinuity::Add(int64_t frame, bool new_segment, const cv::Mat& grey) {
  if (new_segment || segments_.empty()) {
    if (!segments_.empty()) segments_.back().last_look = Look(latest_);
    Segment s;
    s.first = s.last = frame;
    s.first_look = Look(grey);
    segments_.push_back(std::move(s));
  } else {
    segments_.back().last = frame;
  }
  latest_ = grey;
}

const SceneContinuity::Segment* SceneContinuity::Find(int64_t frame) const {
  const auto after = std::upper_bound(segments_.begin(), segments_.end(), frame,
                                      [](int64_t f, const Segment& s) { return f < s.first; });
  if (after == segments_.begin()) return nullptr;
  const Segment& s = *std::prev(after);
  return frame <= s.last ? &s : nullptr;
}

std::optional<double> SceneContinuity::Correlation(const cv::Mat& a, const cv::Mat& b) {
  if (a.empty() || b.empty() || a.size() != b.size()) return std::nullopt;
  // The middle of b against every placement in a within an eighth of the width: the camera may
  // have moved the ground by a few of the copy's pixels between the two frames (a blank of a
  // second or two). The strongest correlation, of either sign, counts.
  const int mx = std::max(1, a.cols / 8), my = std::max(1, a.rows / 8);
  if (a.cols <= 2 * mx || a.rows <= 2 * my) return a.dot(b);
  cv::Mat scores;
  cv::matchTemplate(a, b(cv::Rect(mx, my, b.cols - 2 * mx, b.rows - 2 * my)), scores,
                    cv::TM_CCOEFF_NORMED);
  double low = 0, high = 0;
  cv::minMaxLoc(scores, &low, &high);
  return std::abs(low) > std::abs(high) ? low : high;
}

bool SceneContinuity::SameScene(int64_t a, int64_t b) const {
  const Segment* sa = Find(a);
  const Segment* sb = Find(b);
  if (sa == nullptr || sb == nullptr || sa == sb) return true;
  // The last look of a's segment is made when the next segment starts; the latest segment has
  // none (and b's is later than a's).
  const std::optional<double> r = Correlation(sa->last_look, sb->first_look);
  return !r || std::abs(*r) >= options_.min_correlation;
}

std::optional<double> SceneContinuity::CorrelationAt(int64_t frame) const {
  const Segment* s = Find(frame);
  if (s == nullptr || s->first != frame || s == segments_.data()) return std::nullopt;
  return Correlation(std::prev(s)->last_look, s->first_look);
}

}  // namespace saker::track
