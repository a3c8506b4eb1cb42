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

#include "core/util/byte_io.h"

#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <optional>
#include <vector>

namespace saker::track {

struct SceneCutOptions {
  int look_width = 32;  // width of the copies compared (the height follows the frame's shape)
  // The copies' correlation (absolute: a polarity switch inverts it) below which a break is a cut.
  double min_correlation = 0.4;
  // Consecutive frames whose copies correlate at this or below (the same scene, inverted) are a
  // thermal camera's polarity switch (PolarityWatch).
  double switch_correlation = -0.6;
  double min_contrast_grey = 2;  // a copy with less spread is blank: it tells nothing
};

// A small, blurred copy of an 8-bit grey frame, `look_width` wide, zero mean and unit norm
// (CV_32F); empty when its spread is below `min_contrast_grey` (blank).
cv::Mat SceneLook(const cv::Mat& grey, const SceneCutOptions& options);
// The correlation of two looks, the middle of `b` against `a` shifted by up to an eighth of their
// size (the camera moved the ground a little between them), the strongest of either sign; nullopt
// when either is empty or their sizes differ.
std::optional<double> SceneLookCorrelation(const cv::Mat& a, const cv::Mat& b);

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
  // The segment holding `frame`, or null.
  const Segment* Find(int64_t frame) const;

  SceneCutOptions options_;
  std::vector<Segment> segments_;
  cv::Mat latest_;  // the latest frame added (shared), for its segment's last look
};

// A thermal camera switching between white-hot and black-hot inverts the whole picture from one
// frame to the next. Nothing in the scene changed, but every corner's appearance did: the feature
// tracker loses them all, the change detector sees the whole frame change, and the chain breaks.
// PolarityWatch compares the small copy of each frame with the previous one's (as SceneContinuity
// does, but from a grid of samples: it runs at every frame): the same scene inverted correlates
// strongly negatively (at `switch_correlation` or below), and the frames from there on are
// in the other polarity than the video's first, so that the front end inverts them back and goes
// on as if nothing happened (one chain segment, one polarity in the map). A blank frame (no
// contrast) is skipped: the comparison is with the last frame that had a look.
class PolarityWatch {
 public:
  explicit PolarityWatch(const SceneCutOptions& options = {}) : options_(options) {}

  // The next frame, 8-bit grey; true when it is in the other polarity than the video's first (to
  // be inverted). Frames are given in increasing order.
  bool Add(int64_t frame, const cv::Mat& grey);
  // As Add, but the polarity is the one recorded (switches(), restored from a checkpoint): the
  // look is kept for the next comparison, nothing is detected.
  bool Replay(int64_t frame, const cv::Mat& grey);

  // The frames at which the polarity switched, in order.
  const std::vector<int64_t>& switches() const { return switches_; }
  // Whether `frame` is in the other polarity than the first frame, from the switches.
  bool Inverted(int64_t frame) const;

  // The switches (the looks are not kept: a resumed run makes them again as it replays frames).
  void SaveState(ByteWriter* out) const;
  bool RestoreState(ByteReader* in);

 private:
  SceneCutOptions options_;
  cv::Mat previous_;  // the look of the last frame that had one, in its own polarity
  std::vector<int64_t> switches_;
};

}  // namespace saker::track
