#pragma once

// The feature tracker of the Visual MTI front end: Harris corners followed from frame to frame
// with pyramidal Lucas-Kanade (OpenCV).
//
// Per frame:
//  1. The grey frame is shrunk to `processing_width` and one image pyramid with its gradients is
//     built; it serves as the "next" image of this frame's forward flow, as the "previous" image
//     of its backward flow and of the next frame's forward flow, so gradients are computed once.
//  2. Every live point is tracked forward into the new frame, then back again. A point whose
//     round trip misses its start by more than `max_forward_backward_px`, whose flow did not
//     converge, that left the image, or whose patch no longer looks like the one it had in the
//     previous frame (normalised cross-correlation below `min_correlation`) ends its track. The
//     round trip catches aperture drift and most occlusions and changing regions (a car passing
//     over a ground corner), but lets a few of the latter through when both flows stick near
//     their start in the new content; the correlation catches those, and being invariant to gain
//     and offset it does not end tracks when the camera's exposure changes.
//  3. New corners are detected only where tracks have run out: the image is split into a grid,
//     each cell has a share of `max_corners`, and cells holding too few tracks are refilled every
//     `redetect_interval_s` (at once when the total drops). The Harris quality threshold is
//     relative to the strongest corner of each cell, so weak-texture areas (fields, roofs) still
//     get corners; new corners keep `min_distance_px` from every live one and need some contrast
//     (`min_contrast`), so sensor noise on a featureless area (sky, water, cloud) gets none.
//
// Positions are full-resolution pixels whatever the processing width, with the repository's
// convention (integer = pixel centre): x_full = (x_small + 0.5) * scale - 0.5 per axis.
//
// Speed (measured once during development with a scratch program; saker-bench-frontend reports
// the tracker's time per frame inside the front end). The flow costs the same per point at any
// processing width (window area times pyramid levels, twice for the round trip) and dominates; the
// width only sets the cost of the pyramid and of detection, and how far in full-resolution pixels a
// window and the pyramid reach. With the defaults, 1000 corners and simulated airborne video, one
// core of a shared AMD EPYC takes 5.8-7 ms per frame at 1280x720 and at 1920x1080 (quietest runs:
// pyramid 0.6 ms, flow 5.1 ms, detection 0.1 ms on average); two OpenCV threads on two free
// cores: 3.3 ms at 1280x720. An 11-pixel window instead of the customary 21 is what makes that: 21
// takes 14-17 ms, for a median frame-to-frame error of 0.11 px against 0.14-0.15 px. Fewer levels
// or a smaller window cut the time further (2 levels: about 5 ms, a 9-pixel window: about 4 ms) at
// the cost of reach and accuracy.
//
// Memory is bounded: only live tracks keep a history (at most 1.25 * `max_history` positions
// each); lost tracks are handed out by TakeFinished(), which the caller must call regularly
// (every frame is fine) unless `keep_finished` is off.
//
// A FeatureTracker is used by one thread at a time. OpenCV may run the flow on several threads
// itself (cv::setNumThreads).

#include "core/track/types.h"
#include "core/util/byte_io.h"
#include "core/util/status.h"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <vector>

namespace saker::track {

struct TrackerOptions {
  int max_corners = 1000;       // live tracks at most, shared out over the grid cells
  double quality = 0.005;       // Harris response relative to the strongest in its grid cell
  double min_distance_px = 10;  // between a new corner and any live one, full-resolution pixels
  int processing_width = 960;   // track on a copy this wide (never enlarged); 0 = full resolution
  int window_px = 11;           // Lucas-Kanade window side, processing pixels (odd)
  int pyramid_levels = 3;       // coarser pyramid levels above the processing image
  int max_iterations = 10;      // Lucas-Kanade iterations per level at most
  double max_forward_backward_px = 0.5;  // round-trip error allowed, full-resolution pixels
  // Normalised cross-correlation of the 11x11 processing-pixel patch around a point between
  // consecutive frames, at least; -1 turns the check off.
  double min_correlation = 0.8;
  // Grey-level standard deviation of that patch a new corner needs: no corners on sensor noise in
  // featureless areas (sky, water, a blank frame), which would not survive a frame.
  double min_contrast = 3;
  int grid_cols = 8;  // detection grid over the image
  int grid_rows = 6;
  // Time between refills of the cells that ran short (FrameRate; at least 1 frame): the default
  // is the 5 frames tuned at 25 frames a second.
  double redetect_interval_s = 0.2;
  // A cell holding fewer tracks than this fraction of its share is refilled; and detection runs
  // at once, not waiting for the interval, when the total falls below this fraction of the count
  // one frame after the latest detection.
  double refill_fraction = 0.75;
  double max_frame_gap_s = 0.4;  // a longer time skipped between two calls (at least 1 frame)
                                 // ends every track (as Reset)
  int max_history = 2000;        // positions kept per live track (the latest; see FeatureTrack)
  bool keep_finished = true;     // collect lost tracks for TakeFinished()
  int min_finished_length = 2;   // lost tracks seen in fewer frames are not kept

  Status Validate() const;
};

// A live track in the latest frame.
struct TrackedPoint {
  FeatureTrackId id{};
  Eigen::Vector2d position{0, 0};  // full-resolution pixels
  int64_t first_frame = 0;         // the frame its corner was detected in
};

// A track with its image positions, one per frame index from `history_start` to last_frame().
// Frames skipped by the caller (gaps in the frame indices given to Process) get positions
// interpolated linearly between the frames either side. A long-lived track keeps only its latest
// positions: the oldest are dropped in blocks of a quarter of `max_history`, so `history_start`
// moves past `first_frame` and at least the last `max_history` positions remain.
struct FeatureTrack {
  FeatureTrackId id{};
  int64_t first_frame = 0;    // the frame its corner was detected in
  int64_t history_start = 0;  // frame of positions.front()
  std::vector<Eigen::Vector2d> positions;

  int64_t last_frame() const { return history_start + static_cast<int64_t>(positions.size()) - 1; }
  // The position in `frame`, or null when the history does not cover it.
  const Eigen::Vector2d* PositionAt(int64_t frame) const;
};

class FeatureTracker {
 public:
  // `options` must be valid (Validate()); a bad one is a bug (CheckError).
  FeatureTracker(const TrackerOptions& options, FrameRate rate);

  // Tracks the previous frame's points into `grey` (CV_8UC1, full resolution) and detects new
  // corners where tracks ran out. Frame indices must increase between resets (CheckError
  // otherwise); gaps are allowed up to `max_frame_gap_s`. A change of image size or a longer gap
  // ends every track first. Frames under 16 pixels wide or high (after shrinking) get no tracks.
  // `predicted`: where the ground motion is expected to take the previous frame's points
  // (current_from_previous, full resolution; null: nowhere in particular). The flow then starts
  // from there and goes back from its inverse, so that motions beyond the pyramid's reach (about
  // window_px / 2 * 2^pyramid_levels processing pixels: 44 by default) are followed when they are
  // steady, as between frames a second apart.
  void Process(int64_t frame_index, const cv::Mat& grey,
               const Eigen::Matrix3d* predicted = nullptr);

  // The latest frame given to Process, -1 before the first and after Reset().
  int64_t last_frame() const { return last_frame_; }
  // Tracks alive in the latest frame, ordered by id, including those detected in it.
  const std::vector<TrackedPoint>& points() const { return points_; }
  // Tracks alive in both the previous and the latest frame given to Process: source in the
  // previous one, target in the latest, ordered by id.
  const std::vector<Correspondence>& matches() const { return matches_; }
  // A live track with its history since it started (up to `max_history`), or null when `id` is
  // not alive. Valid until the next non-const call.
  const FeatureTrack* History(FeatureTrackId id) const;

  // Tracks lost since the last call (also by Reset), with their histories, ordered by the frame
  // they were lost in. Empty when `keep_finished` is off.
  std::vector<FeatureTrack> TakeFinished();

  // Ends every track (after a blank frame or a scene cut): they go to TakeFinished() and the next
  // frame starts afresh with new corners. Ids keep increasing; any frame index may follow.
  void Reset();

  // The tracker's state after the latest frame, so that a resumed run goes on exactly from there
  // (docs/reliability.md, "Resume"): everything but the image pyramid, which RestoreState builds
  // again from that same frame (`grey`). RestoreState is false when `in` is malformed.
  void SaveState(ByteWriter* out) const;
  bool RestoreState(ByteReader* in, const cv::Mat& grey);

  // Where the time of the latest Process call went (milliseconds, wall clock).
  struct Timing {
    double pyramid_ms = 0;  // shrinking the frame and building its pyramid
    double flow_ms = 0;     // forward and backward Lucas-Kanade
    double detect_ms = 0;   // new corners (0 on frames without detection)
    double total_ms = 0;    // the whole call
  };
  const Timing& last_timing() const { return timing_; }

 private:
  // Moves every live track to the finished list and forgets the previous frame.
  void EndAll();
  void Finish(FeatureTrack track);
  bool SetFrame(const cv::Mat& grey);
  // Tracks the live points into the pyramid of the new frame; keeps the survivors.
  void TrackPoints(int64_t frame_index, const Eigen::Matrix3d* predicted);
  // Detects corners in the grid cells that ran short and starts tracks on them.
  void Detect(int64_t frame_index);
  Eigen::Vector2d ToFull(const cv::Point2f& p) const;

  TrackerOptions options_;
  int redetect_interval_ = 1;  // redetect_interval_s and max_frame_gap_s at the video's rate
  int max_frame_gap_ = 1;
  int64_t last_frame_ = -1;
  int64_t next_id_ = 1;
  int frames_since_detection_ = 0;
  size_t reference_count_ = 0;        // live tracks one frame after the latest detection
  cv::Size full_size_;                // of the frames being tracked
  cv::Size small_size_;               // of the processing image
  double scale_x_ = 1, scale_y_ = 1;  // full-resolution pixels per processing pixel
  std::vector<cv::Mat> previous_pyramid_, pyramid_;  // with gradients (buildOpticalFlowPyramid)
  bool have_previous_ = false;

  // Live tracks ordered by id, and their positions in the processing image (parallel).
  std::vector<FeatureTrack> live_;
  std::vector<cv::Point2f> live_small_;
  std::vector<float> live_patches_;  // each live track's patch in the latest frame (normalised)
  std::vector<TrackedPoint> points_;
  std::vector<Correspondence> matches_;
  std::vector<FeatureTrack> finished_;
  Timing timing_;

  // Scratch buffers kept between frames to avoid reallocation.
  std::vector<cv::Point2f> forward_, backward_;
  std::vector<uchar> forward_status_, backward_status_;
  std::vector<float> new_patches_;
  cv::Mat mask_;
};

}  // namespace saker::track
