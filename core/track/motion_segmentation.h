#pragma once

// Moving / stationary separation: the paper's Visual MTI.
//
// The camera's own motion makes everything move in the image; the ground moves by one homography
// from frame to frame (flat ground), so a feature that does not follow it is on a moving object,
// on a tall structure (parallax), or is a tracking error. Two stages separate them:
//
//  1. Per frame, each feature's residual r = x_now - H x_before against the dominant ground motion
//     H. Its motion over the last `short_s` seconds is the sum of those residuals (to first
//     order the feature's displacement relative to the ground; tracking noise telescopes rather
//     than adds up), spread over those frames (a single jump is a tracking slip, not motion),
//     which is significant above a threshold set by the feature noise, unless it is
//     explainable as parallax: a point above the ground plane is displaced along the epipolar line
//     (towards or away from the epipole, the image of the camera's translation), and by at most a
//     fraction of the ground's own image motion there (height / altitude). Summing over a few
//     frames lets a walker (a quarter of a pixel per frame) be seen as well as a car.
//  2. Over a longer window, a track is moving only when its motion was significant in most of
//     the window AND its ground-relative displacement over the window is large: one noisy
//     frame, or jitter back and forth, never makes a target. A moving track returns to stationary
//     when it stays still for most of a window (a car stopping at a junction).

// Stationary tracks are what the homographies are estimated from; moving ones are grouped into
// targets (target_tracks.h).

#include "core/track/types.h"
#include "core/util/byte_io.h"
#include "core/util/status.h"

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <unordered_map>
#include <vector>

namespace saker::track {

// Windows in seconds (FrameRate), with their floors in frames in brackets; the defaults are the
// frame counts tuned at 25 frames a second.
struct SegmentationOptions {
  double short_s = 0.32;               // stage 1: time the motion is summed over [1 frame]
  double residual_threshold_px = 1.5;  // stage 1: motion over short_s above this is significant
  double window_s = 0.48;  // stage 2: time looked back on (>= short_s) [3 frames, <= 250]
  double min_significant_fraction = 0.6;    // of the window, to become moving
  double min_window_displacement_px = 2.5;  // ground-relative motion summed over the window
  double release_fraction = 0.25;           // a moving track with fewer significant frames stops
  double max_parallax_fraction = 0.15;  // residuals along the epipolar line up to this fraction of
                                        // the ground flow are parallax (structures up to ~13 % of
                                        // the flying height)
  double epipolar_angle_deg = 12;       // "along the epipolar line" tolerance
  // The thresholds follow the feature noise. Heavily compressed video (a low bit rate's blocks
  // and smoothing) makes the tracker's corners wander over the ground by pixels where clean video
  // gives a tenth of one, and every threshold above, tuned on clean video, is then met by the
  // ground itself. Most features are on the ground, so the median over a frame's features of the
  // stage-1 motion (and of the stage-2 displacement), smoothed over `noise_time_s`, measures that
  // noise; the thresholds are at least `noise_multiple` (`window_noise_multiple`) times it. On
  // clean video the medians are 0.2-0.3 pixels and the fixed thresholds stand. 0: off.
  double noise_multiple = 3;
  double window_noise_multiple = 4;
  double noise_time_s = 1;      // the medians' running mean [1 frame]
  int min_noise_features = 30;  // a frame with fewer full histories leaves the estimate alone
  Status Validate() const;
};

enum class MotionLabel {
  kUnknown,     // too young to say
  kStationary,  // follows the ground
  kMoving,      // consistently off the ground motion
};
const char* MotionLabelName(MotionLabel label);

struct MovingPoint {
  FeatureTrackId id{};
  Eigen::Vector2d position{0, 0};           // in the latest frame
  Eigen::Vector2d residual_velocity{0, 0};  // ground-relative image velocity, pixels per frame
};

class MotionSegmenter {
 public:
  MotionSegmenter(const SegmentationOptions& options, FrameRate rate);

  // One frame: `matches` previous -> current for the tracks alive in both, `current_from_previous`
  // the ground motion, and the epipole in the current frame (homogeneous; nullopt when unknown,
  // which disables the parallax test). Tracks not in `matches` are forgotten.
  void AddFrame(const std::vector<Correspondence>& matches,
                const Eigen::Matrix3d& current_from_previous,
                const std::optional<Eigen::Vector3d>& epipole);

  MotionLabel LabelOf(FeatureTrackId id) const;
  // The tracks labelled moving after the latest frame.
  const std::vector<MovingPoint>& moving() const { return moving_; }

  void Reset();

  // The thresholds in force after the latest frame (the fixed ones, or larger where the measured
  // feature noise asks for it; see SegmentationOptions::noise_multiple).
  double residual_threshold_px() const;
  double window_displacement_px() const;
  // The smoothed medians behind them (0 before the first estimate).
  double short_noise_px() const { return noise_short_; }
  double window_noise_px() const { return noise_window_; }

  // Every track's history and label, so that a resumed run goes on exactly from the latest frame
  // (docs/reliability.md, "Resume"). RestoreState is false when `in` is malformed.
  void SaveState(ByteWriter* out) const;
  bool RestoreState(ByteReader* in);
  // The noise estimate, kept apart from SaveState so that older checkpoints (without it) still
  // read: a run resumed from one starts the estimate afresh.
  void SaveNoise(ByteWriter* out) const;
  bool RestoreNoise(ByteReader* in);

 private:
  struct Step {
    Eigen::Vector2d residual{0, 0};  // the per-frame residual against the ground motion
    Eigen::Vector2d flow{0, 0};      // the ground's image motion at the feature
    bool significant = false;        // the stage 1 verdict
  };
  struct TrackState {
    // The last window_frames_ steps, a ring: the oldest at `first`.
    std::vector<Step> steps;
    size_t first = 0;
    int64_t updated = -1;  // the AddFrame call that saw the track last
    MotionLabel label = MotionLabel::kUnknown;
    // Step k, 0 the oldest held.
    const Step& at(size_t k) const { return steps[(first + k) % steps.size()]; }
  };

  SegmentationOptions options_;
  int short_frames_ = 0;   // short_s and window_s at the video's frame rate
  int window_frames_ = 0;  // (window_frames_ >= short_frames_)
  // Kept from frame to frame, so that a track's state is not allocated again every frame.
  std::unordered_map<int64_t, TrackState> tracks_;
  int64_t calls_ = 0;
  std::vector<MovingPoint> moving_;
  // The smoothed medians of the stage-1 motion and the stage-2 displacement (pixels; 0 unknown).
  double noise_short_ = 0, noise_window_ = 0;
  double noise_weight_ = 1;  // of a new frame's median in the running mean
  // Per frame: the matched tracks' stage-1 figures between the two passes, and the samples of
  // the medians (kept to avoid allocating every frame).
  struct Pending {
    TrackState* state = nullptr;
    FeatureTrackId id{};
    size_t newest = 0;
    Eigen::Vector2d position{0, 0}, motion{0, 0}, flow{0, 0}, window_sum{0, 0};
    double largest_step = 0;
    int significant_before = 0;  // significant steps in the window other than the newest
  };
  std::vector<Pending> pending_;
  std::vector<double> short_samples_, window_samples_;
};

}  // namespace saker::track
