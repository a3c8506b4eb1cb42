#pragma once

// Scene cuts: whether the frames on either side of a chain break show one scene.
//
// The key frame chain breaks wherever a frame has no homography from the one before: at a cut to
// another scene (an edited video, a switch of camera), but also at a blank (cloud, a dropped
// signal), a thermal camera switching polarity, or an estimate that failed. Pieces of a track on
// either side of a cut are different objects in different places, so nothing may join them; on
// either side of an interruption they may well be one car. SceneContinuity tells the two apart
// by appearance: a small, blurred copy of the last frame before the break and of the first after
// it correlate when they show the same ground (a second or two of camera motion moves it by a few
// of the copy's pixels), in either polarity, and do not after a cut.

#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <optional>
#include <vector>

namespace saker::track {

struct SceneCutOptions {
  int look_width = 32;  // width of the copies compared (the height follows the frame's shape)
  // The copies' correlation (absolute: a polarity switch inverts it) below which a break is a cut.
  double min_correlation = 0.4;
  double min_contrast_grey = 2;  // a copy with less spread is blank: it tells nothing
};

class SceneContinuity {
 public:
  explicit SceneContinuity(const SceneCutOptions& options = {}) : options_(options) {}

  // Frames in increasing order (8-bit grey); `new_segment` where the frame has no homography from
  // the one before (it starts a chain segment). Keeps a reference to the latest frame's pixels.
  void Add(int64_t frame, bool new_segment, const cv::Mat& grey);

  // Whether frames a <= b show one scene: always within a chain segment; across segments, unless
  // the last frame of a's segment and the first of b's look unalike (a cut). Unknown frames (not
  // added, or blank looks) count as one scene.
  bool SameScene(int64_t a, int64_t b) const;

  // The copies' correlation across the break before the segment starting at `frame` (nullopt when
  // no segment starts there or either copy is blank): for tests and diagnostics.
  std::optional<double> CorrelationAt(int64_t frame) const;

 private:
  struct Segment {
    int64_t first = 0, last = 0;
    cv::Mat first_look, last_look;  // CV_32F, zero mean, unit norm; empty when blank
  };
  cv::Mat Look(const cv::Mat& grey) const;
  // The segment holding `frame`, or null.
  const Segment* Find(int64_t frame) const;
  static std::optional<double> Correlation(const cv::Mat& a, const cv::Mat& b);

  SceneCutOptions options_;
  std::vector<Segment> segments_;
  cv::Mat latest_;  // the latest frame added (shared), for its segment's last look
};

}  // namespace saker::track
